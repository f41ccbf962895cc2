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
