"""The completion network's checkpoints, and completing a captured cloud with one.

A checkpoint is a torch file of :func:`nbv.models.checkpoints.write_payload` with its own format
tag: the :class:`~nbv.models.completion.CompletionConfig`, the weights and ``extra`` (the
training settings, the epoch, its validation Chamfer distance).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from nbv.geometry.clouds import farthest_points, fill_in
from nbv.models.checkpoints import CheckpointError, read_payload, write_payload
from nbv.models.completion import CompletionConfig, CompletionNet
from nbv.models.networks import network_class
from nbv.models.precision import autocast, flush_denormals

#: The format tag of a completion checkpoint.
COMPLETION_FORMAT = "nbv.models.completion.CompletionNet"
#: Bumped when the layout changes incompatibly.
COMPLETION_VERSION = 1


def save_completion(
    path: str | os.PathLike[str], model: CompletionNet, extra: Mapping[str, Any]
) -> None:
    """Write ``model`` and ``extra`` (plain types) to ``path`` atomically."""
    write_payload(path, COMPLETION_FORMAT, COMPLETION_VERSION, model, extra)


def load_completion(path: str | os.PathLike[str]) -> tuple[CompletionNet, dict[str, Any]]:
    """The network (eval mode, CPU) and ``extra`` of a checkpoint of :func:`save_completion`.

    Raises:
        CheckpointError: one line naming the file: missing, not a torch file, not a completion
            checkpoint, a bad config, or weights that do not fit it.
    """
    path = Path(path)
    payload = read_payload(path, COMPLETION_FORMAT, COMPLETION_VERSION, "completion")
    try:
        config = CompletionConfig.from_dict(payload["config"])
        model = network_class("completion")(config)
        model.load_state_dict({k: v.float() for k, v in payload["state_dict"].items()}, strict=True)
    except (TypeError, ValueError, RuntimeError) as e:
        reason = " ".join(str(e).split())
        raise CheckpointError(f"checkpoint {path}: config or weights unusable: {reason}") from e
    return model.eval(), dict(payload["extra"])


@dataclass
class Completer:
    """A captured cloud in, the network's predicted surface out.

    Attributes:
        model: the network (eval mode).
        precision: the forward pass's arithmetic (:func:`nbv.models.precision.autocast`).
        fill: the distance from the captured cloud beyond which a predicted point completes
            it (:meth:`complete`): the network's validation CD-L1, its typical error.
    """

    model: CompletionNet
    precision: str = "auto"
    fill: float = 0.0

    @classmethod
    def from_checkpoint(cls, path: str | os.PathLike[str], precision: str = "auto") -> Completer:
        """The completer of a checkpoint (:func:`load_completion`); ``fill`` is the validation
        CD-L1 it records (``extra["val_cd_fine"]``, 0 when absent)."""
        model, extra = load_completion(path)
        return cls(model, precision, float(extra.get("val_cd_fine", 0.0)))

    def complete(self, cloud: np.ndarray) -> np.ndarray:
        """(N, 3) captured points -> the captured cloud and the predicted points farther than
        ``fill`` from it (:func:`nbv.geometry.clouds.fill_in`), float64."""
        return fill_in(cloud, self(cloud), self.fill)

    def __call__(self, cloud: np.ndarray) -> np.ndarray:
        """(N, 3) captured points, N >= 1, the normalised frame -> (n_fine, 3) float32 predicted
        points on the whole surface (the input is farthest-point sampled to ``n_input``)."""
        return self.batch([cloud])[0]

    def batch(self, clouds: list[np.ndarray]) -> np.ndarray:
        """Several clouds at once: (B, n_fine, 3) float32."""
        n = self.model.config.n_input
        x = np.stack([farthest_points(np.asarray(c, dtype=np.float32), n) for c in clouds])
        with torch.no_grad(), flush_denormals(), autocast(self.precision):
            _, fine = self.model(torch.from_numpy(x))
        return fine.float().numpy()


__all__ = ["CheckpointError", "Completer", "load_completion", "save_completion"]
