"""The reference methods: a seeded random view and the oracle (greedy by the true gain)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from nbv.dataset.records import score_functions
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import record_time
from nbv.utils.selection import masked_argmax


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
        gains, _ = score_functions(state.model, self.score, state.viewspace)
        choice = masked_argmax(gains(state.view_state), state.view_state)
        record_time(self.timings, "gains", time.perf_counter() - t0)
        return choice
