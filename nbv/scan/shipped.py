"""The weights the package ships, given to the registry's methods: what a network method runs
(a checkpoint, else the shipped weights), and the shipped completion network and learned score
that a run's :class:`~nbv.policies.method.MethodContext` carries.

The policies never read the package's files themselves (their contract forbids
:mod:`nbv.assets`); the commands above them resolve the weights here.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from nbv.assets.weights import SHIPPED_SCORER, shipped_weights
from nbv.infogain.gain_scorer import GainScorer, load_scorer
from nbv.policies.method import MethodContext
from nbv.policies.registry import METHODS

log = logging.getLogger(__name__)

#: The shipped weights' name of the completion network (``python -m train.completion``).
COMPLETION_WEIGHTS = "completion"


def resolve_weights(name: str, checkpoint: str | Path | None) -> Path:
    """The weights network method ``name`` runs: ``checkpoint`` when it exists, else the weights
    the package ships for it (logged: which one, and why).

    Raises:
        ValueError: not a network method, or no checkpoint there and none shipped.
    """
    if METHODS[name].network_input is None:
        raise ValueError(f"method {name!r} runs no network")
    if checkpoint is not None and Path(checkpoint).exists():
        return Path(checkpoint)
    shipped = shipped_weights(name)
    if shipped is None:
        raise ValueError(
            f"method={name} needs trained weights: checkpoint=<best.pt> (none at {checkpoint})"
        )
    log.info("%s: no checkpoint at %s; using the shipped weights %s", name, checkpoint, shipped)
    return shipped


def shipped_scorer() -> GainScorer:
    """The learned score of ``ig_learned`` the package ships."""
    return load_scorer(SHIPPED_SCORER)


class ShippedCompletion:
    """The completion network the package ships, loaded on its first call (a run that builds no
    completion planner never loads torch's network) and kept: (N, 3) -> (M, 3) points."""

    def __init__(self) -> None:
        self._completer = None

    def __call__(self, cloud: np.ndarray) -> np.ndarray:
        """The completion of ``cloud`` (N, 3) float: (M, 3) points on the whole surface.

        Raises:
            ValueError: the package ships no completion network.
        """
        return self.completer()(cloud)

    def completer(self):
        """The loaded :class:`nbv.models.completion_inference.Completer`."""
        if self._completer is None:
            # Imported here: torch is heavy, and settings and listings read this module without.
            from nbv.models.completion_inference import Completer

            path = shipped_weights(COMPLETION_WEIGHTS)
            if path is None:
                raise ValueError(f"no completion network shipped ({COMPLETION_WEIGHTS}.pt)")
            self._completer = Completer.from_checkpoint(path)
        return self._completer


def with_shipped(ctx: MethodContext, methods: Iterable[str] | None = None) -> MethodContext:
    """``ctx`` with the shipped learned score and completion network where it has none: the
    score read when one of ``methods`` (None: any method) ranks with it, the network loaded on
    the completion's first call."""
    scored = methods is None or any(METHODS[m].learned_score for m in methods)
    scorer = ctx.scorer if ctx.scorer is not None or not scored else shipped_scorer()
    completion = ctx.completion if ctx.completion is not None else ShippedCompletion()
    return dataclasses.replace(ctx, scorer=scorer, completion=completion)
