"""The reference methods: a seeded random view and the oracle (greedy by the true gain)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from nbv.geometry.scores import coverage_gains, vig_gains
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import _record


@dataclass
class RandomPolicy:
    """A uniformly random unvisited view, from an explicit generator."""

    rng: np.random.Generator
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def __call__(self, state: EpisodeState) -> int:
        return int(self.rng.choice(np.flatnonzero(~state.view_state)))


@dataclass
class OraclePolicy:
    """Greedy by the true gain of ``score`` (``coverage`` or ``vig``), ties to the lowest index."""

    score: str = "coverage"
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def __call__(self, state: EpisodeState) -> int:
        t0 = time.perf_counter()
        model, view = state.model, state.model.views[state.viewspace]
        if self.score == "coverage":
            gains = coverage_gains(view.coverage, state.view_state, len(model.gt_points))
        else:
            gains = vig_gains(view.view_hulls(), state.view_state, model.gt_hull_volume)
        choice = int(np.argmax(np.where(state.view_state, -np.inf, gains)))
        _record(self.timings, "gains", time.perf_counter() - t0)
        return choice
