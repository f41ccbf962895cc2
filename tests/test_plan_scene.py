"""Captures as a depth camera on a robot gives them: an object on a table with a wall behind it,
rendered by the project's ray caster with the depth-noise model, grazing-angle dropout, random
missing pixels and a range limit (:mod:`nbv.render.scene`), planned by ``python -m nbv.plan``'s
library function."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest
from capturegen import plan_captures
from scipy.spatial import ConvexHull

from nbv.assets.synthetic.catalogue import make_model
from nbv.geometry.camera import Intrinsics, backproject
from nbv.infogain.occupancy import FREE, OCCUPIED, UNKNOWN
from nbv.infogain.settings import InfoGainSettings
from nbv.plan.config import PlanSettings
from nbv.policies.episode import captured_state
from nbv.policies.infogain import InfoGainPolicy
from nbv.render.scene import OBJECT, TABLE, WALL, SceneSettings, table_scene
from nbv.scan.candidates import REASONS, CandidateSettings, limit_candidates
from nbv.scan.captures import read_captures, write_captures
from nbv.scan.frame import ObjectFrame
from nbv.scan.object_estimate import Plane
from nbv.scan.placement import sensed_misses
from nbv.scan.settings import ObjectSettings, ViewspaceSettings

CAMERA = Intrinsics.centred(320, 240, 238.0)
#: The candidates: a sphere of 32 directions about the object, 0.45 m out (z up).
SPHERE = ViewspaceSettings(kind="sphere", n=32, up="z", radius=0.45)


@pytest.fixture(scope="module")
def mesh():
    """A synthetic cabinet, turned from ShapeNet's Y up to the table's Z up."""
    vertices, faces = make_model("cabinet", np.random.default_rng(1))
    return vertices[:, [0, 2, 1]] * np.array([1.0, -1.0, 1.0]), faces


@pytest.fixture(scope="module")
def noisy(mesh):
    return table_scene(*mesh, CAMERA, SceneSettings(), seed=0)


@pytest.fixture(scope="module")
def clean(mesh):
    return table_scene(*mesh, CAMERA, SceneSettings(noise=None, missing=0.0, max_range=None), 0)


def folder_of(scene, path, depth=None, views=None, **kw):
    depth = scene.depth if depth is None else depth
    poses = scene.poses if views is None else scene.poses[views]
    write_captures(path, depth, poses, scene.intrinsics, None, None, **kw)
    return path


def settings_for(folder, tmp_path, **kw) -> PlanSettings:
    return PlanSettings(out_dir=tmp_path / "out", captures=folder, method="ig", camera=CAMERA,
                        viewspace=SPHERE, points_per_view=0, **kw)  # fmt: skip


def test_the_scene_is_a_sensor_view_of_an_object_on_a_table_before_a_wall(noisy):
    shown = {int(k) for k in np.unique(noisy.labels)}
    assert {OBJECT, TABLE, WALL} <= shown
    missing = noisy.depth == 0
    # 15 % lost at random, more at grazing angles, all of it where the clean view saw something.
    assert 0.15 < missing[noisy.labels != 0].mean() < 0.5
    assert (noisy.depth[~missing] <= noisy.settings.max_range).all()
    near = ~missing & (noisy.labels == OBJECT)
    assert np.median(np.abs(noisy.depth[near] - noisy.clean[near])) < 0.003


def test_the_object_is_found_without_object_settings(noisy, tmp_path):
    folder = folder_of(noisy, tmp_path / "caps")
    result = plan_captures(settings_for(folder, tmp_path))
    assert result.object_source == "estimated" and result.estimate["trusted"]
    error = np.linalg.norm(result.frame.center - noisy.center)
    assert error < 0.10 * noisy.radius
    assert abs(result.frame.radius - noisy.radius) < 0.25 * noisy.radius


def test_the_table_and_the_wall_are_not_counted_as_the_object(noisy, tmp_path):
    from nbv.scan.object_estimate import EstimateSettings, estimate_object

    captures, _ = read_captures(folder_of(noisy, tmp_path / "caps"))
    est = estimate_object(noisy.poses, [c.points for c in captures], np.array([0.0, 0.0, 1.0]),
                          EstimateSettings(), 0)  # fmt: skip
    # The planes removed: the table's top z = 0 (the support) and the wall y = 0.3.
    support = est.support_plane
    assert support is not None and support.normal @ [0, 0, 1] > 0.999
    assert abs(support.offset) < 0.003
    walls = [p for i, p in enumerate(est.planes) if i != est.support]
    assert any(p.normal @ [0, -1, 0] > 0.999 and abs(p.offset - 0.3) < 0.003 for p in walls)
    # Every point kept as the object lies on the object's mesh (within the sensor's noise),
    # none on the table or the wall.
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(noisy.vertices.astype(np.float32)),
                        o3d.core.Tensor(noisy.faces.astype(np.uint32)))  # fmt: skip
    distance = scene.compute_distance(o3d.core.Tensor(est.points.astype(np.float32))).numpy()
    assert np.quantile(distance, 0.99) < 0.005
    assert est.points[:, 2].min() > -0.002 and est.points[:, 1].max() < 0.29
    # And most of the object's measured points are in it.
    on_object = sum(int(((c.points[:, 2] > 0.005) & (c.points[:, 1] < 0.25)
                         & (np.linalg.norm(c.points - noisy.center, axis=1) < 0.11)).sum())
                    for c in captures)  # fmt: skip
    assert est.counts["object"] > 0.3 * on_object * est.counts["thinned"] / est.counts["captured"]


def _ig_map(folder, frame: ObjectFrame, camera=CAMERA):
    """ig's occupancy map of a capture folder's views (every point kept)."""
    captures, _ = read_captures(folder)
    poses = frame.poses_to_normalised(np.stack([c.pose for c in captures]))
    parts = [frame.points_to_normalised(c.points).astype(np.float32) for c in captures]
    state = captured_state(poses, parts, list(range(len(captures))),
                           misses=sensed_misses(captures, frame))  # fmt: skip
    policy = InfoGainPolicy(InfoGainSettings(), camera)
    policy.update(state)
    return policy.occupancy


def test_a_patch_of_missing_depth_on_the_object_leaves_its_voxels_unknown(clean, tmp_path):
    frame = ObjectFrame(clean.center, clean.radius, "z")
    # A patch of 2 x 2 of ig's 16-pixel blocks, wholly on the object in the middle view: its
    # depth lost.
    v, size = 1, 32
    on = clean.labels[v] == OBJECT
    corners = [(r, c) for r in range(0, on.shape[0] - size, 16)
               for c in range(0, on.shape[1] - size, 16)]  # fmt: skip
    spots = [(r, c) for r, c in corners if on[r : r + size, c : c + size].all()]
    assert spots
    r0, c0 = spots[len(spots) // 2]
    patch = np.zeros(on.shape, dtype=bool)
    patch[r0 : r0 + size, c0 : c0 + size] = True
    depth = np.where(np.isfinite(clean.clean), clean.clean, 0.0).astype(np.float32)
    holed = depth[[v]].copy()
    holed[0][patch] = 0.0
    one = dict(depth=holed, views=[v])
    unknown = _ig_map(folder_of(clean, tmp_path / "unknown", **one), frame)
    free = _ig_map(folder_of(clean, tmp_path / "free", no_return="free", **one), frame)

    def voxels_of(mask):
        points = backproject(np.where(mask, clean.clean[v], np.inf), CAMERA, clean.poses[v])
        cells = np.unique(unknown.voxel_of(frame.points_to_normalised(points)))
        return cells[cells >= 0]

    # The surface behind each block's centre pixel: the ray ig would carve for a miss.
    centres = np.zeros_like(patch)
    centres[r0 + 8 : r0 + size : 16, c0 + 8 : c0 + size : 16] = True
    # Read as unknown (the default), the hidden surface stays unknown; read as free (a rendered
    # view's background), the hole carves it: the old rule's mistake on a sensor's view.
    assert (unknown.labels()[voxels_of(centres)] == UNKNOWN).all()
    assert (free.labels()[voxels_of(centres)] == FREE).all()
    # Over the whole patch: some hidden voxels share a voxel with measured surface beside the
    # hole (occupied), a few are crossed by the rays to it; none is carved by a miss.
    hidden = unknown.labels()[voxels_of(patch)]
    assert (hidden == UNKNOWN).mean() > 0.7 and (hidden == FREE).mean() < 0.1
    # The measured surface around the hole is occupied.
    cells = voxels_of(on & ~patch)
    assert (unknown.labels()[cells] == OCCUPIED).mean() > 0.9


def test_subsampled_points_make_no_misses_the_full_image_has_not(clean, tmp_path):
    """A rendered view declared free: its misses come from the full image's mask, so keeping
    few of its points carves no more free space than keeping all of them."""
    frame = ObjectFrame(clean.center, clean.radius, "z")
    depth = np.where(np.isfinite(clean.clean), clean.clean, 0.0).astype(np.float32)
    folder = folder_of(clean, tmp_path / "caps", depth=depth[[1]], views=[1], no_return="free")
    captures, _ = read_captures(folder)
    pose = frame.poses_to_normalised(captures[0].pose)
    points = frame.points_to_normalised(captures[0].points)
    (misses,) = sensed_misses(captures, frame)
    from nbv.infogain.occupancy import OccupancyMap

    grid = OccupancyMap(InfoGainSettings().occupancy())
    full = grid.sensed_voxels(points, pose, CAMERA, 16, misses)
    few = grid.sensed_voxels(points[::50], pose, CAMERA, 16, misses)
    old_few = grid.captured_voxels(points[::50], pose, CAMERA, 16)
    free_full, free_few, free_old = set(full[0]), set(few[0]), set(old_few[0])
    # The few points' rays cross fewer voxels, and no miss is added: every free voxel of the few
    # was free with all points (or held one of the points the few left out).
    assert free_few <= free_full | set(full[1])
    assert len(free_old - free_full) > 100  # the dataset's rule on few points: empty blocks


def test_the_plan_from_noisy_captures_with_holes_is_within_one_view_of_the_clean_plan(
    noisy, clean, tmp_path
):
    obj = ObjectSettings(tuple(noisy.center.tolist()), noisy.radius)
    depth = np.where(np.isfinite(clean.clean), clean.clean, 0.0).astype(np.float32)
    plans = []
    for name, d in (("noisy", noisy.depth), ("clean", depth)):
        folder = folder_of(noisy, tmp_path / name, depth=d)
        plans.append(plan_captures(settings_for(folder, tmp_path / name, object=obj)))
    (noisy_plan, clean_plan) = plans
    assert noisy_plan.n_candidates == clean_plan.n_candidates == 32
    # One view apart: neighbours on the viewspace, an edge of its directions' convex hull
    # (the sphere's triangulation).
    directions = clean_plan.views.poses[: clean_plan.n_candidates, :3, 3]
    edges = {frozenset(e) for t in ConvexHull(directions).simplices
             for e in ((t[0], t[1]), (t[1], t[2]), (t[0], t[2]))}  # fmt: skip
    a, b = noisy_plan.chosen[0], clean_plan.chosen[0]
    assert a == b or frozenset((a, b)) in edges


def test_candidates_below_the_table_and_behind_the_wall_are_dropped_and_counted(noisy, tmp_path):
    folder = folder_of(noisy, tmp_path / "caps")
    walls = ((0.0, -1.0, 0.0, 0.3),)  # the wall's face y = 0.3; the allowed side y < 0.3
    result = plan_captures(
        settings_for(folder, tmp_path, candidates=CandidateSettings(walls=walls))
    )
    limits = result.candidate_limits
    # Brute force on the viewspace placed about the estimated centre.
    directions = SPHERE.directions()
    positions = result.frame.center + 0.45 * directions
    below = positions @ limits["support"]["normal"] + limits["support"]["offset"] <= 0
    behind = ~below & (positions[:, 1] >= 0.3)
    assert below.sum() > 0 and behind.sum() > 0
    assert limits["by_reason"]["support"] == below.sum()
    assert limits["by_reason"]["wall"] == behind.sum()
    assert limits["dropped"] == below.sum() + behind.sum() == len(limits["dropped_views"])
    assert sorted(limits["kept_views"]) == np.flatnonzero(~below & ~behind).tolist()
    assert result.n_candidates == len(limits["kept_views"])
    chosen = limits["kept_views"][result.chosen[0]]
    assert not below[chosen] and not behind[chosen]


def test_candidate_limits_on_known_positions():
    support = Plane(np.array([0.0, 0.0, 1.0]), 0.0, 0)
    center = np.array([0.0, 0.0, 0.1])
    # Elevations (seen from the centre) of -30, 0, 10, 40, 80 degrees, all 1 m out along +x.
    el = np.radians([-30.0, 0.0, 10.0, 40.0, 80.0])
    positions = center + np.stack([np.cos(el), np.zeros(5), np.sin(el)], axis=1)
    keep, dropped = limit_candidates(positions, center, CandidateSettings(min_elevation=20.0),
                                     support)  # fmt: skip
    # -30 degrees lies below the table (z < 0): the support; 0 and 10 are too low.
    assert keep.tolist() == [False, False, False, True, True]
    assert dropped == {"support": 1, "elevation": 2, "wall": 0, "cone": 0, "box": 0}
    assert list(dropped) == list(REASONS)
    cone = CandidateSettings(cone_axis=(0.0, 0.0, 1.0), cone_degrees=45.0)
    keep, dropped = limit_candidates(positions, center, cone, None)
    assert keep.tolist() == [False, False, False, False, True] and dropped["cone"] == 4
    # z = 0.1 + sin(elevation): -0.4, 0.1, 0.27, 0.74, 1.08.
    box = CandidateSettings(box_min=(-2.0, -2.0, 0.2), box_max=(2.0, 2.0, 0.8))
    keep, dropped = limit_candidates(positions, center, box, None)
    assert keep.tolist() == [False, False, True, True, False] and dropped["box"] == 3
    with pytest.raises(ValueError, match="candidates.support"):
        limit_candidates(positions, center, CandidateSettings(min_elevation=0.0), None)
