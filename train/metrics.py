"""Training metrics: rank correlation and best-view agreement of predicted and true gains."""

from __future__ import annotations

import numpy as np

from nbv.utils.ranking import best_view_hits, spearman

__all__ = ["SPEARMAN_FILE", "best_view_hits", "spearman", "spearman_by_model"]

#: Validation Spearman per model and epoch, in a training run's folder.
SPEARMAN_FILE = "val_spearman_by_model.csv"


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
