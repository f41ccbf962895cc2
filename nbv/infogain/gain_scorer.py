"""A learned score of candidate views: a small perceptron over :mod:`nbv.infogain.view_features`.

The weights are a plain JSON file (no pickle, readable without torch): the layers, the feature
names they were trained on, and what made them (``python -m train.scorer`` writes it; the
package ships ``nbv/assets/weights/ig_learned.json``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from nbv.infogain.view_features import FEATURES
from nbv.utils.atomic import write_text

#: Format tag of the weight files.
FORMAT = "nbv-gain-scorer-1"


class ScorerError(ValueError):
    """A scorer file is missing or unusable; the message names the file and what is wrong."""


@dataclass(frozen=True)
class GainScorer:
    """A perceptron with ReLU hidden layers and one output: higher is a better next view.

    Attributes:
        weights: per layer ``(inputs, outputs)`` float64 matrices; the first takes
            ``len(FEATURES)`` inputs, the last gives 1 output.
        biases: per layer ``(outputs,)`` float64.
        info: what made it (command, dataset identity, settings), kept as given.
    """

    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    info: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if len(self.weights) != len(self.biases) or not self.weights:
            raise ValueError("a scorer needs as many bias vectors as weight matrices, at least 1")
        inputs = len(FEATURES)
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            if w.ndim != 2 or w.shape[0] != inputs or b.shape != (w.shape[1],):
                raise ValueError(
                    f"layer {i}: weights {w.shape} and bias {b.shape} do not chain from "
                    f"{inputs} inputs"
                )
            inputs = w.shape[1]
        if inputs != 1:
            raise ValueError(f"the last layer must give 1 output, not {inputs}")

    def scores(self, features: np.ndarray) -> np.ndarray:
        """``(C, len(FEATURES))`` features in, ``(C,)`` float64 scores out."""
        x = np.asarray(features, dtype=np.float64)
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            x = x @ w + b
            if i < len(self.weights) - 1:
                x = np.maximum(x, 0.0)
        return x[:, 0]


def save_scorer(path: str | os.PathLike[str], scorer: GainScorer) -> None:
    """Write ``scorer`` as JSON (written to a temporary name, then renamed)."""
    path = Path(path)
    payload = {
        "format": FORMAT,
        "features": list(FEATURES),
        "layers": [
            {"weight": w.tolist(), "bias": b.tolist()}
            for w, b in zip(scorer.weights, scorer.biases, strict=True)
        ],
        "info": dict(scorer.info),
    }
    write_text(path, json.dumps(payload, indent=1))


def load_scorer(path: str | os.PathLike[str]) -> GainScorer:
    """Read a scorer file written by :func:`save_scorer`.

    Raises:
        ScorerError: the file is missing, not a scorer, made for other features, or its layers
            do not chain (the message names the file).
    """
    path = Path(path)
    try:
        payload = json.loads(path.read_text())
    except FileNotFoundError:
        raise ScorerError(f"{path}: no such scorer file") from None
    except (OSError, ValueError) as err:
        raise ScorerError(f"{path}: not a readable JSON scorer file ({err})") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ScorerError(f"{path}: not a scorer file (format must be {FORMAT!r})")
    if payload.get("features") != list(FEATURES):
        raise ScorerError(
            f"{path}: trained on features {payload.get('features')}, this version computes "
            f"{list(FEATURES)}; train it again with python -m train.scorer"
        )
    try:
        scorer = GainScorer(
            tuple(np.asarray(layer["weight"], dtype=np.float64) for layer in payload["layers"]),
            tuple(np.asarray(layer["bias"], dtype=np.float64) for layer in payload["layers"]),
            payload.get("info", {}),
        )
    except (KeyError, TypeError, ValueError) as err:
        raise ScorerError(f"{path}: unusable layers ({err})") from None
    if not all(np.isfinite(a).all() for a in (*scorer.weights, *scorer.biases)):
        raise ScorerError(f"{path}: its layers hold NaN or infinite values")
    return scorer
