"""The convex-hull plan while it covers, then volumetric information gain.

hull_sco plans from the start view's cloud; once its greedy set cover has covered the hull, the
rest of its plan is fill (zero-gain picks spread over the viewspace). This policy takes the plan's
covering picks only, then lets :class:`nbv.policies.infogain.InfoGainPolicy` choose each
later view on the occupancy map of everything captured.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from nbv.policies.episode import EpisodeState
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.setcover import SetCoverPolicy


@dataclass
class HullThenGainPolicy:
    """hull_sco's covering picks, then information gain (see the module docstring)."""

    hull: SetCoverPolicy
    gain: InfoGainPolicy
    planned: bool = field(default=False, init=False)

    @property
    def timings(self) -> dict[str, list[float]]:
        return {**self.hull.timings, **self.gain.timings}

    @property
    def notes(self) -> list[str]:
        return self.hull.notes + self.gain.notes

    @property
    def counts(self) -> dict[str, int]:
        return {k: self.hull.counts[k] + self.gain.counts[k] for k in ("planned", "zero_gain")}

    @property
    def last_gains(self) -> list[float]:
        """None predicted: its picks mix two planners' units."""
        return []

    def __call__(self, state: EpisodeState) -> int | list[int]:
        if not self.planned:
            self.planned = True
            plan = self.hull(state)
            covering = [v for v, g in zip(plan, self.hull.last_gains, strict=True) if g > 0]
            # The fill is not taken: it is not counted as the plan's either.
            self.hull.counts["planned"] = len(covering)
            self.hull.counts["zero_gain"] = 0
            if covering:
                return covering
        return self.gain(state)
