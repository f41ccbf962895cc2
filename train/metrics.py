"""Training metrics: rank correlation and best-view agreement of predicted and true gains."""

from __future__ import annotations

import numpy as np
from scipy.stats import spearmanr

from nbv.utils.selection import masked_argmax


def spearman(pred: np.ndarray, target: np.ndarray, view_state: np.ndarray) -> float:
    """Mean over samples of Spearman's rank correlation between predicted and true gains.

    Args:
        pred, target: (S, V) predicted and true gains.
        view_state: (S, V) bool; only unvisited views are ranked.

    Returns:
        The mean correlation over samples where it is defined (NaN when none is: a constant
        prediction or target has no ranks).
    """
    values = []
    for p, t, s in zip(pred, target, view_state, strict=True):
        free = ~s
        if free.sum() < 2 or np.ptp(t[free]) == 0 or np.ptp(p[free]) == 0:
            continue
        values.append(spearmanr(p[free], t[free]).statistic)
    return float(np.mean(values)) if values else float("nan")


def best_view_hits(pred: np.ndarray, target: np.ndarray, view_state: np.ndarray) -> float:
    """Fraction of samples whose predicted best unvisited view is the oracle's best one.

    Ties in the target count as hits when the prediction picks any of the tied best views.
    """
    masked_target = np.where(view_state, -np.inf, target)
    picked = masked_argmax(pred, view_state)
    best = masked_target.max(axis=1)
    return float(np.mean(masked_target[np.arange(len(picked)), picked] >= best))
