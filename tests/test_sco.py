"""Convex-hull set cover: greedy against brute force, visibility on shapes with known answers,
the analytic path against ray casting, and whole plans."""

from itertools import combinations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from nbv import sco
from nbv.camera import Intrinsics, project, viewspace_poses
from nbv.scores import DEFAULT_EPS
from nbv.viewspace import original_viewspace

K = Intrinsics()


def _fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit vectors (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5.0**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _cube_corners(half: float) -> np.ndarray:
    return np.array(
        [[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    )


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


def _union_size(sets: np.ndarray, views) -> int:
    return int(sets[list(views)].any(axis=0).sum()) if len(views) else 0


def _brute_force_visibility(samples, normals, poses, intrinsics, margin=0.0) -> np.ndarray:
    """Per view with nbv.camera.project: facing the camera and inside the image; with a margin,
    within ``margin`` (world units) of each plane through the camera centre and an image
    border."""
    k = intrinsics
    seen = np.zeros((len(poses), len(samples)), dtype=bool)
    for v, pose in enumerate(poses):
        uv, z = project(samples, k, pose)
        if margin == 0.0:
            inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= k.width - 1)
            inside &= (uv[:, 1] >= 0) & (uv[:, 1] <= k.height - 1)
        else:
            # Distance to the plane through the centre and the border u = b (camera frame):
            # (fx x - (b - cx) z) / |(fx, b - cx)|, with x = (u - cx) z / fx.
            inside = z > 0
            for coord, f, c, last in (
                (uv[:, 0], k.fx, k.cx, k.width - 1),
                (uv[:, 1], k.fy, k.cy, k.height - 1),
            ):
                lateral = (coord - c) * z / f
                for border, sign in ((0.0, 1.0), (last, -1.0)):
                    signed = sign * (f * lateral - (border - c) * z) / np.hypot(f, border - c)
                    inside &= signed >= -margin
        facing = ((pose[:3, 3] - samples) * normals).sum(axis=1) > 1e-9
        seen[v] = inside & facing
    return seen


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
            views, gains = sco.greedy_max_coverage(sets, k)
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
    assert sco.greedy_max_coverage(sets, 3) == ([0, 2, 3], [6, 4, 1])
    assert sco.greedy_max_coverage(sets, 4) == ([0, 2, 3, 1], [6, 4, 1, 0])


def test_greedy_is_not_optimal_where_it_need_not_be():
    # The classic trap: the largest set first leaves only one new element for either half.
    sets = np.zeros((3, 6), dtype=bool)
    sets[0, 1:5] = True
    sets[1, 0:3] = True
    sets[2, 3:6] = True
    assert sco.greedy_max_coverage(sets, 2) == ([0, 1], [4, 1])  # 5 of the optimal 6


def test_greedy_gains_are_marginal_and_match_reference():
    rng = np.random.default_rng(1)
    for n in (1, 63, 64, 65, 1000):
        sets = rng.random((12, n)) < 0.3
        for exclude in ((), (3,), (0, 5, 5)):
            views, gains = sco.greedy_max_coverage(sets, 6, exclude)
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
            assert sco.greedy_max_coverage(sets, 9, exclude) == _reference_greedy(sets, 9, exclude)


def test_greedy_ties_go_to_the_lowest_index():
    sets = np.ones((4, 10), dtype=bool)
    assert sco.greedy_max_coverage(sets, 3) == ([0, 1, 2], [10, 0, 0])
    assert sco.greedy_max_coverage(sets, 3, exclude=[1]) == ([0, 2, 3], [0, 0, 0])


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
    assert sco.greedy_max_coverage(sets, 4, exclude=(0,)) == ([1, 2, 3, 4], [1, 0, 0, 0])
    # Spread: 1; then 180 (170 degrees from {0, 10}); then 270 (90) before 90 (80); then 90.
    spread = sco.greedy_max_coverage(sets, 4, exclude=(0,), positions=positions)
    assert spread == ([1, 4, 5, 3], [1, 0, 0, 0])
    assert spread[0] == _reference_greedy(sets, 4, [0], positions)[0]
    # Only the directions count, not the distances.
    scaled = positions * np.array([1.0, 3.0, 0.5, 2.0, 1.0, 7.0, 1.0])[:, None]
    assert sco.greedy_max_coverage(sets, 4, exclude=(0,), positions=scaled) == spread
    # Ties go to the lowest index: 90 and 270 are both 90 degrees from {0, 180}.
    nothing = np.zeros((7, 5), dtype=bool)
    assert sco.greedy_max_coverage(nothing, 4, exclude=(0,), positions=positions) == (
        [4, 3, 5, 6],
        [0, 0, 0, 0],
    )
    # Nothing visited and nothing to cover: the first pick is view 0, then its opposite.
    assert sco.greedy_max_coverage(nothing, 2, positions=positions)[0] == [0, 4]


def test_greedy_rejects_bad_positions():
    sets = np.ones((3, 5), dtype=bool)
    with pytest.raises(ValueError, match="positions"):
        sco.greedy_max_coverage(sets, 2, positions=np.ones((2, 3)))
    with pytest.raises(ValueError, match="positions"):
        sco.greedy_max_coverage(sets, 2, positions=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="positions"):
        sco.greedy_max_coverage(sets, 2, positions=np.full((3, 3), np.nan))


def test_greedy_spread_matches_reference_on_random_viewspaces():
    rng = np.random.default_rng(14)
    for _ in range(20):
        positions = rng.normal(size=(15, 3))
        sets = rng.random((15, 12)) < 0.2
        exclude = tuple(int(v) for v in rng.choice(15, int(rng.integers(0, 3)), replace=False))
        expected = _reference_greedy(sets, 10, exclude, positions)
        assert sco.greedy_max_coverage(sets, 10, exclude, positions) == expected
        assert expected[1][-3:] == [0, 0, 0]  # the fill was exercised


def test_greedy_exclude_removes_the_visited_views_elements():
    sets = np.zeros((3, 7), dtype=bool)
    sets[0, 0:6] = True
    sets[1, 0:5] = True
    sets[2, 6] = True
    assert sco.greedy_max_coverage(sets, 2) == ([0, 2], [6, 1])
    # View 0 visited: view 1 has nothing new, so the single new element of view 2 wins.
    assert sco.greedy_max_coverage(sets, 2, exclude=(0,)) == ([2, 1], [1, 0])


def test_greedy_rejects_bad_input():
    sets = np.ones((3, 5), dtype=bool)
    with pytest.raises(ValueError, match="n_iter=3 exceeds"):
        sco.greedy_max_coverage(sets, 3, exclude=(0,))
    with pytest.raises(ValueError, match="outside"):
        sco.greedy_max_coverage(sets, 1, exclude=(3,))
    with pytest.raises(ValueError, match="boolean matrix"):
        sco.greedy_max_coverage(np.ones(5, dtype=bool), 1)
    with pytest.raises(ValueError, match="booleans"):
        sco.greedy_max_coverage(np.full((3, 5), 0.5), 1)
    with pytest.raises(ValueError, match="n_iter"):
        sco.greedy_max_coverage(sets, -1)


def test_pack_and_popcount():
    rng = np.random.default_rng(2)
    sets = rng.random((5, 130)) < 0.5
    rows = sco.pack_sets(sets)
    assert rows.dtype == np.uint64 and rows.shape == (5, 3)
    bits = np.unpackbits(rows.view(np.uint8), axis=1, bitorder="little")
    assert np.array_equal(bits[:, :130].astype(bool), sets)
    assert not bits[:, 130:].any()
    assert np.array_equal(sco.popcount_rows(rows), sets.sum(axis=1))
    words = rng.integers(0, 2**63, size=(4, 7), dtype=np.uint64) * np.uint64(2) + np.uint64(1)
    expected = [[bin(int(w)).count("1") for w in row] for row in words]
    assert np.array_equal(sco.popcount_rows(words), np.sum(expected, axis=1))


# --------------------------------------------------------------------------------------------
# Hull samples
# --------------------------------------------------------------------------------------------


def test_sample_hull_lies_on_the_hull_with_outward_normals():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(200, 3)) * [0.3, 0.2, 0.1] + [0.1, 0.0, -0.05]
    samples, normals, faces = sco.sample_hull(points, 5000, rng=7)
    hull = ConvexHull(points)
    assert samples.shape == normals.shape == (5000, 3) and faces.shape == (5000,)
    plane = hull.equations[faces]
    assert np.abs((samples * plane[:, :3]).sum(axis=1) + plane[:, 3]).max() < 1e-12
    assert (samples @ hull.equations[:, :3].T + hull.equations[:, 3]).max() < 1e-12
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    assert ((samples - points.mean(axis=0)) * normals).sum(axis=1).min() > 0  # outward
    assert np.all(np.diff(faces) >= 0)
    again = sco.sample_hull(points, 5000, rng=np.random.default_rng(7))
    assert all(np.array_equal(a, b) for a, b in zip(again, (samples, normals, faces), strict=True))


def test_sample_hull_is_uniform_by_area():
    # A box with faces of areas 0.08, 0.12 and 0.24 (twice each): samples in proportion.
    half = np.array([0.1, 0.2, 0.3])
    corners = _cube_corners(1.0) * half
    n = 60000
    _, normals, _ = sco.sample_hull(corners, n, rng=0)
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
    samples, normals, _ = sco.sample_hull(_cube_corners(1.0) * half, 60000, rng=1)
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
        sco.sample_hull(points, 10, rng=0)


def test_sample_hull_rejects_bad_arguments():
    cube = _cube_corners(0.2)
    with pytest.raises(ValueError, match="non-finite"):
        sco.sample_hull(np.vstack([cube, [np.nan, 0, 0]]), 10)
    with pytest.raises(ValueError, match="n_samp"):
        sco.sample_hull(cube, 0)
    with pytest.raises(ValueError, match="rng"):
        sco.sample_hull(cube, 10, rng=0.5)


# --------------------------------------------------------------------------------------------
# Analytic visibility
# --------------------------------------------------------------------------------------------


def _both_analytic(hull, samples, normals, faces, poses, intrinsics=K, margin=0.0):
    """The visible sets by sample and by triangle, which must agree."""
    per_sample = sco.analytic_visibility(samples, normals, poses, intrinsics, margin)
    per_face = sco.analytic_visibility_faces(hull, samples, faces, poses, intrinsics, margin)
    assert np.array_equal(per_sample, per_face)
    if margin == 0.0:
        assert np.array_equal(per_sample, sco.view_sets(samples, normals, poses, intrinsics))
        exact = sco.view_sets(
            samples, normals, poses, intrinsics, hull=hull, face_ids=faces, dilate=False
        )
        assert np.array_equal(per_sample, exact)
    return per_sample


def test_analytic_cube_sees_exactly_the_faces_turned_to_the_camera():
    hull = sco.convex_hull(_cube_corners(0.2))
    samples, normals, faces = sco.sample_on_hull(hull, 3000, rng=0)
    top = np.array([0.0, 0.0, 1.0])
    corner = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)
    seen = _both_analytic(hull, samples, normals, faces, viewspace_poses(np.stack([top, corner])))
    # Whole cube in view from distance 1: the +z face only, and the three faces of the corner.
    assert np.array_equal(seen[0], normals[:, 2] > 0.5)
    assert np.array_equal(seen[1], normals @ corner > 0.5)


@pytest.mark.parametrize(
    "intrinsics", [K, Intrinsics(20, 16, 20.0, 25.0, 7.0, 9.0)], ids=["default", "tiny"]
)
def test_analytic_clips_to_the_image(intrinsics):
    # 0.1 in front of the +z face; camera x is world x and camera y is world -y, so pixel
    # centres 0 .. W - 1 cover (-cx / fx .. (W - 1 - cx) / fx) * 0.1 in x, and so on.
    k = intrinsics
    hull = sco.convex_hull(_cube_corners(0.2))
    samples, normals, faces = sco.sample_on_hull(hull, 20000, rng=1)
    poses = viewspace_poses(np.array([[0, 0, 0.3]]))
    seen = _both_analytic(hull, samples, normals, faces, poses, k)
    x, y = samples[:, 0] / 0.1, -samples[:, 1] / 0.1
    expected = (normals[:, 2] > 0.5) & (-k.cx / k.fx <= x) & (x <= (k.width - 1 - k.cx) / k.fx)
    expected &= (-k.cy / k.fy <= y) & (y <= (k.height - 1 - k.cy) / k.fy)
    assert expected.sum() > 100
    assert np.array_equal(seen[0], expected)


@pytest.mark.parametrize("distance", [1.0, 2.0])
def test_analytic_sphere_shows_a_cap_of_known_area(distance):
    # A camera at distance d sees the fraction (1 - r / d) / 2 of a sphere of radius r.
    radius = 0.3
    hull = sco.convex_hull(radius * _fibonacci_sphere(2000))
    samples, normals, faces = sco.sample_on_hull(hull, 16384, rng=2)
    poses = viewspace_poses(distance * original_viewspace())
    seen = _both_analytic(hull, samples, normals, faces, poses)
    expected = (1.0 - radius / distance) / 2.0
    fractions = seen.mean(axis=1)
    assert abs(fractions.mean() - expected) < 0.005
    assert np.abs(fractions - expected).max() < 0.02


def test_analytic_paths_agree_with_projection_brute_force():
    # Larger than the vertical field of view: many triangles are cut by the image border.
    rng = np.random.default_rng(4)
    points = _fibonacci_sphere(400) * [0.5, 0.45, 0.48] + [0.02, -0.03, 0.01]
    hull = sco.convex_hull(points)
    samples, normals, faces = sco.sample_on_hull(hull, 8000, rng=3)
    poses = viewspace_poses(original_viewspace())
    expected = _brute_force_visibility(samples, normals, poses, K)
    assert 0 < expected.mean() < 0.5
    assert np.array_equal(_both_analytic(hull, samples, normals, faces, poses), expected)
    # Samples in any order: the per-triangle path does not need them grouped.
    perm = rng.permutation(len(samples))
    shuffled = sco.analytic_visibility_faces(hull, samples[perm], faces[perm], poses, K)
    assert np.array_equal(shuffled, expected[:, perm])
    # A smaller, off-centre image.
    small = Intrinsics(200, 100, 150.0, 160.0, 80.0, 60.0)
    expected_small = _brute_force_visibility(samples, normals, poses, small)
    assert np.array_equal(
        _both_analytic(hull, samples, normals, faces, poses, small), expected_small
    )


def test_analytic_margin_widens_the_image_by_a_distance():
    points = _fibonacci_sphere(400) * [0.5, 0.45, 0.48] + [0.02, -0.03, 0.01]
    hull = sco.convex_hull(points)
    samples, normals, faces = sco.sample_on_hull(hull, 8000, rng=3)
    poses = viewspace_poses(original_viewspace())
    for intrinsics in (K, Intrinsics(200, 100, 150.0, 160.0, 80.0, 60.0)):
        exact = _both_analytic(hull, samples, normals, faces, poses, intrinsics)
        wide = _both_analytic(hull, samples, normals, faces, poses, intrinsics, margin=0.03)
        expected = _brute_force_visibility(samples, normals, poses, intrinsics, margin=0.03)
        assert np.array_equal(wide, expected)
        assert np.all(wide >= exact) and (wide & ~exact).sum() > 100
    with pytest.raises(ValueError, match="margin"):
        sco.analytic_visibility(samples, normals, poses, K, margin=-1.0)


def _expected_near_pairs(hull, samples, faces, eps) -> set[tuple[int, int]]:
    tri = hull.points[hull.simplices]
    dist = _point_triangle_distance(samples, tri)  # (n, F)
    dist[np.arange(len(samples)), faces] = np.inf
    return {(int(i), int(t)) for i, t in zip(*np.nonzero(dist <= eps), strict=True)}


def _near_pairs(near: sco.NearTriangles, faces) -> set[tuple[int, int]]:
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
def test_near_triangles_match_brute_force_distances(shape):
    rng = np.random.default_rng(12)
    if shape == "blob":
        points = rng.normal(size=(60, 3)) * [0.3, 0.2, 0.25]
    elif shape == "fine":  # triangles smaller than eps
        points = 0.3 * _fibonacci_sphere(300)
    elif shape == "cap":  # small triangles on the dome, large ones across the base
        dome = _fibonacci_sphere(600)
        points = 0.3 * dome[dome[:, 2] > 0.0]
    elif shape == "slab":
        # Thinner than eps: every sample is within eps of the opposite face.
        points = rng.uniform(-1.0, 1.0, (40, 3)) * [0.3, 0.2, 0.0] + [0.0, 0.0, 0.004]
        points = np.vstack([points, points * [1.0, 1.0, -1.0]])
    else:
        points = _cube_corners(0.2)  # two triangles per face: the diagonals pair them
    hull = sco.convex_hull(points)
    samples, _, faces = sco.sample_on_hull(hull, 3000, rng=5)
    eps = 0.03
    expected = _expected_near_pairs(hull, samples, faces, eps)
    near = sco.near_triangles(hull, samples, faces, eps)
    assert _near_pairs(near, faces) == expected and len(expected) > 100
    assert near.eps == eps
    # Samples in any order.
    perm = rng.permutation(len(samples))
    shuffled = sco.near_triangles(hull, samples[perm], faces[perm], eps)
    assert {(int(perm[i]), t) for i, t in _near_pairs(shuffled, faces[perm])} == expected


def _small_raycast_setup(points, n_samp=3000):
    hull = sco.convex_hull(points)
    samples, normals, faces = sco.sample_on_hull(hull, n_samp, rng=6)
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
        points = 0.62 * _fibonacci_sphere(600)
    elif shape == "box":
        points = rng.uniform(-1.0, 1.0, (200, 3)) * [0.35, 0.2, 0.3]
    else:
        points = rng.uniform(-1.0, 1.0, (60, 3)) * [0.4, 0.3, 0.0] + [0.0, 0.0, 0.01]
        points = np.vstack([points, points * [1.0, 1.0, -1.0]])
    hull, samples, normals, faces = _small_raycast_setup(points)
    poses = viewspace_poses(original_viewspace())
    visible = sco.view_sets(samples, normals, poses, SMALL, hull=hull, face_ids=faces, dilate=False)
    dilated = sco.view_sets(samples, normals, poses, SMALL, eps=eps, hull=hull, face_ids=faces)
    raycast = sco.view_sets(samples, normals, poses, SMALL, "raycast", eps, hull)
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
    near = sco.near_triangles(hull, samples, faces, eps)
    again = sco.dilate_view_sets(visible, samples, faces, hull, near, poses, SMALL)
    assert np.array_equal(again, dilated)


def test_dilation_behind_an_edge_needs_a_pixel():
    """Just behind a silhouette edge, all within eps of the facing side, which is seen so
    obliquely that its pixels' points lie farther apart than eps: a sample is captured only
    where a pixel's point comes that close, as in the rendered view."""
    hull, samples, normals, faces = _small_raycast_setup(_cube_corners(0.2), 20000)
    # Just above the top face: it is seen at about 5 degrees, its far edge is a silhouette.
    poses = viewspace_poses(np.array([[1.0, 0.0, 0.28]]))
    visible = sco.view_sets(samples, normals, poses, hull=hull, face_ids=faces, dilate=False)
    dilated = sco.view_sets(samples, normals, poses, hull=hull, face_ids=faces)
    raycast = sco.view_sets(samples, normals, poses, method="raycast", hull=hull)
    behind = (normals[:, 0] < -0.5) & (samples[:, 2] > 0.2 - DEFAULT_EPS)  # on -x, by the edge
    assert not visible[0, behind].any()
    assert 0 < dilated[0, behind].sum() < behind.sum()
    assert np.array_equal(dilated[0, behind], raycast[0, behind])


def test_view_sets_rejects_bad_arguments():
    hull = sco.convex_hull(_cube_corners(0.2))
    samples, normals, faces = sco.sample_on_hull(hull, 10, rng=0)
    poses = viewspace_poses(original_viewspace())
    with pytest.raises(ValueError, match="method"):
        sco.view_sets(samples, normals, poses, method="blender")
    with pytest.raises(ValueError, match="hull"):
        sco.view_sets(samples, normals, poses, method="raycast")
    with pytest.raises(ValueError, match="poses"):
        sco.view_sets(samples, normals, poses[:, :3])
    with pytest.raises(ValueError, match="face_ids"):
        sco.view_sets(samples, normals, poses, hull=hull, face_ids=faces[:5])
    with pytest.raises(ValueError, match="dilate=True"):
        sco.view_sets(samples, normals, poses, dilate=True)
    with pytest.raises(ValueError, match="eps"):
        sco.view_sets(samples, normals, poses, eps=-0.1, hull=hull, face_ids=faces)


# --------------------------------------------------------------------------------------------
# Analytic against ray casting
# --------------------------------------------------------------------------------------------


def _single_view_hull_points(view: int) -> np.ndarray:
    """What one full-resolution view of a synthetic chair sees, as the dataset renders it."""
    from nbv import meshes, synthetic
    from nbv.camera import backproject
    from nbv.render import render_raycast

    entry = next(e for e in synthetic.catalogue() if e.category == "chair")
    mesh, _, _ = meshes.normalise(meshes.Mesh(*synthetic.build(entry, 0)))
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
        points = 0.45 * _fibonacci_sphere(1000)
    elif name == "box":
        points = rng.uniform(-1.0, 1.0, (200, 3)) * [0.35, 0.2, 0.3]
    else:
        points = _single_view_hull_points(int(name.split()[-1]))
    hull = sco.convex_hull(points)
    samples, normals, faces = sco.sample_on_hull(hull, 4096, rng=4)
    poses = viewspace_poses(original_viewspace())
    visible = sco.view_sets(samples, normals, poses, hull=hull, face_ids=faces, dilate=False)
    analytic = sco.view_sets(samples, normals, poses, hull=hull, face_ids=faces)
    raycast = sco.view_sets(samples, normals, poses, method="raycast", hull=hull)
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
    result = sco.plan(points, viewspace, exclude=(0,), n_samp=8192, rng=11)
    assert len(result.views) == 9 and len(set(result.views)) == 9 and 0 not in result.views
    assert result.gains[0] > 0
    assert result.gains == sorted(result.gains, reverse=True)
    assert set(result.timings) == {"hull", "sampling", "simulation", "sets", "greedy", "total"}
    assert all(t >= 0 for t in result.timings.values())
    # The same sets computed step by step give the same plan and covered fraction.
    hull = sco.convex_hull(points)
    samples, normals, faces = sco.sample_on_hull(hull, 8192, rng=11)
    sets = sco.view_sets(samples, normals, viewspace_poses(viewspace), hull=hull, face_ids=faces)
    assert (result.views, result.gains) == _reference_greedy(sets, 9, [0], viewspace)
    assert result.covered_fraction == _union_size(sets, [0, *result.views]) / 8192
    # Every face of the cube is seen by some view: the plan covers the whole hull ...
    assert result.covered_fraction == 1.0
    # ... before its last picks, which then spread out over the viewspace instead of taking
    # the lowest indices.
    zero = result.gains.index(0)
    assert zero < 9
    closed = np.zeros(len(viewspace), dtype=bool)
    closed[[0, *result.views[:zero]]] = True
    for view in result.views[zero:]:
        assert view == _farthest_in_angle(viewspace, closed)
        closed[view] = True
    by_index = np.flatnonzero(~np.isin(np.arange(len(viewspace)), [0, *result.views[:zero]]))
    assert result.views[zero:] != by_index[: 9 - zero].tolist()
    again = sco.plan(points, viewspace, exclude=(0,), n_samp=8192, rng=11)
    assert (again.views, again.gains) == (result.views, result.gains)


def test_plan_accepts_precomputed_poses_and_rejects_bad_input():
    points = _cube_surface(500, 0.25, np.random.default_rng(7))
    viewspace = original_viewspace()
    poses = viewspace_poses(viewspace)
    a = sco.plan(points, viewspace, n_iter=3, n_samp=2048, rng=0)
    b = sco.plan(points, viewspace, n_iter=3, n_samp=2048, rng=0, poses=poses)
    assert (a.views, a.gains) == (b.views, b.gains)
    with pytest.raises(ValueError, match="no volume"):
        sco.plan(points * [1.0, 0.0, 1.0], viewspace)
    with pytest.raises(ValueError, match="method"):
        sco.plan(points, viewspace, method="blender")
    with pytest.raises(ValueError, match="viewspace"):
        sco.plan(points, viewspace[:, :2])
    with pytest.raises(ValueError, match="poses"):
        sco.plan(points, viewspace, poses=poses[:5])


def test_plan_raycast_runs_on_a_small_camera():
    points = _cube_surface(500, 0.25, np.random.default_rng(8))
    # 160 x 120 with the same field of view; pixels 4x farther apart, so a larger eps.
    small = Intrinsics.centred(160, 120, 119.0)
    result = sco.plan(
        points,
        original_viewspace(),
        exclude=(0,),
        n_samp=2048,
        method="raycast",
        intrinsics=small,
        eps=0.03,
    )
    assert len(set(result.views)) == 9 and 0 not in result.views
    assert result.gains[0] > 0 and result.gains == sorted(result.gains, reverse=True)


def test_plan_sph_uses_the_signature_hull_at_the_centroid():
    centre = np.array([0.05, -0.03, 0.02])
    points = 0.35 * _fibonacci_sphere(2000) + centre
    signature = sco.sph_hull_points(points, lmax=3)
    assert signature.shape == (64, 3)
    # A sphere's radius function is a constant: the signature lies on the same sphere.
    np.testing.assert_allclose(np.linalg.norm(signature - centre, axis=1), 0.35, atol=1e-6)
    # 64 points on the sphere: their hull holds most of the cloud's hull.
    ratio = ConvexHull(signature).volume / ConvexHull(points).volume
    assert 0.8 < ratio < 1.0
    result = sco.plan_sph(points, original_viewspace(), exclude=(0,), n_samp=4096, rng=0)
    assert len(set(result.views)) == 9 and 0 not in result.views
    assert result.gains == sorted(result.gains, reverse=True) and result.gains[0] > 0
    assert "signature" in result.timings
    assert result.timings["total"] >= result.timings["signature"]
