import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from nbv.geometry.hull import hull_vertices, hull_volume
from nbv.geometry.scores import (
    DEFAULT_EPS,
    coverage,
    coverage_bits,
    coverage_from_bits,
    coverage_gains,
    covered_mask,
    squared_distances,
    view_hull_vertices,
    vig,
    vig_gains,
    vig_of_state,
)
from nbv.geometry.union import UnionHulls

CUBE = np.array(list(itertools.product([0.0, 1.0], repeat=3)))
ROOT = Path(__file__).resolve().parents[1]
#: The eps of datasets made before issue 29: 2-28 ground-truth points a model differ from PC-NBV's.
LEGACY_EPS = 0.00707


def _brute_sq(partial: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Reference: ``(N, M)`` float64 squared distances of every pair, summed x, y, z in order."""
    d = np.asarray(partial, np.float64)[None, :, :] - np.asarray(gt, np.float64)[:, None, :]
    return (d[..., 0] ** 2 + d[..., 1] ** 2) + d[..., 2] ** 2


def _brute_covered(partial: np.ndarray, gt: np.ndarray, eps: float) -> np.ndarray:
    """Reference: PC-NBV's test on every pair, squared distance < eps**2 in float64."""
    if len(partial) == 0:
        return np.zeros(len(gt), dtype=bool)
    return (_brute_sq(partial, gt) < eps * eps).any(axis=1)


def _random_views(rng: np.random.Generator, n_views: int, n_gt: int, eps: float):
    """A ground truth on a unit sphere and view clouds: noisy copies of random caps of it."""
    gt = rng.normal(size=(n_gt, 3))
    gt /= np.linalg.norm(gt, axis=1, keepdims=True)
    views = []
    for _ in range(n_views):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        seen = gt[gt @ axis > rng.uniform(0.0, 0.8)]
        noise = rng.uniform(0.0, 2.0 * eps, size=(len(seen), 1)) * rng.normal(size=(len(seen), 3))
        views.append(seen + noise / np.sqrt(3.0))
    return gt, views


def assert_gains_are_differences(gains, state, score_of, base, abs_tol):
    """Gains are 0 for visited views and score(state + v) - score(state) for the others."""
    for v in range(len(state)):
        if state[v]:
            assert gains[v] == 0.0
        else:
            grown = state.copy()
            grown[v] = True
            assert gains[v] == pytest.approx(score_of(grown) - base, abs=abs_tol)


def test_default_eps_is_pcnbv():
    assert DEFAULT_EPS == math.sqrt(5e-5) == 0.007071067811865475
    # In float64 the square is PC-NBV's threshold exactly, so ``< eps**2`` is its test bit for bit.
    assert DEFAULT_EPS * DEFAULT_EPS == 5e-5 and DEFAULT_EPS**2 == 5e-5
    protocol = yaml.safe_load((ROOT / "conf/protocol/default.yaml").read_text())
    assert protocol["eps"] == DEFAULT_EPS


#: ``P - G`` is an offset whose float64 squared norm is exactly 5e-5 (found by a seeded search;
#: the test checks it), away from the axes.
G = np.array([0.25, -0.125, 0.375])
P = np.array([0.2499506523450238, -0.12884030363707322, 0.369062859881725])


def _at_squared_distance(gt: np.ndarray, sq: float, rng: np.random.Generator) -> np.ndarray:
    """One point per ground-truth point, in a random direction, at squared distance ``sq``."""
    u = rng.normal(size=gt.shape)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return gt + math.sqrt(sq) * u


def test_pcnbv_boundary_below_at_and_above_5e_5():
    rng = np.random.default_rng(10)
    gt = rng.uniform(-0.5, 0.5, size=(200, 3))
    below = _at_squared_distance(gt, 5e-5 - 1e-12, rng)
    above = _at_squared_distance(gt, 5e-5 + 1e-12, rng)
    # The premises, in the test's own arithmetic: 1e-12 is far above float64's rounding here.
    sq_below = np.diag(_brute_sq(below, gt))
    sq_above = np.diag(_brute_sq(above, gt))
    assert np.all(np.abs(sq_below - (5e-5 - 1e-12)) < 1e-17)
    assert np.all(np.abs(sq_above - (5e-5 + 1e-12)) < 1e-17)
    # Each point's nearest ground-truth point is its own (else the test would test nothing).
    assert np.array_equal(_brute_sq(below, gt).argmin(axis=0), np.arange(len(gt)))
    assert covered_mask(below, gt).all() and coverage(below, gt) == 1.0
    assert not covered_mask(above, gt).any() and coverage(above, gt) == 0.0
    # The old eps (0.00707 < sqrt(5e-5 - 1e-12) = 0.0070710677) misses the points just below.
    assert not covered_mask(below, gt, LEGACY_EPS).any()
    # Exactly 5e-5 is not covered (strict): on an axis from the origin and off the axes.
    on_axis = np.array([[DEFAULT_EPS, 0.0, 0.0]])
    assert _brute_sq(on_axis, np.zeros((1, 3)))[0, 0] == 5e-5
    assert _brute_sq(P[None], G[None])[0, 0] == 5e-5
    assert squared_distances(P[None], G[None])[0] == 5e-5
    assert not covered_mask(on_axis, np.zeros((1, 3))).any()
    assert not covered_mask(P[None], G[None]).any()
    # One float64 step closer along each coordinate's offset is covered.
    closer = np.nextafter(P, G)
    assert _brute_sq(closer[None], G[None])[0, 0] < 5e-5
    assert covered_mask(closer[None], G[None]).all()


def test_agrees_with_brute_force_on_ties_within_a_few_ulps():
    """Partial points at squared distances within a few float64 steps of eps**2, several per
    ground-truth point: where a KD-tree's own rounding could decide, the float64 test must."""
    rng = np.random.default_rng(11)
    gt = rng.uniform(-0.5, 0.5, size=(300, 3))
    parts = []
    for _ in range(4):
        scale = 1.0 + rng.integers(-6, 7, size=(len(gt), 1)) * 2.0**-52
        u = rng.normal(size=gt.shape)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        parts.append(gt + DEFAULT_EPS * scale * u)
    partial = np.concatenate(parts)
    ref = _brute_covered(partial, gt, DEFAULT_EPS)
    sq_min = _brute_sq(partial, gt).min(axis=1)
    assert np.all(np.abs(sq_min / 5e-5 - 1.0) < 1e-13)  # every decision is a near-tie
    assert 0 < ref.sum() < len(gt)
    np.testing.assert_array_equal(covered_mask(partial, gt), ref)
    bits = coverage_bits(parts, gt)
    for v, pts in enumerate(parts):
        np.testing.assert_array_equal(bits[v], np.packbits(_brute_covered(pts, gt, DEFAULT_EPS)))


def test_coverage_matches_brute_force():
    rng = np.random.default_rng(0)
    gt = rng.uniform(-0.5, 0.5, size=(400, 3))
    partial = gt[:150] + rng.normal(scale=0.01, size=(150, 3))
    for eps in (0.005, LEGACY_EPS, DEFAULT_EPS, 0.02, 0.2):
        ref = _brute_covered(partial, gt, eps)
        np.testing.assert_array_equal(covered_mask(partial, gt, eps), ref)
        assert coverage(partial, gt, eps) == ref.mean()
    assert 0.0 < coverage(partial, gt) < 1.0


def test_coverage_of_the_ground_truth_itself_is_one_and_empty_is_zero():
    rng = np.random.default_rng(1)
    gt = rng.uniform(size=(100, 3)).astype(np.float32)
    assert coverage(gt, gt) == 1.0
    assert coverage(np.zeros((0, 3)), gt) == 0.0
    with pytest.raises(ValueError, match="empty"):
        coverage(gt, np.zeros((0, 3)))
    with pytest.raises(ValueError, match="eps"):
        coverage(gt, gt, eps=0.0)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        coverage(gt[:, :2], gt)


def test_eps_boundary_is_strict():
    gt = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    eps = DEFAULT_EPS
    below = np.array([[eps * (1 - 1e-6), 0.0, 0.0]])
    above = np.array([[eps * (1 + 1e-6), 0.0, 0.0]])
    np.testing.assert_array_equal(covered_mask(below, gt, eps), [True, False])
    np.testing.assert_array_equal(covered_mask(above, gt, eps), [False, False])
    diag = np.array([[1.0, eps * (1 - 1e-6) / np.sqrt(2), eps * (1 - 1e-6) / np.sqrt(2)]])
    np.testing.assert_array_equal(covered_mask(diag, gt, eps), [False, True])


def test_bits_give_the_coverage_of_the_merged_cloud():
    rng = np.random.default_rng(2)
    eps = 0.05
    gt, views = _random_views(rng, n_views=9, n_gt=301, eps=eps)  # 301: bits need padding
    bits = coverage_bits(views, gt, eps)
    assert bits.shape == (9, 38) and bits.dtype == np.uint8
    for v, pts in enumerate(views):
        np.testing.assert_array_equal(
            np.unpackbits(bits[v])[: len(gt)], _brute_covered(pts, gt, eps)
        )
    for _ in range(40):
        state = rng.random(9) < rng.uniform(0.1, 0.9)
        merged = np.concatenate([views[v] for v in np.flatnonzero(state)] + [np.zeros((0, 3))])
        expected = _brute_covered(merged, gt, eps).mean()
        assert coverage_from_bits(bits, state, len(gt)) == expected
        assert_gains_are_differences(
            coverage_gains(bits, state, len(gt)),
            state,
            lambda grown: coverage_from_bits(bits, grown, len(gt)),
            expected,
            abs_tol=1e-15,
        )
    assert coverage_from_bits(bits, np.zeros(9, dtype=bool), len(gt)) == 0.0
    np.testing.assert_allclose(
        coverage_gains(bits, np.zeros(9, dtype=bool), len(gt)),
        [coverage(v, gt, eps) for v in views],
    )


def test_bits_refuse_inconsistent_input():
    bits = np.zeros((3, 4), dtype=np.uint8)
    with pytest.raises(ValueError, match="n_gt"):
        coverage_from_bits(bits, np.ones(3, dtype=bool), 40)
    with pytest.raises(ValueError, match="view_state"):
        coverage_from_bits(bits, np.ones(4, dtype=bool), 32)
    with pytest.raises(ValueError, match="uint8"):
        coverage_gains(bits.astype(np.int64), np.ones(3, dtype=bool), 32)
    assert coverage_from_bits(bits, np.array([1, 0, 1]), 32) == 0.0


def test_hull_volume_of_known_shapes():
    assert hull_volume(CUBE) == pytest.approx(1.0, abs=1e-12)
    rng = np.random.default_rng(3)
    inside = rng.uniform(0.1, 0.9, size=(200, 3))
    assert hull_volume(np.concatenate([CUBE * 2.0 - 0.5, inside])) == pytest.approx(8.0)
    # Regular tetrahedron with edge a: a^3 / (6 sqrt 2).
    tet = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float32)
    a = 2.0 * np.sqrt(2.0)
    assert hull_volume(tet) == pytest.approx(a**3 / (6.0 * np.sqrt(2.0)), rel=1e-6)
    d = rng.normal(size=(20000, 3))
    sphere = 0.5 * d / np.linalg.norm(d, axis=1, keepdims=True)
    vol = hull_volume(sphere)
    assert vol < 4.0 / 3.0 * np.pi * 0.125
    assert vol == pytest.approx(4.0 / 3.0 * np.pi * 0.125, rel=2e-3)


@pytest.mark.parametrize(
    "points",
    [
        np.zeros((0, 3)),
        np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]),
        np.repeat([[0.3, 0.2, 0.1]], 50, axis=0),
        np.array([[t, 2 * t, -t] for t in np.linspace(0, 1, 20)]),
        np.array([[x, y, 0.25] for x in range(5) for y in range(5)], dtype=float),
        np.array([[x, y, x + y] for x in range(5) for y in range(5)], dtype=float),
    ],
    ids=["empty", "3 points", "duplicates", "colinear", "flat grid", "tilted plane"],
)
def test_degenerate_hulls_have_no_volume(points):
    assert hull_volume(points) == 0.0
    verts = hull_vertices(points)
    assert len(verts) <= max(len(np.unique(points, axis=0)), 0)
    if len(points):
        # The kept points span the same lower-dimensional hull: same extent along every axis.
        np.testing.assert_allclose(verts.min(axis=0), points.min(axis=0))
        np.testing.assert_allclose(verts.max(axis=0), points.max(axis=0))


def test_hull_vertices_of_a_flat_grid_are_its_corners():
    grid = np.array([[x, y, 0.25] for x in range(5) for y in range(5)], dtype=float)
    corners = {(0.0, 0.0), (0.0, 4.0), (4.0, 0.0), (4.0, 4.0)}
    assert {tuple(v[:2]) for v in hull_vertices(grid)} == corners
    line = np.array([[t, 2 * t, -t] for t in np.linspace(0, 1, 20)])
    ends = hull_vertices(line)
    np.testing.assert_allclose(ends[np.argsort(ends[:, 0])], line[[0, -1]])
    assert hull_vertices(np.repeat([[1.0, 2, 3]], 7, axis=0)).shape == (1, 3)


def test_hull_vertices_span_the_same_hull():
    rng = np.random.default_rng(4)
    pts = rng.normal(size=(3000, 3))
    verts = hull_vertices(pts)
    assert len(verts) < len(pts)
    assert hull_volume(verts) == pytest.approx(hull_volume(pts), rel=1e-12)
    assert np.isin(verts, pts).all()


def test_vig_of_cube_halves_and_flat_ground_truth():
    rng = np.random.default_rng(5)
    gt = np.concatenate([CUBE, rng.uniform(size=(500, 3))])
    lower = gt[gt[:, 2] <= 0.5]
    lower_box = np.concatenate([lower, CUBE * [1, 1, 0.5]])
    assert vig(lower_box, gt) == pytest.approx(0.5, abs=1e-12)
    assert vig(gt, gt) == pytest.approx(1.0)
    assert vig(np.zeros((0, 3)), gt) == 0.0
    flat = np.array([[x, y, 0.0] for x in range(3) for y in range(3)], dtype=float)
    with pytest.raises(ValueError, match="VIG is undefined"):
        vig(gt, flat)
    with pytest.raises(ValueError, match="non-finite"):
        hull_volume(np.array([[np.nan, 0, 0]] * 5))


def test_vig_of_state_equals_the_hull_of_the_merged_cloud():
    rng = np.random.default_rng(6)
    gt, views = _random_views(rng, n_views=12, n_gt=1000, eps=0.01)
    # A flat view and an empty one must not break the union.
    views[3] = np.array([[x, y, 0.9] for x in np.linspace(-0.3, 0.3, 6) for y in (-0.2, 0.2)])
    views[7] = np.zeros((0, 3))
    gt_volume = hull_volume(gt)
    verts = view_hull_vertices(views)
    assert sum(len(v) for v in verts) < sum(len(v) for v in views)
    for _ in range(25):
        state = rng.random(12) < rng.uniform(0.1, 0.7)
        merged = np.concatenate([views[v] for v in np.flatnonzero(state)] + [np.zeros((0, 3))])
        expected = vig(merged, gt)
        assert vig_of_state(verts, state, gt_volume) == pytest.approx(expected, rel=1e-10)
        gains = vig_gains(verts, state, gt_volume)
        assert_gains_are_differences(
            gains,
            state,
            lambda grown: vig_of_state(verts, grown, gt_volume),
            expected,
            abs_tol=1e-10,
        )
        assert (gains >= -1e-12).all()
    assert vig_of_state(verts, np.zeros(12, dtype=bool), gt_volume) == 0.0
    with pytest.raises(ValueError, match="gt_volume"):
        vig_of_state(verts, np.zeros(12, dtype=bool), 0.0)


def _views_of_a_sphere(rng: np.random.Generator, n_views: int = 12) -> list[np.ndarray]:
    """Points of a unit sphere split into caps around random directions, one cap a view."""
    pts = rng.normal(size=(6000, 3))
    pts /= np.linalg.norm(pts, axis=1, keepdims=True)
    dirs = rng.normal(size=(n_views, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return [pts[pts @ d > 0.6] for d in dirs]


@pytest.mark.slow
def test_union_hulls_equal_the_hull_of_the_merged_views():
    rng = np.random.default_rng(4)
    views = _views_of_a_sphere(rng)
    unions = UnionHulls([hull_vertices(v) for v in views])
    for _ in range(40):
        order = rng.permutation(len(views))[: rng.integers(1, len(views) + 1)]
        for i in range(1, len(order) + 1):
            merged = np.concatenate([views[v] for v in order[:i]])
            assert unions.volume(order[:i]) == pytest.approx(hull_volume(merged), rel=1e-12)


def test_union_hulls_memoise_each_set_once_whatever_the_order():
    rng = np.random.default_rng(5)
    unions = UnionHulls([hull_vertices(v) for v in _views_of_a_sphere(rng, 6)])
    first = unions.volume([4, 1, 2])
    size = len(unions)  # the empty set, {1}, {1, 2}, {1, 2, 4}: the path to the set
    assert size == 4
    assert unions.volume([2, 4, 1, 4]) == first
    assert len(unions) == size
    assert unions.volume([]) == 0.0
    with pytest.raises(IndexError, match="outside 0..5"):
        unions.volume([6])


def test_union_hulls_grow_from_flat_and_single_views():
    square = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    unions = UnionHulls([square, square + [0, 0, 1], np.array([[0.5, 0.5, 3.0]])])
    assert unions.volume([0]) == 0.0
    assert unions.volume([2]) == 0.0
    assert unions.volume([0, 2]) == pytest.approx(1.0)  # a pyramid of base 1 and height 3
    assert unions.volume([0, 1]) == pytest.approx(1.0)  # the unit cube
    assert unions.volume([0, 1, 2]) == pytest.approx(1.0 + 2.0 / 3.0)
