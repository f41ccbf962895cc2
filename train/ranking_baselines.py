"""What a network's ranking has to beat: two baselines scored on the same validation samples.

* ``ridge``: for each candidate view ``v`` a linear model (ridge regression, closed form) of the
  sample's view state (V bits), ``v``'s angle to its nearest visited view (radians), the step and
  a constant, fitted on the training samples in which ``v`` is unvisited, against ``v``'s gain
  divided by the sample's largest gain. Its weights are the candidate's own: a model whose
  weights were shared by every candidate would rank the views of a sample by the angle alone
  (the view state, step and constant add the same to every candidate), that is, as ``spread``.
* ``spread``: the angle to the nearest visited view alone, the rule of the ``spread`` policy.

Both are scored by :func:`train.metrics.spearman_by_stage` (the project's Spearman over the
unvisited views, overall and at early and late steps), as the network is, so the numbers compare.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from nbv.dataset.samples import SampleSet
from nbv.geometry.viewspace import angular_distances
from nbv.utils.atomic import write_text
from train.metrics import EARLY_STEPS, spearman_by_stage

__all__ = [
    "BASELINES_FILE",
    "RIDGE_ALPHA",
    "baseline_spearman",
    "fit_ridge",
    "fit_view_ridge",
    "nearest_visited_angles",
    "normalised_targets",
    "ridge_features",
    "ridge_scores",
    "write_baselines",
]

log = logging.getLogger(__name__)

#: The baselines' validation Spearman, in a training run's folder.
BASELINES_FILE = "baselines.json"
#: The ridge penalty of the training runs' baseline (features of order 1, thousands of rows:
#: a light shrinkage that keeps the never-varying columns' weights at 0).
RIDGE_ALPHA = 1.0


def nearest_visited_angles(directions: np.ndarray, view_state: np.ndarray) -> np.ndarray:
    """The angle at the origin from every view to the nearest visited view of each sample.

    Args:
        directions: (V, 3) view positions or directions (any length but 0).
        view_state: (S, V) bool, True for visited views.

    Returns:
        (S, V) float64 radians in [0, pi]: 0 for a visited view, pi for every view of a sample
        with none visited.
    """
    between = np.deg2rad(angular_distances(directions, directions))  # (V, V)
    state = np.asarray(view_state, dtype=bool)
    # pi where nothing is visited.
    return np.where(state[:, None, :], between[None], np.pi).min(axis=2)


def normalised_targets(target: np.ndarray) -> np.ndarray:
    """(S, V) gains divided by each sample's largest gain; a sample without gain stays as it is
    (the ``normalised`` loss's targets, :mod:`train.losses`)."""
    top = target.max(axis=1, keepdims=True)
    return np.where(top > 0, target / np.where(top > 0, top, 1.0), target).astype(np.float64)


def ridge_features(view_state: np.ndarray, angles: np.ndarray, step: np.ndarray) -> np.ndarray:
    """(S, V, V + 3) float64 features of every (sample, candidate view): the sample's view state
    (V bits), the candidate's angle to its nearest visited view (radians), the sample's step and
    1.

    Args:
        view_state: (S, V) bool.
        angles: (S, V) radians, :func:`nearest_visited_angles`.
        step: (S,) steps of the samples in their trajectories.
    """
    s, v = view_state.shape
    out = np.empty((s, v, v + 3))
    out[:, :, :v] = np.asarray(view_state, dtype=np.float64)[:, None, :]
    out[:, :, v] = angles
    out[:, :, v + 1] = np.asarray(step, dtype=np.float64)[:, None]
    out[:, :, v + 2] = 1.0
    return out


def fit_ridge(x: np.ndarray, y: np.ndarray, alpha: float) -> np.ndarray:
    """The weights ``w`` minimising ``|x w - y|^2 + alpha |w|^2`` (every weight penalised:
    give a constant column for an intercept).

    Args:
        x: (N, F) features.
        y: (N,) targets.
        alpha: >= 0; 0 gives the least-squares solution of least norm.

    Returns:
        (F,) float64.
    """
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if alpha < 0:
        raise ValueError(f"alpha={alpha}: must be >= 0")
    if alpha == 0:
        return np.linalg.lstsq(x, y, rcond=None)[0]
    return np.linalg.solve(x.T @ x + alpha * np.eye(x.shape[1]), x.T @ y)


def fit_view_ridge(
    features: np.ndarray, target: np.ndarray, view_state: np.ndarray, alpha: float
) -> np.ndarray:
    """One ridge per candidate view (:func:`fit_ridge`), each on the samples where that view is
    unvisited; a view never unvisited gets zero weights.

    Args:
        features: (S, V, F) from :func:`ridge_features`.
        target: (S, V) what to predict (e.g. :func:`normalised_targets`).
        view_state: (S, V) bool, True for visited views.
        alpha: the ridge penalty.

    Returns:
        (V, F) float64 weights.
    """
    weights = np.zeros(features.shape[1:])
    for v in range(features.shape[1]):
        rows = ~np.asarray(view_state[:, v], dtype=bool)
        if rows.any():
            weights[v] = fit_ridge(features[rows, v], target[rows, v], alpha)
    return weights


def ridge_scores(features: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(S, V) scores of the per-view ridges: ``features`` (S, V, F), ``weights`` (V, F)."""
    return np.einsum("svf,vf->sv", features, weights)


def baseline_spearman(
    train: SampleSet, val: SampleSet, directions: np.ndarray, alpha: float = 1.0
) -> dict[str, dict[str, float]]:
    """The baselines' Spearman on the validation samples, the ridge fitted on ``train``.

    Args:
        train, val: the samples (same viewspace).
        directions: (V, 3) the samples' viewspace positions.
        alpha: the ridge penalty.

    Returns:
        ``{"ridge": {...}, "spread": {...}}``, each :func:`train.metrics.spearman_by_stage` of
        ``val``.
    """

    def features(samples: SampleSet) -> tuple[np.ndarray, np.ndarray]:
        angles = nearest_visited_angles(directions, samples.view_state)
        return ridge_features(samples.view_state, angles, samples.step), angles

    train_x, _ = features(train)
    weights = fit_view_ridge(train_x, normalised_targets(train.target), train.view_state, alpha)
    val_x, val_angles = features(val)
    scores = {"ridge": ridge_scores(val_x, weights), "spread": val_angles}
    return {
        name: spearman_by_stage(score, val.target, val.view_state, val.step)
        for name, score in scores.items()
    }


def write_baselines(
    out_dir: Path, train: SampleSet, val: SampleSet, directions: np.ndarray, viewspace: str
) -> dict[str, dict[str, float]]:
    """:func:`baseline_spearman` (``alpha`` = :data:`RIDGE_ALPHA`), written to
    ``out_dir/baselines.json`` with what it was computed on, and logged; returned as it is."""
    result = baseline_spearman(train, val, directions, RIDGE_ALPHA)
    info = {"viewspace": viewspace, "ridge_alpha": RIDGE_ALPHA, "early_steps": EARLY_STEPS,
            "train_samples": len(train), "val_samples": len(val)}  # fmt: skip
    write_text(Path(out_dir) / BASELINES_FILE, json.dumps({**result, **info}, indent=1))
    for method, stages in result.items():
        log.info("baseline %s: validation Spearman %.3f (early %.3f, late %.3f)", method,
                 stages["spearman"], stages["spearman_early"], stages["spearman_late"])  # fmt: skip
    return result
