"""TSDF fusion of depth images (nbv.geometry.fusion) and the mesh scores
(nbv.geometry.reconstruction_metrics.mesh_scores), on shapes with known answers rendered by the
project's own ray caster (nbv.geometry.raycast.raycast_depth, Open3D / Embree).

The scene: a sphere of radius 0.5 centred off the origin, seen by 8 cameras on a Fibonacci
lattice at distance 1.5 from its centre, 160 x 120 pixels with a focal length of 120 pixels. The
default voxel is the radius / 50 = 0.01; a pixel's footprint on the sphere's nearest point (depth
1.0) is 1 / 120 = 0.0083, just under the voxel.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree
from shapes import fibonacci_sphere

from nbv.geometry.camera import Intrinsics, look_at, opencv_to_blender, project
from nbv.geometry.fusion import VOXELS_PER_RADIUS, FusionSettings, fuse_depth
from nbv.geometry.raycast import raycast_depth
from nbv.geometry.reconstruction_metrics import mesh_scores, surface_points
from nbv.utils.fields import ConfigError
from nbv.utils.seeding import named_rng

CENTRE = np.array([0.2, -0.1, 0.3])
RADIUS = 0.5
DISTANCE = 1.5
CAMERA = Intrinsics.centred(160, 120, 120.0)
VOXEL = RADIUS / VOXELS_PER_RADIUS  # 0.01, the default voxel of this object
#: Points sampled on each surface by the Chamfer tests.
N_SAMPLES = 200_000


class Scene:
    """A sphere's triangle mesh, its depth images and poses."""

    def __init__(self, n_views: int = 8) -> None:
        sphere = trimesh.creation.icosphere(subdivisions=5, radius=RADIUS)  # 20,480 faces
        self.vertices = np.asarray(sphere.vertices) + CENTRE
        self.faces = np.asarray(sphere.faces)
        self.area = float(sphere.area)
        directions = fibonacci_sphere(n_views)
        self.poses = np.stack([look_at(CENTRE + DISTANCE * d, CENTRE) for d in directions])
        self.depth = raycast_depth(self.vertices, self.faces, self.poses, CAMERA)


@pytest.fixture(scope="module")
def scene() -> Scene:
    return Scene()


@pytest.fixture(scope="module")
def fused(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    return fuse_depth(scene.depth, scene.poses, CAMERA, radius=RADIUS)


def sphere_error(points: np.ndarray) -> np.ndarray:
    """(N,) exact distance of each point to the true sphere."""
    return np.abs(np.linalg.norm(points - CENTRE, axis=1) - RADIUS)


def fit_sphere(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares sphere through points: |p|^2 = 2 c.p + (r^2 - |c|^2) is linear in
    (c, r^2 - |c|^2)."""
    a = np.hstack([2.0 * points, np.ones((len(points), 1))])
    solution, *_ = np.linalg.lstsq(a, (points**2).sum(axis=1), rcond=None)
    centre = solution[:3]
    return centre, float(np.sqrt(solution[3] + centre @ centre))


def sampled(vertices: np.ndarray, triangles: np.ndarray, name: str) -> np.ndarray:
    return surface_points(vertices, triangles, N_SAMPLES, named_rng(0, "test_fusion", name))


# --- settings and input checks ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("key", "value", "allowed"),
    [
        ("voxel", 0.0, "null or a positive distance"),
        ("truncation", 0.5, "a number of voxels >= 1"),
        ("max_depth", -1.0, "null or a positive distance"),
        ("min_views", 0, "an integer >= 1"),
    ],
)
def test_settings_refuse_a_bad_value_naming_the_key(key, value, allowed):
    with pytest.raises(ConfigError, match=f"^{key}={value!r}: must be {allowed}$"):
        FusionSettings(**{key: value})


def test_the_default_voxel_is_a_fiftieth_of_the_radius_and_a_given_voxel_wins():
    assert FusionSettings().voxel_size(RADIUS) == pytest.approx(0.01, abs=1e-15)
    assert FusionSettings().voxel_size(0.1) == pytest.approx(0.002, abs=1e-15)
    assert FusionSettings(voxel=0.004).voxel_size(RADIUS) == 0.004
    assert FusionSettings(voxel=0.004).voxel_size() == 0.004
    with pytest.raises(ValueError, match="give reconstruction.voxel"):
        FusionSettings().voxel_size(None)


def test_inputs_of_the_wrong_shape_are_refused(scene: Scene):
    with pytest.raises(ValueError, match=r"poses must be \(V, 4, 4\) for V = 8"):
        fuse_depth(scene.depth, scene.poses[:7], CAMERA, radius=RADIUS)
    with pytest.raises(ValueError, match=r"depth image 0 is \(120, 160\), its intrinsics expect"):
        fuse_depth(scene.depth, scene.poses, Intrinsics.centred(640, 480), radius=RADIUS)
    with pytest.raises(ValueError, match="2 intrinsics for 8 depth images"):
        fuse_depth(scene.depth, scene.poses, [CAMERA, CAMERA], radius=RADIUS)
    with pytest.raises(ValueError, match="give reconstruction.voxel"):
        fuse_depth(scene.depth, scene.poses, CAMERA)


# --- the fused sphere ----------------------------------------------------------------------------


@pytest.mark.slow
def test_fused_sphere_is_within_a_bound_from_the_voxel_of_the_true_surface(scene, fused):
    """Chamfer distance below ``voxel / 2 + 0.5 sqrt(area / n)``.

    Why: with exact depth, a fused vertex is off the surface by the error of the truncated
    distance at the voxels around it, which Open3D reads at the nearest pixel: half a pixel's
    footprint (0.0042 here) times the surface's slope in that view; averaged over the views that
    saw a voxel and interpolated by marching cubes, the mean stays under half a voxel while the
    footprint is under the voxel. Sampling both surfaces with n points adds the mean distance to
    the nearest of n uniform points, 0.5 sqrt(area / n) (0.002 here). Measured: 0.0034.
    """
    vertices, triangles = fused
    # The exact distance of the reconstruction's surface to the sphere first (a misplaced
    # surface fails here, before the KD-tree queries, which are slow for clouds far apart):
    # half a voxel on average; grazing views' nearest-pixel error reaches 1.5 voxels at worst
    # (measured 1.45).
    error = sphere_error(sampled(vertices, triangles, "exact"))
    assert error.mean() < VOXEL / 2
    assert error.max() < 2 * VOXEL
    scores = mesh_scores(vertices, triangles, scene.vertices, scene.faces, eps=VOXEL,
                         rng=named_rng(0, "test_fusion", "chamfer"), n=N_SAMPLES)  # fmt: skip
    bound = VOXEL / 2 + 0.5 * np.sqrt(scene.area / N_SAMPLES)
    assert scores["chamfer"] < bound
    assert scores["chamfer_accuracy"] < bound and scores["chamfer_completeness"] < bound
    assert scores["fscore_eps"] > 0.99  # within one voxel, both ways
    assert scores["fscore_2eps"] > 0.999


def test_fused_sphere_has_the_true_radius_and_centre_within_a_voxel(fused):
    vertices, triangles = fused
    centre, radius = fit_sphere(vertices)
    assert abs(radius - RADIUS) < VOXEL  # measured 0.0004
    assert np.linalg.norm(centre - CENTRE) < VOXEL
    assert abs(np.linalg.norm(vertices - CENTRE, axis=1).mean() - RADIUS) < VOXEL
    # Triangles wind outwards (a viewer shades the outside): measured 99.7 %.
    a, b, c = (vertices[triangles[:, i]] for i in range(3))
    outward = (np.cross(b - a, c - a) * ((a + b + c) / 3 - CENTRE)).sum(axis=1) > 0
    assert outward.mean() > 0.99


@pytest.mark.parametrize("wrong", ["blender axes", "world-to-camera"])
def test_poses_in_another_convention_do_not_give_the_sphere(scene, wrong):
    """The placement the tests above check depends on the pose convention: the same images
    with Blender-axes poses (camera -z forward), or with world-to-camera matrices, fuse into
    something that is not the sphere (or into nothing)."""
    poses = (
        opencv_to_blender(scene.poses) if wrong == "blender axes" else np.linalg.inv(scene.poses)
    )
    vertices, _ = fuse_depth(scene.depth, poses, CAMERA, radius=RADIUS)
    on_sphere = np.count_nonzero(sphere_error(vertices) < VOXEL) if len(vertices) else 0
    assert on_sphere < 0.05 * max(len(vertices), 1)


@pytest.mark.slow
def test_a_block_of_missing_depth_does_not_carve_what_other_views_saw(scene):
    """View 0 loses a 60 x 60 block over the sphere (depth 0, then NaN): every point of the
    sphere in that block that another view saw within 60 degrees of its normal stays within a
    voxel of the fused surface. The same block read as free space (a far depth, as a sensor
    model that carves along rays without a return would) does carve it."""
    rows, cols = slice(30, 90), slice(50, 110)
    truth = surface_points(scene.vertices, scene.faces, 50_000, named_rng(0, "test_fusion", "gt"))
    normals = (truth - CENTRE) / RADIUS

    def facing(view: int) -> np.ndarray:  # cosine between the normal and the way to camera
        towards = scene.poses[view, :3, 3] - truth
        return (towards * normals).sum(axis=1) / np.linalg.norm(towards, axis=1)

    uv, _ = project(truth, CAMERA, scene.poses[0])
    in_block = (
        (facing(0) > 0)
        & (uv[:, 0] >= cols.start - 0.5) & (uv[:, 0] < cols.stop - 0.5)
        & (uv[:, 1] >= rows.start - 0.5) & (uv[:, 1] < rows.stop - 0.5)
    )  # fmt: skip
    seen_by_others = np.max([facing(v) for v in range(1, len(scene.poses))], axis=0)
    patch = truth[in_block & (seen_by_others > np.cos(np.radians(60)))]
    assert len(patch) > 1000

    def worst_gap(fill: float) -> float:
        depth = scene.depth.copy()
        depth[0, rows, cols] = fill
        vertices, triangles = fuse_depth(depth, scene.poses, CAMERA, radius=RADIUS)
        gaps, _ = cKDTree(sampled(vertices, triangles, "block")).query(patch)
        return float(gaps.max())

    assert worst_gap(0.0) < VOXEL  # measured 0.0087
    assert worst_gap(np.nan) < VOXEL
    assert worst_gap(5.0) > 4 * VOXEL  # carved: measured 0.083


def test_a_view_without_measurements_changes_nothing(scene, fused):
    empty = np.zeros_like(scene.depth[:3])
    empty[1], empty[2] = np.nan, np.inf
    vertices, triangles = fuse_depth(
        np.concatenate([scene.depth, empty]),
        np.concatenate([scene.poses, scene.poses[:3]]),
        CAMERA,
        radius=RADIUS,
    )
    np.testing.assert_array_equal(vertices, fused[0])
    np.testing.assert_array_equal(triangles, fused[1])
    nothing = fuse_depth(empty, scene.poses[:3], CAMERA, radius=RADIUS)
    assert nothing[0].shape == (0, 3) and nothing[1].shape == (0, 3)
    assert nothing[1].dtype == np.int64


def test_min_views_drops_what_fewer_views_measured(scene):
    one = fuse_depth(scene.depth[:1], scene.poses[:1], CAMERA, radius=RADIUS)
    assert len(one[1]) > 1000
    assert sphere_error(one[0]).mean() < VOXEL / 2
    none = fuse_depth(scene.depth[:1], scene.poses[:1], CAMERA, FusionSettings(min_views=2),
                      radius=RADIUS)  # fmt: skip
    assert none[0].shape == (0, 3)
    two = fuse_depth(scene.depth, scene.poses, CAMERA, FusionSettings(min_views=2), radius=RADIUS)
    assert 0 < len(two[1]) < len(fuse_depth(scene.depth, scene.poses, CAMERA, radius=RADIUS)[1])


def test_views_of_two_cameras_fuse_with_one_intrinsics_each(scene):
    fine = Intrinsics.centred(320, 240, 240.0)
    depths = [*scene.depth[:4], *raycast_depth(scene.vertices, scene.faces, scene.poses[4:], fine)]
    vertices, triangles = fuse_depth(depths, scene.poses, [CAMERA] * 4 + [fine] * 4, radius=RADIUS)
    assert sphere_error(sampled(vertices, triangles, "two cameras")).mean() < VOXEL / 2
    assert abs(fit_sphere(vertices)[1] - RADIUS) < VOXEL


@pytest.mark.slow
def test_max_depth_leaves_a_wall_behind_the_object_out():
    """Cameras in front of a sphere with a wall 1 behind its centre: without a range limit the
    wall is fused too; with ``max_depth`` 2.0 (the sphere's seen side lies within 1.5 of each
    camera, the wall from 2.4 on) none of it is."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=RADIUS)
    wall = trimesh.creation.box(extents=(4.0, 4.0, 0.05))
    wall.apply_translation([0.0, 0.0, -1.0])
    scene = trimesh.util.concatenate([sphere, wall])
    vertices, faces = np.asarray(scene.vertices) + CENTRE, np.asarray(scene.faces)
    directions = np.array([[0, 0, 1], [0.4, 0, 1], [-0.4, 0, 1], [0, 0.4, 1], [0, -0.4, 1]])
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    poses = np.stack([look_at(CENTRE + DISTANCE * d, CENTRE) for d in directions])
    depth = raycast_depth(vertices, faces, poses, CAMERA)
    near_wall = lambda v: np.count_nonzero(v[:, 2] - CENTRE[2] < -0.9)  # noqa: E731
    full, _ = fuse_depth(depth, poses, CAMERA, radius=RADIUS)
    limited, _ = fuse_depth(depth, poses, CAMERA, FusionSettings(max_depth=2.0), radius=RADIUS)
    assert near_wall(full) > 1000
    assert near_wall(limited) == 0
    assert np.count_nonzero(sphere_error(limited) < VOXEL) > 0.99 * len(limited)


# --- mesh scores ---------------------------------------------------------------------------------


def test_surface_points_are_seeded_uniform_by_area_and_on_the_triangles():
    # Two triangles in z = 0, of areas 0.5 and 1.5.
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [5, 0, 0], [2, 1, 0.0]])
    triangles = np.array([[0, 1, 2], [3, 4, 5]])
    n = 40_000
    points = surface_points(vertices, triangles, n, named_rng(0, "test_fusion", "uniform"))
    again = surface_points(vertices, triangles, n, named_rng(0, "test_fusion", "uniform"))
    np.testing.assert_array_equal(points, again)
    assert points.shape == (n, 3) and points.dtype == np.float64
    assert np.all(points[:, 2] == 0)
    x, y, tol = points[:, 0], points[:, 1], 1e-12
    assert np.all(y >= -tol)
    small = (x >= -tol) & (x + y <= 1 + tol)  # the first triangle
    big = (x >= 2 - tol) & (y <= (5 - x) / 3 + tol)  # the second
    assert np.all(small | big)
    # The small triangle holds a quarter of the area: its count is binomial(n, 1/4).
    sigma = np.sqrt(n * 0.25 * 0.75)
    assert abs(np.count_nonzero(small) - n / 4) < 5 * sigma
    assert surface_points(vertices, np.zeros((0, 3), int), 10, named_rng(0, "x")).shape == (0, 3)
    with pytest.raises(ValueError, match=r"triangle indices must lie in \[0, 6\)"):
        surface_points(vertices, np.array([[0, 1, 6]]), 10, named_rng(0, "x"))


def test_mesh_scores_of_concentric_spheres_are_their_gap():
    """Spheres of radius 0.5 and 0.52: every distance between the surfaces is at least the gap
    0.02 (less the faceting, 1e-4) and at most the gap plus the nearest sample's spacing."""
    inner = trimesh.creation.icosphere(subdivisions=5, radius=0.5)
    outer = trimesh.creation.icosphere(subdivisions=5, radius=0.52)
    n = 100_000
    scores = mesh_scores(inner.vertices, inner.faces, outer.vertices, outer.faces, eps=0.015,
                         rng=named_rng(0, "test_fusion", "concentric"), n=n)  # fmt: skip
    spacing = 0.5 * np.sqrt(outer.area / n)
    for key in ("chamfer_accuracy", "chamfer_completeness", "chamfer"):
        assert 0.02 - 2e-4 < scores[key] < 0.02 + spacing
    assert scores["fscore_eps"] == 0.0  # 0.015 < the gap
    assert scores["fscore_2eps"] == 1.0  # 0.03 > the gap and any sample spacing here


def test_mesh_scores_of_an_empty_reconstruction(scene):
    scores = mesh_scores(np.zeros((0, 3)), np.zeros((0, 3), int), scene.vertices, scene.faces,
                         eps=VOXEL, rng=named_rng(0, "test_fusion", "empty"), n=1000)  # fmt: skip
    assert np.isnan(scores["chamfer"]) and scores["chamfer_completeness"] == np.inf
    assert scores["fscore_eps"] == scores["fscore_2eps"] == 0.0
    with pytest.raises(ValueError, match="ground-truth mesh has no area"):
        mesh_scores(scene.vertices, scene.faces, np.zeros((0, 3)), np.zeros((0, 3), int),
                    eps=VOXEL, rng=named_rng(0, "x"), n=10)  # fmt: skip
