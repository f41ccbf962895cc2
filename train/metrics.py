"""Training metrics: rank correlation and best-view agreement of predicted and true gains."""

from __future__ import annotations

import numpy as np
from scipy.stats import spearmanr

from nbv.utils.selection import masked_argmax

#: Validation Spearman per model and epoch, in a training run's folder.
SPEARMAN_FILE = "val_spearman_by_model.csv"


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


def spearman_by_model(
    pred: np.ndarray, target: np.ndarray, view_state: np.ndarray, models: np.ndarray
) -> list[dict]:
    """:func:`spearman` of each model's samples: ``[{"model", "samples", "spearman"}, ...]``
    in the order the models first appear (``models``: (S,) the model of each sample)."""
    out = []
    for model in dict.fromkeys(np.asarray(models).tolist()):
        rows = np.asarray(models) == model
        value = spearman(pred[rows], target[rows], view_state[rows])
        out.append({"model": str(model), "samples": int(rows.sum()), "spearman": value})
    return out


def best_view_hits(pred: np.ndarray, target: np.ndarray, view_state: np.ndarray) -> float:
    """Fraction of samples whose predicted best unvisited view is the oracle's best one.

    Ties in the target count as hits when the prediction picks any of the tied best views.
    """
    masked_target = np.where(view_state, -np.inf, target)
    picked = masked_argmax(pred, view_state)
    best = masked_target.max(axis=1)
    return float(np.mean(masked_target[np.arange(len(picked)), picked] >= best))
