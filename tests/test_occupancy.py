"""The occupancy map and the information gain of views: voxel traversal against a brute-force
slab test, the map against OctoMap itself, the compiled gains against plain numpy, and a scene
with a pocket that only one view can look into."""

import numpy as np
import octomap
import pytest
import trimesh
from shapes import INTO_POCKET, cup, pocket_scene

from nbv.bench.infogain import decision, numpy_ray_gains, numpy_traverse, plain_decision
from nbv.geometry.camera import Intrinsics, backproject, viewspace_poses
from nbv.geometry.viewspace import spread_views
from nbv.infogain.gain import (
    METRICS,
    frontier,
    ray_gains,
    view_gains,
)
from nbv.infogain.occupancy import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    Misses,
    OccupancyMap,
    OccupancySettings,
    background_directions,
    mask_directions,
)
from nbv.infogain.raytrace import traverse
from nbv.infogain.settings import InfoGainSettings
from nbv.render.raycast import render_raycast


def _slab_voxels(origin: np.ndarray, end: np.ndarray, n: int, bound: float) -> np.ndarray:
    """Every voxel whose box the segment meets with positive length, by the segment's entry."""
    res = 2 * bound / n
    ijk = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    lo, hi = ijk * res - bound, (ijk + 1) * res - bound
    d = end - origin
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (lo - origin) / d, (hi - origin) / d
    inside = (origin >= lo) & (origin < hi)
    t0 = np.where(d == 0, np.where(inside, -np.inf, np.inf), np.minimum(ta, tb)).max(axis=1)
    t1 = np.where(d == 0, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb)).min(axis=1)
    t0, t1 = np.maximum(t0, 0), np.minimum(t1, 1)
    met = np.flatnonzero(t0 < t1)
    return met[np.argsort(t0[met])]


def test_traversal_meets_the_voxels_of_a_brute_force_slab_test_in_order():
    rng = np.random.default_rng(0)
    n, bound = 8, 0.5
    origins = rng.uniform(-1.2, 1.2, (300, 3))
    ends = np.where(np.arange(300)[:, None] % 2, rng.uniform(-0.8, 0.8, (300, 3)),
                    rng.uniform(-1.5, 1.5, (300, 3)))  # fmt: skip
    ends[:20, 1] = origins[:20, 1]  # segments parallel to a grid plane
    got = traverse(origins, ends, n, bound)
    for row, o, e in zip(got, origins, ends, strict=True):
        np.testing.assert_array_equal(row[row >= 0], _slab_voxels(o, e, n, bound))
    # Without the end voxel: one voxel fewer exactly for the segments that end inside.
    short = traverse(origins, ends, n, bound, include_end=False)
    inside = (np.abs(ends) < bound).all(axis=1)
    counts, short_counts = (got >= 0).sum(axis=1), (short >= 0).sum(axis=1)
    np.testing.assert_array_equal(short_counts, counts - (inside & (counts > 0)))


def test_the_numpy_reference_traverses_the_same_voxels():
    rng = np.random.default_rng(3)
    origins, ends = rng.uniform(-1.2, 1.2, (500, 3)), rng.uniform(-0.6, 0.6, (500, 3))
    for include_end in (True, False):
        np.testing.assert_array_equal(
            numpy_traverse(origins, ends, 12, 0.6, include_end),
            traverse(origins, ends, 12, 0.6, include_end),
        )


def test_a_segment_that_misses_the_grid_crosses_nothing():
    out = traverse(np.array([[2.0, 2.0, 2.0]]), np.array([[3.0, 2.0, 2.0]]), 4, 0.5)
    assert out.shape == (1, 1) and out[0, 0] == -1


def _views_of_a_ball(rng: np.random.Generator, n_views: int = 6):
    ball = rng.normal(size=(3000, 3))
    ball = ball / np.linalg.norm(ball, axis=1, keepdims=True) * 0.3
    for _ in range(n_views):
        centre = rng.normal(size=3)
        centre /= np.linalg.norm(centre)
        misses = rng.normal(size=(600, 3)) * 0.4 - centre
        unit = misses / np.linalg.norm(misses, axis=1, keepdims=True)
        # Rays that hit nothing pass the ball: their line keeps 0.35 from its centre.
        passing = np.linalg.norm(np.cross(unit, -centre), axis=1) > 0.35
        yield centre, ball[ball @ centre > 0.05], misses[passing]


def test_the_map_matches_octomap_voxel_for_voxel():
    settings = OccupancySettings(resolution=0.04, bound=0.56, object_radius=None)
    ours = OccupancyMap(settings)
    tree = octomap.OcTree(settings.resolution)
    tree.setProbHit(settings.p_hit)
    tree.setProbMiss(settings.p_miss)
    tree.setClampingThresMin(settings.clamp_min)
    tree.setClampingThresMax(settings.clamp_max)
    reach = 1.0 + 2 * np.sqrt(3) * settings.bound
    for centre, hits, misses in _views_of_a_ball(np.random.default_rng(1)):
        ours.insert_view(centre, hits, misses)
        # OctoMap carves a ray longer than maxrange free up to maxrange, and skips its end.
        far = centre + misses / np.linalg.norm(misses, axis=1, keepdims=True) * (reach + 1)
        tree.insertPointCloud(np.concatenate([hits, far]), centre, maxrange=reach)
    labels = ours.labels()
    theirs = np.asarray(tree.getLabels(ours.centres()))
    np.testing.assert_array_equal(labels, theirs)
    assert {UNKNOWN, FREE, OCCUPIED} <= set(labels.tolist())
    # The same log-odds, not only the same side of 0.5.
    known = np.flatnonzero(labels != UNKNOWN)[::97]
    for v in known:
        node = tree.search(ours.centres()[v])
        assert node.getLogOdds() == pytest.approx(ours.log_odds[v], abs=1e-5)


#: The metrics the plain-numpy reference of the benchmark implements (area_factor and
#: proximity_count have their own tests: test_information_gain_metrics.py).
SUMMED = ("unobserved", "entropy", "rear_side_voxel", "rear_side_entropy", "frontier")


def test_every_metric_is_tested():
    assert set(METRICS) == {*SUMMED, "area_factor", "proximity_count"}


@pytest.mark.parametrize("metric", SUMMED)
def test_compiled_ray_gains_equal_plain_numpy(metric):
    rng = np.random.default_rng(2)
    occupancy = OccupancyMap(OccupancySettings(resolution=0.08, bound=0.56))
    for centre, hits, misses in _views_of_a_ball(rng, 3):
        occupancy.insert_view(centre, hits, misses)
    origins = rng.normal(size=(400, 3))
    origins /= np.linalg.norm(origins, axis=1, keepdims=True)
    voxels = traverse(origins, -origins * 1.5, occupancy.settings.n, 0.56)
    got = ray_gains(occupancy, voxels, metric)
    reference = numpy_ray_gains(occupancy.log_odds, voxels, metric, frontier(occupancy))
    np.testing.assert_allclose(got, reference, rtol=1e-12)
    assert got.max() > 0
    with pytest.raises(ValueError, match="metric='volume': must be one of unobserved"):
        ray_gains(occupancy, voxels, "volume")
    if metric in ("unobserved", "frontier"):
        capped = ray_gains(occupancy, voxels, metric, depth=2)
        np.testing.assert_array_equal(capped, np.minimum(reference, 2))
        np.testing.assert_array_equal(
            capped, numpy_ray_gains(occupancy.log_odds, voxels, metric, frontier(occupancy), 2)
        )
        assert reference.max() > 2  # the cap binds on some rays


def test_background_blocks_are_those_no_point_falls_in():
    camera = Intrinsics.centred(64, 48, 48.0)
    pose = viewspace_poses(np.array([[0.0, 0.0, 1.0]]))[0]
    depth = np.full((48, 64), np.inf)
    depth[:, :32] = 1.0  # the left half of the image sees a wall
    points = backproject(depth, camera, pose)
    directions = background_directions(points, pose, camera, block=16)
    assert directions.shape == (6, 3)  # the right half: 2 x 3 blocks of 16 pixels
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0)
    # They leave the camera through the right half of the image.
    cam = directions @ pose[:3, :3]
    assert (cam[:, 0] > 0).all() and (cam[:, 2] > 0).all()
    with pytest.raises(ValueError, match="block=0"):
        background_directions(points, pose, camera, block=0)


def test_mask_blocks_of_a_full_image_are_the_background_blocks_of_all_its_points():
    """A rendered view: its no-return mask gives the dataset's background blocks bit for bit
    (every point kept), and the same however few points are kept."""
    camera = Intrinsics.centred(64, 48, 48.0)
    pose = viewspace_poses(np.array([[0.3, 0.4, 0.9]]))[0]
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.35)
    depth = render_raycast(mesh.vertices, mesh.faces, pose[None], camera)[0]
    points = backproject(depth, camera, pose)
    mask = ~np.isfinite(depth)
    for block in (1, 4, 16, 20):
        np.testing.assert_array_equal(
            mask_directions(mask, pose, camera, block),
            background_directions(points, pose, camera, block),
        )
    # A block with one measured (or unknown) pixel is not a miss.
    partial = np.ones((48, 64), dtype=bool)
    partial[5, 5] = False
    assert len(mask_directions(partial, pose, camera, 16)) == 3 * 4 - 1
    few = points[::40]
    assert len(background_directions(few, pose, camera, 4)) > len(
        mask_directions(mask, pose, camera, 4)
    )
    grid = OccupancyMap()
    for keep in (points, few):
        carved = grid.sensed_voxels(keep, pose, camera, 4, Misses(mask))
        free, hit = grid.view_voxels(pose[:3, 3], keep, mask_directions(mask, pose, camera, 4))
        np.testing.assert_array_equal(carved[0], free)
        np.testing.assert_array_equal(carved[1], hit)
    with pytest.raises(ValueError, match="block=0"):
        mask_directions(mask, pose, camera, block=0)


def test_a_sensed_view_carves_only_what_its_user_declared():
    """Unknown no-return carves nothing beyond the hits; a range stops the misses at that planar
    depth (here inside the map: the far half of the region stays unknown)."""
    camera = Intrinsics.centred(32, 24, 24.0)
    # Off the grid's planes: a ray along a voxel face may take either voxel.
    pose = viewspace_poses(np.array([[0.013, 0.007, 1.0]]))[0]
    grid = OccupancyMap(OccupancySettings(object_radius=None))
    none = np.zeros((0, 3))
    free, hit = grid.sensed_voxels(none, pose, camera, 8, None)
    assert len(free) == len(hit) == 0
    everything = np.ones((24, 32), dtype=bool)
    free, _ = grid.sensed_voxels(none, pose, camera, 8, Misses(everything))
    near, _ = grid.sensed_voxels(none, pose, camera, 8, Misses(everything, reach=1.0))
    assert set(near) < set(free)
    # The rays end at planar depth 1: about z = 0 (the camera is at z = 1, looking down -z).
    z = grid.centres()[near][:, 2]
    assert z.min() >= -grid.settings.resolution and grid.centres()[free][:, 2].min() < -0.5


@pytest.mark.parametrize("metric", ["unobserved", "rear_side_voxel", "rear_side_entropy"])
def test_information_gain_looks_into_the_pocket_where_spread_does_not(metric):
    # (entropy does not: it prefers views through lightly observed free space, whose voxels
    # have an entropy near 1 after one crossing at OctoMap's p_miss = 0.4)
    directions, _, _, captured, voxels, occupancy = pocket_scene()
    gains = view_gains(occupancy, voxels, metric)
    assert int(np.argmax(np.where(captured, -1, gains))) == INTO_POCKET
    assert spread_views(directions, captured, 1)[0] != INTO_POCKET


def test_the_plain_decision_of_the_benchmark_is_the_planners():
    mesh = cup()
    camera = Intrinsics.centred(96, 72, 72.0)
    poses = viewspace_poses(np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, 0, 1], [1, 1, 1.0]]))
    depth = render_raycast(mesh.vertices, mesh.faces, poses, camera)
    views = [(v, backproject(depth[v], camera, poses[v])) for v in (1, 3)]
    settings = InfoGainSettings(resolution=0.04, block=4)
    assert decision(views, poses, camera, settings) == plain_decision(
        views, poses, camera, settings
    )


def test_the_frontier_is_the_unknown_ring_around_occupied_voxels():
    occupancy = OccupancyMap(OccupancySettings(resolution=0.1, bound=0.5, object_radius=None))
    n = occupancy.settings.n
    occupancy.log_odds[(5 * n + 5) * n + 5] = 1.0  # one occupied voxel
    occupancy.log_odds[(5 * n + 5) * n + 6] = -1.0  # a free neighbour
    ring = frontier(occupancy).reshape(n, n, n)
    assert ring.sum() == 25 and ring[4:7, 4:7, 4:7].sum() == 25


def test_the_frontier_is_scipys_dilation_of_the_occupied_voxels():
    from scipy import ndimage

    occupancy = OccupancyMap(OccupancySettings(resolution=0.1, bound=0.5, object_radius=None))
    n = occupancy.settings.n
    rng = np.random.default_rng(4)
    for share in (0.0, 0.02, 0.2):
        values = rng.choice([np.nan, -1.0, 0.0, 1.0], size=n**3, p=[0.6, 0.4 - share, 0, share])
        values[[0, n - 1, n**3 - 1]] = 1.0  # corners and edges: neighbours off the grid
        occupancy.log_odds[:] = values
        grid = values.reshape(n, n, n)
        near = ndimage.binary_dilation(grid >= 0, structure=np.ones((3, 3, 3), bool))
        np.testing.assert_array_equal(frontier(occupancy), (near & np.isnan(grid)).ravel())
