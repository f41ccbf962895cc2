"""The reference methods: a seeded random view, the geometry-free spread rule (its ties broken
by a seeded generator), and the oracle (greedy by the true gain)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from nbv.geometry.viewspace import angular_distances, spread_picks, unit_directions
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import record_time
from nbv.utils.selection import masked_argmax


@dataclass
class RandomPolicy:
    """A uniformly random unvisited view, from an explicit generator."""

    rng: np.random.Generator
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    last_gains: list[float] = field(default_factory=list)

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) uniform random scores from the generator: the ranking of no information."""
        return self.rng.random(len(state.view_state))

    def __call__(self, state: EpisodeState) -> int:
        return int(self.rng.choice(np.flatnonzero(~state.view_state)))


@dataclass
class SpreadPolicy:
    """The unvisited view farthest in angle from every visited view (seen from the origin).

    It reads only the camera positions: no cloud, no ground truth. Views tied for the farthest
    (:func:`nbv.geometry.viewspace.spread_picks`: cosines within ``TIE_TOLERANCE``) are chosen
    among uniformly with ``rng``; without one, the lowest index wins (the deterministic
    *lowest-index* variant, biased towards the first view of each ring on a viewspace of
    rings). The baseline a geometric method has to beat: on PC-NBV's viewspace it explains most
    of what covering an object takes.

    Attributes:
        rng: the generator of the tie-break; None for the lowest index.
        counts: ``decisions`` made, and ``ties``: those where two or more views tied.
    """

    rng: np.random.Generator | None = None
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=lambda: {"decisions": 0, "ties": 0})
    last_gains: list[float] = field(default_factory=list)

    @staticmethod
    def _directions(state: EpisodeState) -> np.ndarray:
        return unit_directions(state.views.poses[:, :3, 3])

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) degrees from each view to its nearest visited view (what the rule maximises)."""
        d = self._directions(state)
        return angular_distances(d, d[state.view_state]).min(axis=1)

    def __call__(self, state: EpisodeState) -> int:
        picks = spread_picks(self._directions(state), state.view_state, 1, self.rng)
        self.counts["decisions"] += 1
        self.counts["ties"] += picks.ties
        return picks.views[0]


@dataclass
class OraclePolicy:
    """Greedy by the true gain of ``score`` (``coverage`` or ``vig``), ties to the lowest index.
    The one policy given the ground truth (``EpisodeState.true_gains``)."""

    reads_ground_truth: ClassVar[bool] = True

    score: str = "coverage"
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    last_gains: list[float] = field(default_factory=list)

    def __call__(self, state: EpisodeState) -> int:
        t0 = time.perf_counter()
        if state.true_gains is None:
            raise ValueError("the oracle needs the ground truth; the episode gave none")
        gains = state.true_gains(self.score, state.view_state)
        choice = masked_argmax(gains, state.view_state)
        record_time(self.timings, "gains", time.perf_counter() - t0)
        return choice
