"""Convex-hull set cover: greedy against brute force, hull sampling, the arguments of
view_sets, and whole plans (with and without the dilation). The visibility and the dilation have
their own tests: test_visibility.py, test_dilation.py."""

from dataclasses import replace
from itertools import combinations

import numpy as np
import pytest
from scipy.spatial import ConvexHull
from shapes import cube_corners, fibonacci_sphere

from nbv.geometry.camera import Intrinsics, viewspace_poses
from nbv.geometry.scores import DEFAULT_EPS
from nbv.geometry.sph import equiangular_directions, signature_with_centroid, unit_vectors
from nbv.geometry.viewspace import original_viewspace, spread_views
from nbv.policies.setcover import SetCoverPolicy
from nbv.setcover.greedy import greedy_max_coverage, pack_sets
from nbv.setcover.hull_sampling import cameras_inside, convex_hull, sample_hull, sample_on_hull
from nbv.setcover.oneshot import plan, sph_hull_points
from nbv.setcover.settings import SetCoverSettings
from nbv.setcover.view_sets import view_sets
from nbv.utils.bits import popcount_rows


def _reference_greedy(
    sets: np.ndarray, n_iter: int, exclude=(), positions=None
) -> tuple[list[int], list[int]]:
    """Algorithm 3 on plain booleans, written independently of the bit-packed version. With
    ``positions``, a pick that gains nothing is the open view farthest in angle from the closed
    ones (ties within 1e-9 rad: the lowest index)."""
    covered = np.zeros(sets.shape[1], dtype=bool)
    closed = np.zeros(len(sets), dtype=bool)
    for v in exclude:
        covered |= sets[v]
        closed[v] = True
    views, gains = [], []
    for _ in range(n_iter):
        new = (sets & ~covered).sum(axis=1)
        new[closed] = -1
        best = int(np.argmax(new))
        if new[best] == 0 and positions is not None:
            best = _farthest_in_angle(positions, closed)
        views.append(best)
        gains.append(int(new[best]))
        closed[best] = True
        covered |= sets[best]
    return views, gains


def _farthest_in_angle(positions: np.ndarray, closed: np.ndarray) -> int:
    """The open view whose smallest angle to a closed view is largest (lowest index on ties)."""
    unit = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    best, best_angle = -1, -1.0
    for v in np.flatnonzero(~closed):
        cosines = unit[closed] @ unit[v]
        angle = float(np.arccos(np.clip(cosines, -1.0, 1.0)).min()) if closed.any() else np.pi
        if angle > best_angle + 1e-9:
            best, best_angle = int(v), angle
    return best


def _farthest_in_angle_all(positions: np.ndarray, closed: np.ndarray) -> list[int]:
    """Every open view whose smallest angle to a closed view is within 1e-9 rad of the largest
    such angle."""
    unit = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    open_ = np.flatnonzero(~closed)
    angles = np.arccos(np.clip(unit[open_] @ unit[closed].T, -1.0, 1.0)).min(axis=1)
    return [int(v) for v in open_[angles >= angles.max() - 1e-9]]


def _check_plan(views, gains, sets, exclude, positions) -> None:
    """``views`` and ``gains`` are a greedy plan of ``sets``: its covering picks (gain > 0) and
    its gains those of :func:`_reference_greedy`, each zero-gain pick one of the views farthest
    in angle from the closed ones (whichever of them a random tie-break chose)."""
    reference = _reference_greedy(sets, len(views), exclude, positions)
    covering = sum(1 for g in gains if g > 0)
    assert views[:covering] == reference[0][:covering] and gains == reference[1]
    closed = np.isin(np.arange(len(sets)), [*exclude, *views[:covering]])
    for view in views[covering:]:
        assert view in _farthest_in_angle_all(positions, closed)
        closed[view] = True


def _union_size(sets: np.ndarray, views) -> int:
    return int(sets[list(views)].any(axis=0).sum()) if len(views) else 0


# --------------------------------------------------------------------------------------------
# Greedy maximum coverage
# --------------------------------------------------------------------------------------------


def test_greedy_against_brute_force_optimum():
    rng = np.random.default_rng(0)
    bound = 1.0 - 1.0 / np.e
    suboptimal = 0
    for _ in range(150):
        sets = rng.random((8, 30)) < rng.uniform(0.1, 0.5)
        for k in (1, 2, 3):
            views, gains = greedy_max_coverage(sets, k)
            assert len(set(views)) == k
            assert sum(gains) == _union_size(sets, views)
            optimum = max(_union_size(sets, c) for c in combinations(range(8), k))
            assert sum(gains) <= optimum
            assert sum(gains) >= bound * optimum
            if k == 1:
                assert sum(gains) == optimum
            suboptimal += sum(gains) < optimum
    # The instances are hard enough that greedy is sometimes beaten: the comparison has teeth.
    assert suboptimal > 0


def test_greedy_hand_built_order():
    sets = np.zeros((4, 11), dtype=bool)
    sets[0, 0:6] = True  # 6 elements: first
    sets[1, [0, 1, 2, 6]] = True  # 4, but 3 of them go with view 0
    sets[2, 6:10] = True  # 4 new after view 0: second
    sets[3, [3, 4, 5, 10]] = True  # 1 new after views 0 and 2
    assert greedy_max_coverage(sets, 3) == ([0, 2, 3], [6, 4, 1])
    assert greedy_max_coverage(sets, 4) == ([0, 2, 3, 1], [6, 4, 1, 0])


def test_greedy_is_not_optimal_where_it_need_not_be():
    # The classic trap: the largest set first leaves only one new element for either half.
    sets = np.zeros((3, 6), dtype=bool)
    sets[0, 1:5] = True
    sets[1, 0:3] = True
    sets[2, 3:6] = True
    assert greedy_max_coverage(sets, 2) == ([0, 1], [4, 1])  # 5 of the optimal 6


def test_greedy_gains_are_marginal_and_match_reference():
    rng = np.random.default_rng(1)
    for n in (1, 63, 64, 65, 1000):
        sets = rng.random((12, n)) < 0.3
        for exclude in ((), (3,), (0, 5, 5)):
            views, gains = greedy_max_coverage(sets, 6, exclude)
            assert (views, gains) == _reference_greedy(sets, 6, sorted(set(exclude)))
            covered = sets[list(exclude)].any(axis=0) if exclude else np.zeros(n, dtype=bool)
            for v, g in zip(views, gains, strict=True):
                # Algorithm 3: a pick counts only what nothing chosen before covered.
                assert g == int((sets[v] & ~covered).sum())
                covered |= sets[v]
            assert gains == sorted(gains, reverse=True)


def test_greedy_matches_reference_on_block_sets():
    # Sets made of a few runs of consecutive elements, like hull samples grouped by triangle:
    # after the first picks the new elements sit in few 64-bit words.
    rng = np.random.default_rng(9)
    for _ in range(20):
        sets = np.zeros((20, 4000), dtype=bool)
        for row in sets:
            for start in rng.integers(0, 4000, rng.integers(1, 6)):
                row[start : start + rng.integers(10, 800)] = True
        for exclude in ((), (int(rng.integers(20)),)):
            assert greedy_max_coverage(sets, 9, exclude) == _reference_greedy(sets, 9, exclude)


def test_greedy_ties_go_to_the_lowest_index():
    sets = np.ones((4, 10), dtype=bool)
    assert greedy_max_coverage(sets, 3) == ([0, 1, 2], [10, 0, 0])
    assert greedy_max_coverage(sets, 3, exclude=[1]) == ([0, 2, 3], [0, 0, 0])


def _circle(degrees) -> np.ndarray:
    angle = np.radians(degrees)
    return np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=1)


def test_greedy_spreads_zero_gain_picks_by_angle():
    # Views on a circle (degrees); view 0 is visited, view 1 has the one element left.
    positions = 2.0 * _circle([0, 10, 20, 90, 180, 270, 135])
    sets = np.zeros((7, 5), dtype=bool)
    sets[0, 1:] = True
    sets[1, 0] = True
    # By index: 1 (gain 1), then 2, 3, 4.
    assert greedy_max_coverage(sets, 4, exclude=(0,)) == ([1, 2, 3, 4], [1, 0, 0, 0])
    # Spread: 1; then 180 (170 degrees from {0, 10}); then 270 (90) before 90 (80); then 90.
    spread = greedy_max_coverage(sets, 4, exclude=(0,), positions=positions)
    assert spread == ([1, 4, 5, 3], [1, 0, 0, 0])
    assert spread[0] == _reference_greedy(sets, 4, [0], positions)[0]
    # Only the directions count, not the distances.
    scaled = positions * np.array([1.0, 3.0, 0.5, 2.0, 1.0, 7.0, 1.0])[:, None]
    assert greedy_max_coverage(sets, 4, exclude=(0,), positions=scaled) == spread
    # Ties go to the lowest index: 90 and 270 are both 90 degrees from {0, 180}.
    nothing = np.zeros((7, 5), dtype=bool)
    assert greedy_max_coverage(nothing, 4, exclude=(0,), positions=positions) == (
        [4, 3, 5, 6],
        [0, 0, 0, 0],
    )
    # Nothing visited and nothing to cover: the first pick is view 0, then its opposite.
    assert greedy_max_coverage(nothing, 2, positions=positions)[0] == [0, 4]
    # With a generator the tie between 90 and 270 is broken at random: each seed's fill is a
    # maximin spread, the same seed gives the same fill, and both tied views come first for
    # some seed.
    seeded = {
        seed: greedy_max_coverage(
            nothing, 4, exclude=(0,), positions=positions, rng=np.random.default_rng(seed)
        )[0]
        for seed in range(20)
    }
    assert {tuple(v) for v in seeded.values()} == {(4, 3, 5, 6), (4, 5, 3, 6)}
    again = greedy_max_coverage(
        nothing, 4, exclude=(0,), positions=positions, rng=np.random.default_rng(3)
    )[0]
    assert again == seeded[3]


def test_greedy_rejects_bad_positions():
    sets = np.ones((3, 5), dtype=bool)
    with pytest.raises(ValueError, match="positions"):
        greedy_max_coverage(sets, 2, positions=np.ones((2, 3)))
    with pytest.raises(ValueError, match="positions"):
        greedy_max_coverage(sets, 2, positions=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="positions"):
        greedy_max_coverage(sets, 2, positions=np.full((3, 3), np.nan))


def test_greedy_spread_matches_reference_on_random_viewspaces():
    rng = np.random.default_rng(14)
    for _ in range(20):
        positions = rng.normal(size=(15, 3))
        sets = rng.random((15, 12)) < 0.2
        exclude = tuple(int(v) for v in rng.choice(15, int(rng.integers(0, 3)), replace=False))
        expected = _reference_greedy(sets, 10, exclude, positions)
        assert greedy_max_coverage(sets, 10, exclude, positions) == expected
        assert expected[1][-3:] == [0, 0, 0]  # the fill was exercised


def test_greedy_exclude_removes_the_visited_views_elements():
    sets = np.zeros((3, 7), dtype=bool)
    sets[0, 0:6] = True
    sets[1, 0:5] = True
    sets[2, 6] = True
    assert greedy_max_coverage(sets, 2) == ([0, 2], [6, 1])
    # View 0 visited: view 1 has nothing new, so the single new element of view 2 wins.
    assert greedy_max_coverage(sets, 2, exclude=(0,)) == ([2, 1], [1, 0])


def test_greedy_rejects_bad_input():
    sets = np.ones((3, 5), dtype=bool)
    with pytest.raises(ValueError, match="n_iter=3 exceeds"):
        greedy_max_coverage(sets, 3, exclude=(0,))
    with pytest.raises(ValueError, match="outside"):
        greedy_max_coverage(sets, 1, exclude=(3,))
    with pytest.raises(ValueError, match="boolean matrix"):
        greedy_max_coverage(np.ones(5, dtype=bool), 1)
    with pytest.raises(ValueError, match="booleans"):
        greedy_max_coverage(np.full((3, 5), 0.5), 1)
    with pytest.raises(ValueError, match="n_iter"):
        greedy_max_coverage(sets, -1)


def test_pack_and_popcount():
    rng = np.random.default_rng(2)
    sets = rng.random((5, 130)) < 0.5
    rows = pack_sets(sets)
    assert rows.dtype == np.uint64 and rows.shape == (5, 3)
    bits = np.unpackbits(rows.view(np.uint8), axis=1, bitorder="little")
    assert np.array_equal(bits[:, :130].astype(bool), sets)
    assert not bits[:, 130:].any()
    assert np.array_equal(popcount_rows(rows), sets.sum(axis=1))
    words = rng.integers(0, 2**63, size=(4, 7), dtype=np.uint64) * np.uint64(2) + np.uint64(1)
    expected = [[bin(int(w)).count("1") for w in row] for row in words]
    assert np.array_equal(popcount_rows(words), np.sum(expected, axis=1))


# --------------------------------------------------------------------------------------------
# Hull samples
# --------------------------------------------------------------------------------------------


def test_sample_hull_lies_on_the_hull_with_outward_normals():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(200, 3)) * [0.3, 0.2, 0.1] + [0.1, 0.0, -0.05]
    samples, normals, faces = sample_hull(points, 5000, rng=7)
    hull = ConvexHull(points)
    assert samples.shape == normals.shape == (5000, 3) and faces.shape == (5000,)
    plane = hull.equations[faces]
    assert np.abs((samples * plane[:, :3]).sum(axis=1) + plane[:, 3]).max() < 1e-12
    assert (samples @ hull.equations[:, :3].T + hull.equations[:, 3]).max() < 1e-12
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    assert ((samples - points.mean(axis=0)) * normals).sum(axis=1).min() > 0  # outward
    assert np.all(np.diff(faces) >= 0)
    again = sample_hull(points, 5000, rng=np.random.default_rng(7))
    assert all(np.array_equal(a, b) for a, b in zip(again, (samples, normals, faces), strict=True))


def test_sample_hull_is_uniform_by_area():
    # A box with faces of areas 0.08, 0.12 and 0.24 (twice each): samples in proportion.
    half = np.array([0.1, 0.2, 0.3])
    corners = cube_corners(1.0) * half
    n = 60000
    _, normals, _ = sample_hull(corners, n, rng=0)
    area = 4 * np.array([half[1] * half[2], half[0] * half[2], half[0] * half[1]])
    expected = area / (2 * area.sum())
    for axis in range(3):
        for sign in (1.0, -1.0):
            frac = np.mean(normals[:, axis] * sign > 0.5)
            sigma = np.sqrt(expected[axis] * (1 - expected[axis]) / n)
            assert abs(frac - expected[axis]) < 5 * sigma


def test_sample_hull_is_uniform_inside_each_face():
    # Each box face is two triangles; uniform samples fill its four quadrants equally.
    half = np.array([0.1, 0.2, 0.3])
    samples, normals, _ = sample_hull(cube_corners(1.0) * half, 60000, rng=1)
    for axis in range(3):
        u, w = [a for a in range(3) if a != axis]
        for sign in (1.0, -1.0):
            on_face = normals[:, axis] * sign > 0.5
            s = samples[on_face]
            sigma = np.sqrt(0.25 * 0.75 / len(s))
            for su in (1, -1):
                for sw in (1, -1):
                    frac = np.mean((s[:, u] * su > 0) & (s[:, w] * sw > 0))
                    assert abs(frac - 0.25) < 5 * sigma
            # And the inner half of each side holds a quarter of the face.
            inner = np.mean((np.abs(s[:, u]) < half[u] / 2) & (np.abs(s[:, w]) < half[w] / 2))
            assert abs(inner - 0.25) < 5 * sigma


@pytest.mark.parametrize(
    "points",
    [
        np.zeros((3, 3)),  # too few
        np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.2, 0]]),  # flat
        np.outer(np.linspace(0, 1, 10), [1.0, 2.0, 3.0]),  # colinear
        np.ones((10, 3)),  # one point
    ],
)
def test_sample_hull_rejects_a_hull_without_volume(points):
    with pytest.raises(ValueError, match="points"):
        sample_hull(points, 10, rng=0)


def test_sample_hull_rejects_bad_arguments():
    cube = cube_corners(0.2)
    with pytest.raises(ValueError, match="non-finite"):
        sample_hull(np.vstack([cube, [np.nan, 0, 0]]), 10)
    with pytest.raises(ValueError, match="n_samp"):
        sample_hull(cube, 0)
    with pytest.raises(ValueError, match="rng"):
        sample_hull(cube, 10, rng=0.5)


# --------------------------------------------------------------------------------------------
# View sets
# --------------------------------------------------------------------------------------------


def test_view_sets_rejects_bad_arguments():
    hull = convex_hull(cube_corners(0.2))
    samples, normals, faces = sample_on_hull(hull, 10, rng=0)
    poses = viewspace_poses(original_viewspace())
    with pytest.raises(ValueError, match="method"):
        view_sets(samples, normals, poses, method="blender")
    with pytest.raises(ValueError, match="hull"):
        view_sets(samples, normals, poses, method="raycast")
    with pytest.raises(ValueError, match="poses"):
        view_sets(samples, normals, poses[:, :3])
    with pytest.raises(ValueError, match="face_ids"):
        view_sets(samples, normals, poses, hull=hull, face_ids=faces[:5])
    with pytest.raises(ValueError, match="dilate=True"):
        view_sets(samples, normals, poses, dilate=True)
    with pytest.raises(ValueError, match="eps"):
        view_sets(samples, normals, poses, eps=-0.1, hull=hull, face_ids=faces, dilate=True)


# --------------------------------------------------------------------------------------------
# Plans
# --------------------------------------------------------------------------------------------


def _cube_surface(n: int, half: float, rng: np.random.Generator) -> np.ndarray:
    points = rng.uniform(-half, half, (n, 3))
    axis = rng.integers(0, 3, n)
    points[np.arange(n), axis] = half * rng.choice([-1.0, 1.0], n)
    return points


def test_plan_on_a_cube_is_greedy_and_deterministic():
    rng = np.random.default_rng(6)
    points = _cube_surface(3000, 0.25, rng)
    viewspace = original_viewspace()
    result = plan(points, viewspace, exclude=(0,), rng=11, settings=SetCoverSettings(n_samp=8192))
    assert len(result.views) == 9 and len(set(result.views)) == 9 and 0 not in result.views
    assert result.gains[0] > 0
    assert result.gains == sorted(result.gains, reverse=True)
    assert set(result.timings) == {"hull", "sampling", "simulation", "sets", "greedy", "total"}
    assert all(t >= 0 for t in result.timings.values())
    # The same sets computed step by step give the same plan and covered fraction.
    hull = convex_hull(points)
    samples, normals, faces = sample_on_hull(hull, 8192, rng=11)
    sets = view_sets(samples, normals, viewspace_poses(viewspace), hull=hull, face_ids=faces)
    # The covering picks are the reference greedy's: the fill's random tie-break drew nothing
    # from the sampling's generator.
    zero = result.gains.index(0)
    reference = _reference_greedy(sets, 9, [0], viewspace)
    assert result.views[:zero] == reference[0][:zero]
    assert result.gains == reference[1]
    assert result.covered_fraction == _union_size(sets, [0, *result.views]) / 8192
    # Every face of the cube is seen by some view: the plan covers the whole hull ...
    assert result.covered_fraction == 1.0
    # ... before its last picks, which then spread out over the viewspace instead of taking
    # the lowest indices: each is one of the views farthest in angle (maximin, brute force) ...
    assert zero < 9
    closed = np.zeros(len(viewspace), dtype=bool)
    closed[[0, *result.views[:zero]]] = True
    tied = 0
    for view in result.views[zero:]:
        farthest = _farthest_in_angle_all(viewspace, closed)
        assert view in farthest
        tied += len(farthest) > 1
        closed[view] = True
    assert tied > 0  # the original viewspace's rings tie
    # ... picked among the tied ones by the child the plan spawns from its generator.
    child = np.random.default_rng(11).spawn(1)[0]
    assert result.views[zero:] == spread_views(
        viewspace, np.isin(np.arange(33), [0, *result.views[:zero]]), 9 - zero, child
    )
    by_index = np.flatnonzero(~np.isin(np.arange(len(viewspace)), [0, *result.views[:zero]]))
    assert result.views[zero:] != by_index[: 9 - zero].tolist()
    again = plan(points, viewspace, exclude=(0,), rng=11, settings=SetCoverSettings(n_samp=8192))
    assert (again.views, again.gains) == (result.views, result.gains)


def test_plan_dilates_the_sets_only_when_asked():
    """By default a plan works on the visible sets, with ``dilate=True`` on the dilated ones.
    Both are valid greedy plans. The dilated sets hold the visible ones, so a first pick covers
    at least as much with them (on this cube strictly more, after two picks too); nine picks
    cover the whole cube either way."""
    points = _cube_surface(3000, 0.25, np.random.default_rng(6))
    viewspace = original_viewspace()
    poses = viewspace_poses(viewspace)
    hull = convex_hull(points)
    samples, normals, faces = sample_on_hull(hull, 8192, rng=11)
    visible = view_sets(samples, normals, poses, hull=hull, face_ids=faces)
    dilated = view_sets(samples, normals, poses, hull=hull, face_ids=faces, dilate=True)
    assert np.all(dilated >= visible) and (dilated & ~visible).sum() > 100
    for n_iter in (1, 2, 9):
        kw = dict(n_iter=n_iter, exclude=(0,), rng=11, poses=poses)
        n8192 = SetCoverSettings(n_samp=8192)
        plain = plan(points, viewspace, settings=n8192, **kw)
        explicit = plan(points, viewspace, settings=replace(n8192, dilate=False), **kw)
        assert (explicit.views, explicit.gains) == (plain.views, plain.gains)
        wide = plan(points, viewspace, settings=replace(n8192, dilate=True), **kw)
        for result, sets in ((plain, visible), (wide, dilated)):
            assert len(set(result.views)) == n_iter and 0 not in result.views
            assert result.gains[0] > 0 and result.gains == sorted(result.gains, reverse=True)
            _check_plan(result.views, result.gains, sets, [0], viewspace)
            assert result.covered_fraction == _union_size(sets, [0, *result.views]) / 8192
        if n_iter < 9:
            assert wide.covered_fraction > plain.covered_fraction
        else:
            assert wide.covered_fraction == plain.covered_fraction == 1.0
    sph = plan(
        sph_hull_points(points, 3), viewspace, exclude=(0,), rng=0,
        settings=SetCoverSettings(n_samp=4096, dilate=True),
    )  # fmt: skip
    assert len(set(sph.views)) == 9 and 0 not in sph.views


def test_plan_accepts_precomputed_poses_and_rejects_bad_input():
    points = _cube_surface(500, 0.25, np.random.default_rng(7))
    viewspace = original_viewspace()
    poses = viewspace_poses(viewspace)
    n2048 = SetCoverSettings(n_samp=2048)
    a = plan(points, viewspace, n_iter=3, rng=0, settings=n2048)
    b = plan(points, viewspace, n_iter=3, rng=0, settings=n2048, poses=poses)
    assert (a.views, a.gains) == (b.views, b.gains)
    with pytest.raises(ValueError, match="no volume"):
        plan(points * [1.0, 0.0, 1.0], viewspace)
    with pytest.raises(ValueError, match="simulation"):
        plan(points, viewspace, settings=SetCoverSettings(simulation="blender"))
    with pytest.raises(ValueError, match="viewspace"):
        plan(points, viewspace[:, :2])
    with pytest.raises(ValueError, match="poses"):
        plan(points, viewspace, poses=poses[:5])


def test_plan_raycast_runs_on_a_small_camera():
    points = _cube_surface(500, 0.25, np.random.default_rng(8))
    # 160 x 120 with the same field of view; pixels 4x farther apart, so a larger eps.
    small = Intrinsics.centred(160, 120, 119.0)
    result = plan(
        points,
        original_viewspace(),
        exclude=(0,),
        settings=SetCoverSettings(n_samp=2048, simulation="raycast"),
        intrinsics=small,
        eps=0.03,
    )
    assert len(set(result.views)) == 9 and 0 not in result.views
    assert result.gains[0] > 0 and result.gains == sorted(result.gains, reverse=True)


def test_the_signature_hull_sits_at_the_centroid_and_plans():
    centre = np.array([0.05, -0.03, 0.02])
    points = 0.35 * fibonacci_sphere(2000) + centre
    signature = sph_hull_points(points, lmax=3)
    assert signature.shape == (64, 3)
    # A sphere's radius function is a constant: the signature lies on the same sphere.
    np.testing.assert_allclose(np.linalg.norm(signature - centre, axis=1), 0.35, atol=1e-6)
    # 64 points on the sphere: their hull holds most of the cloud's hull.
    ratio = ConvexHull(signature).volume / ConvexHull(points).volume
    assert 0.8 < ratio < 1.0
    result = plan(
        signature, original_viewspace(), exclude=(0,), rng=0, settings=SetCoverSettings(n_samp=4096)
    )
    assert len(set(result.views)) == 9 and 0 not in result.views
    assert result.gains == sorted(result.gains, reverse=True) and result.gains[0] > 0
    assert result.timings["total"] == pytest.approx(
        sum(result.timings[k] for k in ("hull", "sampling", "simulation", "sets", "greedy"))
    )


@pytest.mark.slow
def test_raycast_planning_agrees_with_the_analytic_path():
    # The two view simulations of the planner on the same hull samples, at the dataset's camera:
    # their view sets agree on most samples, and the analytic plan covers, as the ray caster
    # sees it, nearly what the ray-cast plan covers. (A cut face through the camera rings would
    # be seen edge-on, where the two differ by definition: the cut is tilted.)
    rng = np.random.default_rng(0)
    box = (rng.random((3000, 3)) - 0.5) * [0.8, 0.5, 0.3]
    ball = rng.normal(size=(3000, 3))
    ball = 0.4 * ball / np.linalg.norm(ball, axis=1, keepdims=True)
    positions = original_viewspace()
    poses = viewspace_poses(positions)
    for cloud in (box, ball):
        part = cloud[cloud @ np.array([0.3, 0.2, 0.93]) > 0.02]
        hull = convex_hull(part)
        samples, normals, faces = sample_on_hull(hull, 4096, 0)
        sets = {
            m: view_sets(samples, normals, poses, Intrinsics(), m, DEFAULT_EPS, hull, faces, d)
            for m, d in (("analytic", True), ("raycast", False))
        }
        agreement = (sets["analytic"] == sets["raycast"]).mean(axis=1)
        assert np.median(agreement) >= 0.98 and agreement.min() >= 0.85
        covered = {}
        for m in sets:
            views, _ = greedy_max_coverage(sets[m], 4, exclude=[0], positions=positions)
            covered[m] = sets["raycast"][[0, *views]].any(axis=0).mean()
        assert covered["analytic"] >= covered["raycast"] - 0.02


def _one_view_of_a_ball() -> np.ndarray:
    """The cap of a ball of radius 0.4 that a camera at +z sees (a tenth of its surface)."""
    ball = fibonacci_sphere(4000) * 0.4
    return ball[ball[:, 2] > 0.32]


def test_the_planning_signature_stays_within_the_cloud_that_fitted_it():
    cap = _one_view_of_a_ball()
    raw, centroid = signature_with_centroid(cap, 3)
    extent = np.linalg.norm(cap - centroid, axis=1).max()
    radius = np.linalg.norm(raw, axis=1)
    assert radius.max() > 3 * extent  # a fit to one view extrapolates far past it
    bounded = sph_hull_points(cap, 3)
    assert np.linalg.norm(bounded - centroid, axis=1).max() <= extent + 1e-9
    # Positive radii below the bound are kept: the same point, direction and length.
    directions = unit_vectors(*equiangular_directions(3))
    kept = (np.einsum("ij,ij->i", raw, directions) > 0) & (radius < extent)
    assert kept.sum() >= 8
    np.testing.assert_allclose(bounded[kept] - centroid, raw[kept], atol=1e-5)
    assert not cameras_inside(convex_hull(bounded), original_viewspace()).any()


def test_cameras_inside_a_hull_are_found_and_noted():
    viewspace = original_viewspace()  # radius 1
    big, small = convex_hull(cube_corners(1.5)), convex_hull(cube_corners(0.3))
    assert cameras_inside(big, viewspace).all() and not cameras_inside(small, viewspace).any()
    offset = convex_hull(cube_corners(0.3) + viewspace[0])  # around camera 0 only
    np.testing.assert_array_equal(np.flatnonzero(cameras_inside(offset, viewspace)), [0])
    policy = SetCoverPolicy(np.random.default_rng(0), SetCoverSettings(n_samp=500))
    policy.plan_from(cube_corners(0.3) + viewspace[0], viewspace_poses(viewspace), [5], 3)
    assert policy.notes == [
        "1 cameras inside the planning hull (views [0]): the analytic visibility assumes cameras "
        "outside it"
    ]
