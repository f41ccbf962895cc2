"""The eps-dilation of analytic view sets: nearby triangles against brute-force distances, and
the dilated sets against ray casting, exactly off the visible part on small cameras and up to
oblique faces at full resolution."""

import numpy as np
import pytest
from shapes import cube_corners, fibonacci_sphere

from nbv.geometry.camera import Intrinsics, viewspace_poses
from nbv.geometry.scores import DEFAULT_EPS
from nbv.geometry.viewspace import original_viewspace
from nbv.setcover.dilation import NearTriangles, dilate_view_sets, near_triangles
from nbv.setcover.hull_sampling import convex_hull, sample_on_hull
from nbv.setcover.view_sets import view_sets

K = Intrinsics()


# --------------------------------------------------------------------------------------------
# Nearby triangles
# --------------------------------------------------------------------------------------------


def _point_triangle_distance(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Distance from each point ``p`` (m, 3) to each triangle ``tri`` (t, 3, 3): (m, t).

    Brute force: the distance to the plane when the foot lies inside the triangle, else to the
    nearest of the three edges."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    d = p[:, None, :] - a[None]
    height = (d * normal[None]).sum(axis=2)
    foot = p[:, None, :] - height[..., None] * normal[None]
    inside = np.ones(height.shape, dtype=bool)
    for u, w in ((a, b), (b, c), (c, a)):
        side = (np.cross(w - u, foot - u[None]) * normal[None]).sum(axis=2)
        inside &= side >= 0
    best = np.where(inside, np.abs(height), np.inf)
    for u, w in ((a, b), (b, c), (c, a)):
        e = w - u
        t = np.clip(((p[:, None, :] - u[None]) * e[None]).sum(axis=2) / (e * e).sum(axis=1), 0, 1)
        closest = u[None] + t[..., None] * e[None]
        best = np.minimum(best, np.linalg.norm(p[:, None, :] - closest, axis=2))
    return best


def _expected_near_pairs(hull, samples, faces, eps) -> set[tuple[int, int]]:
    tri = hull.points[hull.simplices]
    dist = _point_triangle_distance(samples, tri)  # (n, F)
    dist[np.arange(len(samples)), faces] = np.inf
    return {(int(i), int(t)) for i, t in zip(*np.nonzero(dist <= eps), strict=True)}


def _near_pairs(near: NearTriangles, faces) -> set[tuple[int, int]]:
    sizes = np.diff(near.starts)
    assert np.all(sizes > 0) and near.starts[0] == 0 and near.starts[-1] == len(near.sample)
    own, other = np.repeat(near.own, sizes), np.repeat(near.other, sizes)
    assert np.array_equal(faces[near.sample], own) and np.all(own != other)
    groups = list(zip(near.own.tolist(), near.other.tolist(), strict=True))
    assert groups == sorted(set(groups))
    pairs = set(zip(near.sample.tolist(), other.tolist(), strict=True))
    assert len(pairs) == len(near.sample)
    return pairs


@pytest.mark.parametrize("shape", ["blob", "slab", "cube", "fine", "cap"])
@pytest.mark.slow
def test_near_triangles_match_brute_force_distances(shape):
    rng = np.random.default_rng(12)
    if shape == "blob":
        points = rng.normal(size=(60, 3)) * [0.3, 0.2, 0.25]
    elif shape == "fine":  # triangles smaller than eps
        points = 0.3 * fibonacci_sphere(300)
    elif shape == "cap":  # small triangles on the dome, large ones across the base
        dome = fibonacci_sphere(600)
        points = 0.3 * dome[dome[:, 2] > 0.0]
    elif shape == "slab":
        # Thinner than eps: every sample is within eps of the opposite face.
        points = rng.uniform(-1.0, 1.0, (40, 3)) * [0.3, 0.2, 0.0] + [0.0, 0.0, 0.004]
        points = np.vstack([points, points * [1.0, 1.0, -1.0]])
    else:
        points = cube_corners(0.2)  # two triangles per face: the diagonals pair them
    hull = convex_hull(points)
    samples, _, faces = sample_on_hull(hull, 3000, rng=5)
    eps = 0.03
    expected = _expected_near_pairs(hull, samples, faces, eps)
    near = near_triangles(hull, samples, faces, eps)
    assert _near_pairs(near, faces) == expected and len(expected) > 100
    assert near.eps == eps
    # Samples in any order.
    perm = rng.permutation(len(samples))
    shuffled = near_triangles(hull, samples[perm], faces[perm], eps)
    assert {(int(perm[i]), t) for i, t in _near_pairs(shuffled, faces[perm])} == expected


# --------------------------------------------------------------------------------------------
# Dilated sets against ray casting, exactly, on a small camera
# --------------------------------------------------------------------------------------------


def _small_raycast_setup(points, n_samp=3000):
    hull = convex_hull(points)
    samples, normals, faces = sample_on_hull(hull, n_samp, rng=6)
    return hull, samples, normals, faces


SMALL = Intrinsics.centred(160, 120, 119.0)  # the field of view of K, pixels 4x farther apart


@pytest.mark.parametrize("shape", ["sphere", "box", "slab"])
def test_dilation_captures_exactly_what_the_pixels_capture(shape):
    """Off the visible part, the dilated analytic sets are the ray-cast sets: the pixels of the
    ray-cast views, solved analytically. A sphere larger than the image (borders), a box, and
    a slab thinner than eps (its back lies within eps of its front)."""
    rng = np.random.default_rng(13)
    eps = 0.03
    if shape == "sphere":
        points = 0.62 * fibonacci_sphere(600)
    elif shape == "box":
        points = rng.uniform(-1.0, 1.0, (200, 3)) * [0.35, 0.2, 0.3]
    else:
        points = rng.uniform(-1.0, 1.0, (60, 3)) * [0.4, 0.3, 0.0] + [0.0, 0.0, 0.01]
        points = np.vstack([points, points * [1.0, 1.0, -1.0]])
    hull, samples, normals, faces = _small_raycast_setup(points)
    poses = viewspace_poses(original_viewspace())
    visible = view_sets(samples, normals, poses, SMALL, hull=hull, face_ids=faces, dilate=False)
    dilated = view_sets(
        samples, normals, poses, SMALL, eps=eps, hull=hull, face_ids=faces, dilate=True
    )
    raycast = view_sets(samples, normals, poses, SMALL, "raycast", eps, hull)
    assert np.all(dilated >= visible)
    added = dilated & ~visible
    assert added.sum() > 50
    facing = np.einsum("vij,ij->vi", poses[:, None, :3, 3] - samples, normals) > 0
    if shape == "sphere":
        assert (added & facing).any()  # just outside the image
    assert (added & ~facing).any()  # just behind the silhouette
    # Off the visible part: the same, up to float32 rendering. On it, the analytic sets keep
    # what faces seen obliquely may lose between pixels: nothing captured is missed.
    assert ((dilated != raycast) & ~visible).sum() <= 2
    assert (raycast & ~dilated).sum() <= 2
    near = near_triangles(hull, samples, faces, eps)
    again = dilate_view_sets(visible, samples, faces, hull, near, poses, SMALL)
    assert np.array_equal(again, dilated)


def test_dilation_behind_an_edge_needs_a_pixel():
    """Just behind a silhouette edge, all within eps of the facing side, which is seen so
    obliquely that its pixels' points lie farther apart than eps: a sample is captured only
    where a pixel's point comes that close, as in the rendered view."""
    hull, samples, normals, faces = _small_raycast_setup(cube_corners(0.2), 20000)
    # Just above the top face: it is seen at about 5 degrees, its far edge is a silhouette.
    poses = viewspace_poses(np.array([[1.0, 0.0, 0.28]]))
    visible = view_sets(samples, normals, poses, hull=hull, face_ids=faces, dilate=False)
    dilated = view_sets(samples, normals, poses, hull=hull, face_ids=faces, dilate=True)
    raycast = view_sets(samples, normals, poses, method="raycast", hull=hull)
    behind = (normals[:, 0] < -0.5) & (samples[:, 2] > 0.2 - DEFAULT_EPS)  # on -x, by the edge
    assert not visible[0, behind].any()
    assert 0 < dilated[0, behind].sum() < behind.sum()
    assert np.array_equal(dilated[0, behind], raycast[0, behind])


# --------------------------------------------------------------------------------------------
# Dilated sets against ray casting at full resolution
# --------------------------------------------------------------------------------------------


def _single_view_hull_points(view: int) -> np.ndarray:
    """What one full-resolution view of a synthetic chair sees, as the dataset renders it."""
    from nbv.assets.meshes import Mesh, normalise
    from nbv.assets.synthetic import build, catalogue
    from nbv.geometry.camera import backproject
    from nbv.render.raycast import render_raycast

    entry = next(e for e in catalogue() if e.category == "chair")
    mesh, _, _ = normalise(Mesh(*build(entry, 0)))
    pose = viewspace_poses(original_viewspace())[view]
    depth = render_raycast(mesh.vertices, mesh.faces, pose[None], K)
    return backproject(depth[0], K, pose)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "min_agreement"),
    [("sphere", 0.99), ("box", 0.99), ("chair view 1", 0.985), ("chair view 20", 0.985)],
)
def test_analytic_matches_raycast_up_to_oblique_faces(name, min_agreement):
    """Full 640 x 480 images, eps = DEFAULT_EPS, all 33 views, on a sphere, a box and hulls of
    single views. Everything the ray-cast sets hold, the dilated analytic sets hold too, and off
    the visible part they are the same (the dilation is exact per pixel). They differ on faces
    seen so obliquely that the pixels' points on them lie farther apart than eps: the analytic
    sets keep all of such a face."""
    rng = np.random.default_rng(5)
    if name == "sphere":
        points = 0.45 * fibonacci_sphere(1000)
    elif name == "box":
        points = rng.uniform(-1.0, 1.0, (200, 3)) * [0.35, 0.2, 0.3]
    else:
        points = _single_view_hull_points(int(name.split()[-1]))
    hull = convex_hull(points)
    samples, normals, faces = sample_on_hull(hull, 4096, rng=4)
    poses = viewspace_poses(original_viewspace())
    visible = view_sets(samples, normals, poses, hull=hull, face_ids=faces, dilate=False)
    analytic = view_sets(samples, normals, poses, hull=hull, face_ids=faces, dilate=True)
    raycast = view_sets(samples, normals, poses, method="raycast", hull=hull)
    assert (analytic == raycast).mean() >= min_agreement
    assert (analytic == raycast).mean() > (visible == raycast).mean()
    # Up to float32 rendering: nothing the pixels capture is missed ...
    assert (raycast & ~analytic).mean() < 1e-3
    # ... and off the visible part the two are the same.
    assert ((analytic != raycast) & ~visible).mean() < 1e-3
    # The rest: visible samples on faces seen so obliquely that the pixel spacing stretched
    # along the face (depth over focal length, over the cosine of the viewing angle) exceeds
    # eps.
    v, i = np.nonzero(analytic & ~raycast)
    assert np.all(visible[v, i])
    ray = poses[v, :3, 3] - samples[i]
    cosine = (ray * normals[i]).sum(axis=1) / np.linalg.norm(ray, axis=1)
    depth = (-ray * poses[v, :3, 2]).sum(axis=1)
    assert np.all(depth / K.fx / cosine > DEFAULT_EPS)
