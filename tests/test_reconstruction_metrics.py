"""The reconstruction and path metrics (nbv.geometry.reconstruction_metrics) on cases with known
answers, and against independent brute-force implementations."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from nbv.geometry.reconstruction_metrics import (
    MAX_TOUR_VIEWS,
    ViewDistances,
    cloud_scores,
    distance_scores,
    fscore,
    great_circle_matrix,
    nearest_distances,
    path_length,
    shortest_open_path,
    views_to_reach,
)
from nbv.utils.seeding import named_rng


def grid(spacing: float = 0.1, n: int = 5) -> np.ndarray:
    """(n^3, 3) points of a cubic grid."""
    axis = np.arange(n) * spacing
    return np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)


def brute_scores(recon: np.ndarray, gt: np.ndarray, eps: float) -> dict[str, float]:
    """Chamfer and F-scores from the full distance matrix (no KD-tree)."""
    d = np.linalg.norm(recon[:, None, :] - gt[None, :, :], axis=-1)
    to_gt, to_recon = d.min(axis=1), d.min(axis=0)
    out = {"chamfer_accuracy": to_gt.mean(), "chamfer_completeness": to_recon.mean()}
    out["chamfer"] = (out["chamfer_accuracy"] + out["chamfer_completeness"]) / 2
    for name, t in (("eps", eps), ("2eps", 2 * eps)):
        p, q = (to_gt < t).mean(), (to_recon < t).mean()
        out[f"precision_{name}"], out[f"recall_{name}"] = p, q
        out[f"fscore_{name}"] = 2 * p * q / (p + q) if p + q else 0.0
    return out


def test_chamfer_of_identical_clouds_is_zero_and_f_score_one():
    g = grid()
    s = cloud_scores(g, g, eps=0.01)
    assert s["chamfer"] == s["chamfer_accuracy"] == s["chamfer_completeness"] == 0.0
    assert s["fscore_eps"] == s["fscore_2eps"] == s["precision_eps"] == s["recall_eps"] == 1.0


def test_a_grid_shifted_by_d_is_d_away_in_both_directions():
    g, d = grid(spacing=0.1), 0.03  # d < half the spacing: each point's nearest is its shift
    s = cloud_scores(g + [d, 0.0, 0.0], g, eps=0.02)
    assert s["chamfer_accuracy"] == pytest.approx(d, abs=1e-12)
    assert s["chamfer_completeness"] == pytest.approx(d, abs=1e-12)
    assert s["chamfer"] == pytest.approx(d, abs=1e-12)
    # d = 0.03 lies beyond eps = 0.02 and within 2 eps = 0.04: F-score 0 then 1.
    assert s["precision_eps"] == s["recall_eps"] == s["fscore_eps"] == 0.0
    assert s["fscore_2eps"] == 1.0


def test_f_score_of_half_a_cloud():
    g = grid(n=4)
    half = g[:32]
    s = cloud_scores(half, g, eps=0.01)
    # Every reconstruction point is on the truth (P = 1), half the truth is seen (R = 1/2).
    assert s["precision_eps"] == 1.0 and s["recall_eps"] == 0.5
    assert s["fscore_eps"] == pytest.approx(2 * 0.5 / 1.5)
    assert fscore(0.0, 0.0) == 0.0 and fscore(1.0, 1.0) == 1.0


def test_an_empty_reconstruction_scores_zero_and_has_no_chamfer():
    s = distance_scores(np.zeros(0), nearest_distances(grid(), np.zeros((0, 3))), eps=0.01)
    assert np.isnan(s["chamfer"]) and np.isnan(s["chamfer_accuracy"])
    assert s["chamfer_completeness"] == np.inf
    assert s["fscore_eps"] == s["precision_eps"] == s["recall_eps"] == 0.0


def test_cloud_scores_agree_with_the_brute_force_distance_matrix():
    rng = named_rng(0, "reconstruction", "brute")
    recon, gt = rng.normal(size=(300, 3)) * 0.2, rng.normal(size=(400, 3)) * 0.2
    got, want = cloud_scores(recon, gt, eps=0.03), brute_scores(recon, gt, eps=0.03)
    assert got.keys() == want.keys()
    for key in want:
        assert got[key] == pytest.approx(want[key], rel=1e-12, abs=1e-15), key


def test_view_distances_of_a_union_equal_the_scores_of_the_concatenated_cloud():
    rng = named_rng(0, "reconstruction", "views")
    gt = rng.normal(size=(500, 3)) * 0.2
    parts = [rng.normal(size=(n, 3)) * 0.2 for n in (50, 0, 80, 120, 30)]
    points = np.concatenate(parts).astype(np.float32)
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in parts])])
    memo = ViewDistances(gt, points, offsets, eps=0.03)
    for views in ([0], [2, 0], [0, 1, 2, 3, 4], [3, 4, 2], [1]):
        cloud = np.concatenate([points[offsets[v] : offsets[v + 1]] for v in views])
        want = cloud_scores(cloud, gt, eps=0.03)
        got = memo.scores(views)
        for key in want:
            assert got[key] == pytest.approx(want[key], rel=1e-12, nan_ok=True), (views, key)


def test_views_to_reach_and_censoring_on_hand_made_curves():
    curve = [0.3, 0.6, 0.85, 0.9, 0.95, 0.97]
    assert views_to_reach(curve, 0.3) == 1
    assert views_to_reach(curve, 0.9) == 4  # reached exactly: counts
    assert views_to_reach(curve, 0.92) == 5
    assert views_to_reach(curve, 0.98) is None  # never reached: censored
    # 87.5 % of a total coverage 0.8 is 0.7, which float rounding puts above 7 / 10: a ratio of
    # counts that reaches the target exactly must still count.
    counts = np.array([3, 5, 7, 8]) / 10
    assert 0.875 * 0.8 > counts[2]
    assert views_to_reach(counts, 0.875 * 0.8) == 3
    assert views_to_reach(counts, 0.9 * 0.8) == 4
    assert views_to_reach([0.5, 0.4], 0.45) == 1


def test_great_circle_quarter_turns_are_quarter_circles():
    r = 1.7
    positions = r * np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, 0, 1], [1, 0, 0]], float)
    arcs = great_circle_matrix(positions)
    assert arcs[0, 1] == pytest.approx(np.pi / 2 * r)
    assert arcs[0, 2] == pytest.approx(np.pi * r)  # opposite points: half a circle
    assert arcs[0, 4] == 0.0 and arcs[1, 1] == 0.0
    # Each step a quarter turn: four steps are four quarter circles.
    assert path_length(arcs, [0, 1, 2, 3, 4]) == pytest.approx(4 * np.pi / 2 * r)
    assert path_length(arcs, [3]) == 0.0
    # The radius given wins over the positions' own.
    assert great_circle_matrix(positions, radius=2.0)[0, 1] == pytest.approx(np.pi)


def test_shortest_open_path_against_every_permutation():
    rng = named_rng(0, "reconstruction", "tour")
    for n in (1, 2, 3, 5, 8):
        points = rng.normal(size=(n, 3))
        arcs = great_circle_matrix(points, radius=1.0)
        length, order = shortest_open_path(arcs)
        brute = min(
            (path_length(arcs, [0, *perm]) for perm in itertools.permutations(range(1, n))),
            default=0.0,
        )
        assert length == pytest.approx(brute, abs=1e-12), n
        assert order[0] == 0 and sorted(order) == list(range(n))
        assert path_length(arcs, order) == pytest.approx(length, abs=1e-12)
    # Stops along a line in a scrambled order: the path walks the line.
    x = np.array([0.0, 3.0, 1.0, 4.0, 2.0])
    length, order = shortest_open_path(np.abs(x[:, None] - x[None, :]))
    assert length == 4.0 and order == [0, 2, 4, 1, 3]
    with pytest.raises(ValueError, match="at most"):
        shortest_open_path(np.zeros((MAX_TOUR_VIEWS + 1,) * 2))
