"""The two-stage planner of "Spherical Harmonics for Robust Next-best-view Estimation": a network
trained on VIG picks the first views, then the convex-hull set cover plans the rest.

VIG (volumetric information gain) is the hull volume of the captured points over the object's.
A network trained to predict it picks views one at a time after the start view, so that the
partial cloud's convex hull grows towards the object's; then the hull of the whole accumulated
cloud is planned once by the one-shot set cover
(:meth:`~nbv.policies.setcover.SetCoverPolicy.plan_rest`), and its plan gives the remaining views.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from nbv.policies.episode import EpisodeState
from nbv.policies.lockstep import NetworkRequest
from nbv.policies.network import NetworkPolicy
from nbv.policies.setcover import SetCoverPolicy


@dataclass
class NetworkThenHullPolicy:
    """A network's picks for the first ``network_views`` decisions, then one set-cover plan.

    While the episode holds at most ``network_views`` views (the start view counts) the network
    chooses one view a call, as :class:`NetworkPolicy` does; after that the set cover plans every
    view left on the hull of ``state.cloud()`` (all captured views' points), the captured views
    excluded, and the episode takes the plan in order. Which stage a call is in follows from the
    state alone. ``network_views = 0`` is the one-shot planner itself.

    The default of ``network_views`` (``setcover.network_views``,
    :class:`~nbv.setcover.settings.SetCoverSettings`) is 2: the paper's Fig. 13 shows VIG nearly
    saturating after 2-3 views, and each network view is one view fewer for the set cover's plan.

    Attributes:
        network: the episode's own network policy (a ``fresh()`` copy of a loaded VIG network).
        hull: the episode's own one-shot planner (its ``probes`` are not used).
        network_views: decisions the network makes after the start view, >= 0.
    """

    network: NetworkPolicy
    hull: SetCoverPolicy
    network_views: int = 2
    #: The last decision was the set cover's plan (its ``last_gains`` are then the plan's).
    planned: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        if self.network_views < 0:
            raise ValueError(f"network_views={self.network_views}: must be >= 0")

    @property
    def timings(self) -> dict[str, list[float]]:
        """Both stages' seconds per decision; a stage both have (``signature`` of a signature
        network before a plan on the signature's hull) holds the network's, then the plan's."""
        net, hull = self.network.timings, self.hull.timings
        return {k: net.get(k, []) + hull.get(k, []) for k in {**net, **hull}}

    @property
    def notes(self) -> list[str]:
        return self.network.notes + self.hull.notes

    @property
    def counts(self) -> dict[str, int]:
        """The set cover's ``planned`` and ``zero_gain`` picks (the network's are not plans)."""
        return self.hull.counts

    @property
    def last_gains(self) -> list[float]:
        """The plan's hull samples newly covered by each view after the plan; none after a
        network's pick (it predicts scores, not a gain in a unit)."""
        return list(self.hull.last_gains) if self.planned else []

    @property
    def gain_unit(self) -> str:
        return self.hull.gain_unit

    def network_turn(self, state: EpisodeState) -> bool:
        """Whether the network picks the next view in ``state``: at most ``network_views``
        views are captured."""
        return len(state.order) <= self.network_views

    def request(self, state: EpisodeState) -> NetworkRequest | None:
        """The network's batched request while it picks; None when the plan is due (the
        policy is then called: :func:`nbv.policies.lockstep.run_lockstep`)."""
        if not self.network_turn(state):
            return None
        self.planned = False
        return self.network.request(state)

    def __call__(self, state: EpisodeState) -> int | list[int]:
        self.planned = not self.network_turn(state)
        if not self.planned:
            return self.network(state)
        return self.hull.plan_rest(state, state.cloud())
