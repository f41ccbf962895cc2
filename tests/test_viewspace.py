from pathlib import Path

import numpy as np
import pytest

from nbv.geometry.symmetry import viewspace_symmetries
from nbv.geometry.viewspace import (
    DATA_DIR,
    PERMUTED_SEED,
    ViewspaceError,
    angular_distances,
    elevation,
    get_viewspace,
    load_viewspace,
    original_viewspace,
    permuted_viewspace,
    save_viewspace,
    spread_picks,
    spread_views,
)
from nbv.geometry.viewspace_generators import (
    UP_AXES,
    ViewspaceSpec,
    fibonacci_sphere,
    rings,
    up_rotation,
)

REFERENCE = (
    Path(__file__).resolve().parents[2] / "shared" / "reference" / "viewspace_original_33.txt"
)


def test_original_viewspace_layout():
    vs = original_viewspace()
    assert vs.shape == (33, 3) and vs.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(vs, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(vs[0], [0, 1, 0], atol=1e-15)
    rings = elevation(vs[1:]).reshape(4, 8)
    np.testing.assert_allclose(rings, [[60] * 8, [30] * 8, [0] * 8, [-30] * 8], atol=1e-9)
    # Azimuth 0 is +z, then 45 degrees towards +x.
    np.testing.assert_allclose(vs[17], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(vs[19], [1, 0, 0], atol=1e-15)


@pytest.mark.skipif(
    not REFERENCE.exists(), reason="../shared/reference is not beside this checkout"
)
def test_original_viewspace_matches_reference_file():
    np.testing.assert_allclose(original_viewspace(), np.loadtxt(REFERENCE), rtol=0, atol=1e-12)


def test_shipped_original_file_matches():
    np.testing.assert_allclose(
        load_viewspace(DATA_DIR / "original_33.txt"), original_viewspace(), rtol=0, atol=1e-15
    )


def test_permuted_viewspace_properties():
    orig = original_viewspace()
    perm = get_viewspace("permuted")
    assert perm.shape == (33, 3)
    np.testing.assert_allclose(np.linalg.norm(perm, axis=1), 1.0, atol=1e-12)
    # No permuted view within 5 degrees of an original view (so positions differ, and so order).
    assert angular_distances(perm, orig).min() >= 5.0
    # Same elevation band, and spread over it: both hemispheres of the band and all azimuths.
    el = elevation(perm)
    assert el.min() >= -30.0 and el.max() <= 90.0
    assert (el < 0).sum() >= 3 and (el > 45).sum() >= 3
    az = np.rad2deg(np.arctan2(perm[:, 0], perm[:, 2])) % 360
    assert np.histogram(az, bins=4, range=(0, 360))[0].min() >= 4
    # Evenly spread: no two permuted views closer than 10 degrees.
    d = angular_distances(perm, perm) + np.eye(33) * 999
    assert d.min() > 10.0


def test_permuted_file_is_the_seeded_procedure():
    np.testing.assert_allclose(
        get_viewspace("permuted"), permuted_viewspace(PERMUTED_SEED), rtol=0, atol=1e-15
    )
    assert not np.allclose(permuted_viewspace(1), permuted_viewspace(2))


def test_save_load_round_trip(tmp_path):
    vs = permuted_viewspace(5)
    save_viewspace(tmp_path / "v.txt", vs)
    np.testing.assert_array_equal(load_viewspace(tmp_path / "v.txt"), vs)
    assert np.array_equal(get_viewspace(tmp_path / "v.txt"), vs)


def test_user_file_with_comments_and_commas(tmp_path):
    path = tmp_path / "mine.txt"
    path.write_text("# my views\n1 0 0\n\n0, 2, 0\n")
    np.testing.assert_array_equal(load_viewspace(path), [[1, 0, 0], [0, 2, 0]])


@pytest.mark.parametrize(
    "text, line, message",
    [
        ("1 0 0\n0 1\n", 2, "expected 3 columns"),
        ("1 0 0\n0 1 0 4\n", 2, "expected 3 columns"),
        ("1 0 nan\n", 1, "NaN or infinite"),
        ("1 0 0\n0 inf 0\n", 2, "NaN or infinite"),
        ("1 0 0\n0 0 0\n", 2, "zero vector"),
        ("1 0 0\n0 1 0\n2 0 0\n", 3, "duplicate of the direction on line 1"),
        ("1 a 0\n", 1, "not a number"),
    ],
)
def test_bad_viewspace_files_refused_with_file_and_line(tmp_path, text, line, message):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(ViewspaceError, match=message) as err:
        load_viewspace(path)
    assert f"{path}:{line}:" in str(err.value)


def test_missing_and_empty_files_refused(tmp_path):
    with pytest.raises(ViewspaceError, match="cannot read"):
        load_viewspace(tmp_path / "none.txt")
    (tmp_path / "empty.txt").write_text("# nothing\n")
    with pytest.raises(ViewspaceError, match="no camera positions"):
        load_viewspace(tmp_path / "empty.txt")
    with pytest.raises(ViewspaceError, match="no such viewspace"):
        get_viewspace("sideways")


# --- generated viewspaces for real rigs (nbv.geometry.viewspace_generators) ---


def _min_gap(dirs: np.ndarray) -> float:
    gaps = angular_distances(dirs, dirs) + np.diag(np.full(len(dirs), np.inf))
    return float(gaps.min())


@pytest.mark.parametrize("n", [2, 7, 33, 100])
@pytest.mark.parametrize("hemisphere", [False, True])
def test_fibonacci_lattice_counts_radii_no_duplicates(n, hemisphere):
    dirs = fibonacci_sphere(n, hemisphere)
    assert dirs.shape == (n, 3) and dirs.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-15)
    assert _min_gap(dirs) > 1.0  # degrees: no two alike
    height = dirs[:, 1]
    if hemisphere:
        np.testing.assert_allclose(height, 1 - (np.arange(n) + 0.5) / n, atol=1e-15)
        assert height.min() > 0
    else:
        np.testing.assert_allclose(height, 1 - (2 * np.arange(n) + 1) / n, atol=1e-15)
        assert abs(height.mean()) < 1e-12  # even in height: the lattice is area-uniform


def test_fibonacci_sphere_is_even_its_spacing_close_to_the_ideal():
    # n equal caps cover the sphere: the nearest-neighbour angle of an even set is about
    # sqrt(4 pi / n) radians; the lattice's smallest gap is at least 70 % of it.
    n = 200
    ideal = np.rad2deg(np.sqrt(4 * np.pi / n))
    assert _min_gap(fibonacci_sphere(n)) > 0.7 * ideal


def test_rings_reproduce_the_original_viewspace_row_for_row():
    np.testing.assert_allclose(rings([90, 60, 30, 0, -30], 8), original_viewspace(), atol=1e-15)


def test_rings_counts_elevations_and_per_ring_lists():
    dirs = rings([45, 10, -20], [6, 12, 3])
    assert dirs.shape == (21, 3)
    np.testing.assert_allclose(elevation(dirs), [45] * 6 + [10] * 12 + [-20] * 3, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-15)
    # Azimuths of a ring of 12: 0, 30, ..., 330 degrees from +z towards +x.
    az = np.rad2deg(np.arctan2(dirs[6:18, 0], dirs[6:18, 2])) % 360
    np.testing.assert_allclose(az, np.arange(0, 360, 30), atol=1e-9)
    assert _min_gap(dirs) > 1.0


def test_a_pole_ring_is_one_view():
    np.testing.assert_allclose(rings([-90, 0], 4), [[0, -1, 0], [0, 0, 1], [1, 0, 0], [0, 0, -1],
                                                    [-1, 0, 0]], atol=1e-15)  # fmt: skip


@pytest.mark.parametrize("up", list(UP_AXES))
def test_up_rotation_is_a_rotation_taking_y_to_up(up):
    r = up_rotation(up)
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_allclose(r @ [0, 1, 0], UP_AXES[up], atol=1e-15)
    # A hemisphere about that axis lies on its side of the plane through the centre.
    assert (fibonacci_sphere(50, True, up) @ np.array(UP_AXES[up])).min() > 0


def test_z_up_turns_the_original_viewspace_pole_to_z():
    dirs = ViewspaceSpec(kind="original", up="z").directions()
    np.testing.assert_allclose(dirs[0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(dirs @ up_rotation("z"), original_viewspace(), atol=1e-15)


def test_spec_directions_of_each_kind(tmp_path):
    path = tmp_path / "vs.txt"
    save_viewspace(path, 3.0 * original_viewspace()[:5])
    assert np.array_equal(ViewspaceSpec().directions(), original_viewspace())
    np.testing.assert_allclose(ViewspaceSpec(kind="file", file=str(path)).directions(),
                               original_viewspace()[:5], atol=1e-15)  # fmt: skip
    assert ViewspaceSpec(kind="sphere", n=12).directions().shape == (12, 3)
    assert ViewspaceSpec(kind="hemisphere", n=12).directions()[:, 1].min() > 0
    assert ViewspaceSpec(kind="rings", elevations=(30.0,), per_ring=5).directions().shape == (5, 3)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        (dict(kind="ball"), "viewspace.kind='ball': must be one of original, permuted, file"),
        (dict(kind="file"), "viewspace.kind=file needs viewspace.file="),
        (dict(kind="sphere", n=1), "viewspace.n=1: must be an integer >= 2"),
        (dict(kind="rings", elevations=(95.0,)), r"viewspace.elevations=\[95.0\]: must be degrees"),
        (dict(kind="rings", elevations=()), "viewspace.elevations is empty"),
        (dict(kind="rings", elevations=(10.0, 10.0)), "an elevation is given twice"),
        (dict(kind="rings", elevations=(10.0, 20.0), per_ring=(4, 5, 6)), "one per elevation"),
        (dict(kind="rings", per_ring=0), "counts must be integers >= 1"),
        (dict(up="w"), "viewspace.up='w': must be one of x, y, z, -x, -y, -z"),
    ],
)
def test_invalid_specs_get_one_message_naming_the_key(spec, message):
    with pytest.raises(ViewspaceError, match=message):
        ViewspaceSpec(**spec)


def test_a_file_with_two_views_in_one_direction_is_refused(tmp_path):
    path = tmp_path / "vs.txt"
    path.write_text("0 0 1\n1 0 0\n0 0 2\n")
    with pytest.raises(ViewspaceError, match="duplicate of the direction on line 1"):
        ViewspaceSpec(kind="file", file=str(path)).directions()


def test_angular_distances_known_angles_and_zero_to_itself():
    a = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    b = np.array([[3.0, 3.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 5.0]])
    np.testing.assert_allclose(
        angular_distances(a, b), [[45.0, 180.0, 90.0], [45.0, 90.0, 90.0]], rtol=0, atol=1e-12
    )
    # 0 from every direction to itself, to rounding (arccos of the dot product is off by up to
    # ~1e-6 degrees, as much as the threshold that tells one view from another).
    for name in ("original", "permuted"):
        vs = get_viewspace(name)
        assert np.all(np.diag(angular_distances(vs, vs)) == 0.0)
        assert np.diag(angular_distances(vs, 2.5 * vs)).max() < 1e-12


def test_angular_distances_tie_views_equally_far_in_exact_arithmetic():
    # PC-NBV's viewspace has 16 symmetries; each maps every pair of views to a pair exactly as
    # far apart, and the rounded angles agree to the last bit (arccos gave 52 distinct values
    # where there are 28).
    vs = get_viewspace("original")
    angles = angular_distances(vs, vs)
    symmetries = viewspace_symmetries(vs)
    assert len(symmetries) == 16
    for sym in symmetries:
        p = sym.permutation
        assert np.array_equal(angles[np.ix_(p, p)], angles)
    assert len(np.unique(angles)) == 28


# --------------------------------------------------------------------------------------------
# Spread picks: maximin, ties counted, broken at random with a generator
# --------------------------------------------------------------------------------------------


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _farthest_by_brute_force(unit: np.ndarray, closed: list[int], tol: float = 1e-9) -> list[int]:
    """The open views whose smallest angle (radians, arccos) to a closed view is within ``tol``
    of the largest such angle; every open view when nothing is closed."""
    open_ = [v for v in range(len(unit)) if v not in closed]
    if not closed:
        return open_
    smallest = [min(np.arccos(np.clip(unit[v] @ unit[w], -1, 1)) for w in closed) for v in open_]
    return [v for v, a in zip(open_, smallest, strict=True) if a >= max(smallest) - tol]


def _lowest_index_spread(directions, closed, count) -> list[int]:
    """The rule before the random tie-break, as it was written: cosines rounded to 12 decimals,
    the lowest index of the smallest."""
    open_views = ~np.array(closed, dtype=bool)
    nearest = np.full(len(directions), -np.inf)
    if (~open_views).any():
        nearest = (directions @ directions[~open_views].T).max(axis=1)
    picks = []
    for _ in range(count):
        candidates = np.flatnonzero(open_views)
        best = int(candidates[np.argmin(np.round(nearest[candidates], 12))])
        picks.append(best)
        open_views[best] = False
        np.maximum(nearest, directions @ directions[best], out=nearest)
    return picks


#: Three rings of 6, 12 and 6 views: many ties, of different sizes.
RINGS = _unit(rings([60, 10, -40], [6, 12, 6]))


@pytest.mark.parametrize("seed", [None, 0, 1])
def test_spread_picks_are_maximin_and_count_their_ties_exactly(seed):
    rng = None if seed is None else np.random.default_rng(seed)
    for start in (0, 7, 20):
        closed = np.zeros(len(RINGS), dtype=bool)
        closed[start] = True
        picks = spread_picks(RINGS, closed, len(RINGS) - 1, rng)
        assert sorted(picks.views) == sorted(set(range(len(RINGS))) - {start})
        visited = [start]
        for view, tied in zip(picks.views, picks.tied, strict=True):
            farthest = _farthest_by_brute_force(RINGS, visited)
            assert view in farthest  # no open view is farther than the pick
            assert tied == len(farthest)
            if seed is None:
                assert view == min(farthest)
            visited.append(view)
        assert picks.ties == sum(1 for t in picks.tied if t > 1)
        assert 0 < picks.ties < len(picks.views)  # both kinds of decision happen here
    # The input is not modified.
    assert closed.sum() == 1


def test_spread_breaks_ties_uniformly_over_the_tied_views_and_repeats_a_seed():
    closed = np.zeros(len(RINGS), dtype=bool)
    closed[[0, 3]] = True  # opposite views of the top ring: four of the bottom ring tie
    tied = _farthest_by_brute_force(RINGS, [0, 3])
    assert tied == [19, 20, 22, 23]
    # Nothing closed: all 24 views tie for the first pick.
    nothing = np.zeros(len(RINGS), dtype=bool)
    firsts = [spread_views(RINGS, nothing, 1, np.random.default_rng(s))[0] for s in range(400)]
    assert set(firsts) == set(range(len(RINGS)))
    seconds = [spread_views(RINGS, closed, 1, np.random.default_rng(s))[0] for s in range(400)]
    assert set(seconds) == set(tied)
    # Each is binomial(400, 1/4) (mean 100, sd 8.7): outside 60-140 has p < 1e-5 in all.
    assert all(60 < seconds.count(v) < 140 for v in tied)
    # Whole sequences: the same seed, the same picks; another seed, other picks.
    a = spread_views(RINGS, closed, 12, np.random.default_rng(5))
    assert spread_views(RINGS, closed, 12, np.random.default_rng(5)) == a
    assert any(spread_views(RINGS, closed, 12, np.random.default_rng(s)) != a for s in range(6, 9))


@pytest.mark.parametrize("name", ["original", "permuted"])
def test_without_a_generator_spread_is_the_lowest_index_rule_of_before(name):
    d = _unit(get_viewspace(name))
    ties = 0
    for start in range(len(d)):
        closed = np.zeros(len(d), dtype=bool)
        closed[start] = True
        picks = spread_picks(d, closed, len(d) - 1)
        assert picks.views == _lowest_index_spread(d, closed, len(d) - 1), start
        assert spread_views(d, closed, len(d) - 1) == picks.views
        ties += picks.ties
    # The original viewspace's rings tie in most decisions; the permuted one never ties.
    assert ties == {"original": 834, "permuted": 0}[name]
    # From the top pole the farthest views are the -30 degree ring: the tie goes to its first.
    if name == "original":
        top = np.zeros(33, dtype=bool)
        top[0] = True
        assert spread_picks(d, top, 1) == ([25], [8])
