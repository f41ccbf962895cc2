"""How well predicted view scores rank the true gains: Spearman's rank correlation over the
unvisited views of each sample, and how often the predicted best view is the true best one."""

from __future__ import annotations

import numpy as np
from scipy.stats import spearmanr

from nbv.utils.selection import masked_argmax


def spearman_per_sample(pred: np.ndarray, target: np.ndarray, view_state: np.ndarray) -> np.ndarray:
    """Spearman's rank correlation of each sample's predicted and true gains.

    Args:
        pred, target: (S, V) predicted scores and true gains.
        view_state: (S, V) bool; only unvisited views are ranked.

    Returns:
        (S,) float; NaN where it is undefined (fewer than two unvisited views, or constant
        predictions or targets among them: no ranks).
    """
    out = np.full(len(pred), np.nan)
    for i, (p, t, s) in enumerate(zip(pred, target, view_state, strict=True)):
        free = ~np.asarray(s, dtype=bool)
        if free.sum() < 2 or np.ptp(t[free]) == 0 or np.ptp(p[free]) == 0:
            continue
        out[i] = spearmanr(p[free], t[free]).statistic
    return out


def spearman(pred: np.ndarray, target: np.ndarray, view_state: np.ndarray) -> float:
    """Mean of :func:`spearman_per_sample` over the samples where it is defined (NaN when it
    is nowhere)."""
    values = spearman_per_sample(pred, target, view_state)
    values = values[np.isfinite(values)]
    return float(values.mean()) if len(values) else float("nan")


def best_view_hit(pred: np.ndarray, target: np.ndarray, view_state: np.ndarray) -> np.ndarray:
    """(S,) bool: whether each sample's predicted best unvisited view is a true best one (ties
    in the target count as hits when the prediction picks any of the tied best views)."""
    masked_target = np.where(view_state, -np.inf, target)
    picked = masked_argmax(pred, view_state)
    best = masked_target.max(axis=1)
    return masked_target[np.arange(len(picked)), picked] >= best


def best_view_hits(pred: np.ndarray, target: np.ndarray, view_state: np.ndarray) -> float:
    """Fraction of samples whose predicted best unvisited view is the oracle's best one
    (the mean of :func:`best_view_hit`)."""
    return float(np.mean(best_view_hit(pred, target, view_state)))


def split_half_reliability(
    covered: np.ndarray, view_state: np.ndarray, rng: np.random.Generator, splits: int = 4
) -> float:
    """How far the true coverage gains of one state rank the views reproducibly: the split-half
    reliability of their ranking over the ground-truth points.

    The ground-truth points are split at random into two halves; the unvisited views' gains
    counted on each half are rank-correlated (Spearman), the correlation is averaged over
    ``splits`` splits and stepped up to the whole set by Spearman-Brown, ``2 r / (1 + r)``. Late
    in an episode a view gains a handful of points, and which views gain a few more is then
    largely which points were sampled: no scorer's Spearman against the gains can be expected
    above about the square root of this value.

    Args:
        covered: (V, N) bool, the ground-truth points each view covers.
        view_state: (V,) bool, True for visited views.
        rng: draws the splits.
        splits: random splits averaged.

    Returns:
        The reliability, at most 1 (a negative mean correlation is returned as it is: there is
        nothing to step up); NaN when no split gives both halves ranks (fewer than two
        unvisited views, or all gaining alike on a half).
    """
    state = np.asarray(view_state, dtype=bool)
    new = covered[~state] & ~covered[state].any(axis=0)
    values = []
    for _ in range(splits):
        half = rng.random(covered.shape[1]) < 0.5
        a, b = new[:, half].sum(axis=1), new[:, ~half].sum(axis=1)
        if len(a) >= 2 and np.ptp(a) > 0 and np.ptp(b) > 0:
            values.append(spearmanr(a, b).statistic)
    if not values:
        return float("nan")
    r = float(np.mean(values))
    return 2 * r / (1 + r) if r > 0 else r
