"""Training metrics: rank correlation and best-view agreement of predicted and true gains,
overall and by trajectory stage."""

from __future__ import annotations

import numpy as np

from nbv.dataset.samples import SampleSet
from nbv.utils.ranking import best_view_hits, spearman

__all__ = [
    "EARLY_STEPS",
    "SPEARMAN_FILE",
    "best_view_hits",
    "ranking_metrics",
    "spearman",
    "spearman_by_model",
    "spearman_by_stage",
]

#: Validation Spearman per model and epoch, in a training run's folder.
SPEARMAN_FILE = "val_spearman_by_model.csv"
#: Steps 0 .. EARLY_STEPS - 1 of a trajectory are its early samples (one or two views visited,
#: large gains); the later steps are its late ones (80 % of the samples of 10-step trajectories).
EARLY_STEPS = 2


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


def spearman_by_stage(
    pred: np.ndarray, target: np.ndarray, view_state: np.ndarray, step: np.ndarray
) -> dict[str, float]:
    """:func:`spearman` of all samples, of the early ones (``step < EARLY_STEPS``) and of the
    late ones: ``{"spearman", "spearman_early", "spearman_late"}`` (NaN for a stage without a
    sample whose ranking is defined).

    Args:
        pred, target: (S, V) predicted scores and true gains.
        view_state: (S, V) bool, True for visited views (not ranked).
        step: (S,) the step of each sample in its trajectory (0 = one view visited).
    """
    early = np.asarray(step) < EARLY_STEPS
    out = {"spearman": spearman(pred, target, view_state)}
    for name, rows in (("early", early), ("late", ~early)):
        value = spearman(pred[rows], target[rows], view_state[rows]) if rows.any() else np.nan
        out[f"spearman_{name}"] = float(value)
    return out


def ranking_metrics(pred: np.ndarray, samples: SampleSet, prefix: str) -> dict[str, float]:
    """``<prefix>_spearman`` overall, ``_early`` and ``_late`` (:func:`spearman_by_stage`) and
    ``<prefix>_best_view_hits`` of predictions ``pred`` (S, V) of ``samples``."""
    stages = spearman_by_stage(pred, samples.target, samples.view_state, samples.step)
    out = {f"{prefix}_{k}": v for k, v in stages.items()}
    out[f"{prefix}_best_view_hits"] = best_view_hits(pred, samples.target, samples.view_state)
    return out
