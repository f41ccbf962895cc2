"""A PCNBV network on another viewspace than the one it was trained on, its views matched by
direction.

PCNBV's view state and its predicted gains are indexed by the views of its training viewspace
(PC-NBV's 33). On another viewspace the same indices name other directions, so the plain network
reads a wrong state and scores the wrong views (the paper's claim 2 measures that loss).
:class:`ViewMap` moves both across by direction, with rules fixed before any measurement:

* the state the network is shown: each captured view marks the training view nearest to it;
* each view's score: Shepard's interpolation (weights the inverse square of the angle) of the
  training views' predicted gains over its :data:`NEIGHBOURS` nearest training views. A view in
  a training view's direction takes that view's gain exactly, so on the training viewspace
  itself the map is the identity and the matched network decides as the plain one.

:class:`MatchedNetworkPolicy` is a network policy with that map between it and the episode.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from nbv.geometry.viewspace import angular_distances
from nbv.policies.episode import EpisodeState
from nbv.policies.lockstep import StateRequest
from nbv.policies.network import NetworkPolicy

#: Training views each view's score is interpolated from (a triangle of the sphere around it).
NEIGHBOURS = 3
#: Degrees below which two directions are the same view (the score is copied, not interpolated).
SAME_DEG = 1e-6


@dataclass(frozen=True)
class ViewMap:
    """The views of an episode's viewspace (V) matched with a network's training views (T).

    Attributes:
        n_trained: T, the training views.
        nearest: (V,) int, the training view nearest to each view.
        neighbours: (V, k) int, each view's ``k`` nearest training views.
        weights: (V, k) float64, their interpolation weights (each row sums to 1).
    """

    n_trained: int
    nearest: np.ndarray
    neighbours: np.ndarray
    weights: np.ndarray

    @classmethod
    def between(cls, trained: np.ndarray, views: np.ndarray, k: int = NEIGHBOURS) -> ViewMap:
        """The map from the training views' directions ``trained`` (T, 3) to the episode's
        views' directions ``views`` (V, 3) (any nonzero lengths: only directions count)."""
        k = min(k, len(trained))
        angles = angular_distances(views, trained)
        neighbours = np.argsort(angles, axis=1, kind="stable")[:, :k]
        near = np.take_along_axis(angles, neighbours, axis=1)
        same = near[:, :1] < SAME_DEG
        weights = np.where(same, np.eye(1, k), 1.0 / np.maximum(near, SAME_DEG) ** 2)
        weights = weights / weights.sum(axis=1, keepdims=True)
        return cls(len(trained), neighbours[:, 0].copy(), neighbours, weights)

    def shown(self, view_state: np.ndarray) -> np.ndarray:
        """(T,) bool: the training views shown visited for the episode's (V,) bool state."""
        out = np.zeros(self.n_trained, dtype=bool)
        out[self.nearest[np.asarray(view_state, bool)]] = True
        return out

    def scores(self, trained_scores: np.ndarray) -> np.ndarray:
        """(..., V) float64 scores of the episode's views from the training views' (..., T)."""
        values = np.asarray(trained_scores, dtype=np.float64)[..., self.neighbours]
        return (values * self.weights).sum(axis=-1)


@dataclass
class MatchedNetworkPolicy:
    """A network policy (:class:`~nbv.policies.network.NetworkPolicy`) run on any viewspace
    through a :class:`ViewMap` from its training views' directions ``trained`` (T, 3) to the
    episode's views (the directions of their camera positions from the object's centre, the
    origin). Its timings, notes and ``selected_on`` are the network's; ``maps`` caches one map
    per viewspace (shared by :meth:`fresh` copies: a map is a function of the directions only).
    """

    network: NetworkPolicy
    trained: np.ndarray
    maps: dict[bytes, ViewMap] = field(default_factory=dict)

    def __post_init__(self) -> None:
        outputs = int(self.network.model.config.n_views)
        if outputs != len(self.trained):
            raise ValueError(
                f"the network has {outputs} outputs but its training viewspace {len(self.trained)} "
                "views: a matched network needs the directions it was trained on"
            )

    @property
    def model(self) -> object:
        """The network's model (episodes that share it are batched together)."""
        return self.network.model

    @property
    def timings(self) -> dict[str, list[float]]:
        return self.network.timings

    @property
    def notes(self) -> list[str]:
        return self.network.notes

    @property
    def counts(self) -> dict[str, int]:
        return self.network.counts

    @property
    def last_gains(self) -> list[float]:
        return self.network.last_gains

    @property
    def selected_on(self) -> tuple[str, ...]:
        return self.network.selected_on

    def fresh(self) -> MatchedNetworkPolicy:
        """A copy for one episode: the network's :meth:`~NetworkPolicy.fresh` copy."""
        return MatchedNetworkPolicy(self.network.fresh(), self.trained, self.maps)

    def view_map(self, state: EpisodeState) -> ViewMap:
        """The map to the viewspace of ``state``'s views."""
        views = np.ascontiguousarray(state.views.poses[:, :3, 3])
        key = views.tobytes()
        if key not in self.maps:
            self.maps[key] = ViewMap.between(self.trained, views)
        return self.maps[key]

    def view_scores_many(
        self, states: Sequence[EpisodeState], episodes: Sequence[MatchedNetworkPolicy] | None = None
    ) -> np.ndarray:
        """(K, V) float64 scores of the views of K states of one viewspace's size, from one
        batched forward pass; ``episodes``: the K episodes' own policies (their timings)."""
        maps = [self.view_map(s) for s in states]
        shown = [m.shown(s.view_state) for m, s in zip(maps, states, strict=True)]
        networks = None if episodes is None else [e.network for e in episodes]
        trained = self.network.predict_many([s.cloud() for s in states], shown, networks)
        return np.stack([m.scores(row) for m, row in zip(maps, trained, strict=True)])

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) the scores this policy picks by in ``state``."""
        return self.view_scores_many([state])[0]

    def choose_many(
        self, states: Sequence[EpisodeState], episodes: Sequence[MatchedNetworkPolicy] | None = None
    ) -> list[int]:
        """The best unvisited view of each of K states (ties to the lowest index)."""
        import torch

        from nbv.models.inference import masked_argmax  # refuses NaN scores and a full state

        if not len(states):
            return []
        scores = torch.from_numpy(self.view_scores_many(states, episodes))
        visited = torch.from_numpy(np.stack([np.asarray(s.view_state, bool) for s in states]))
        return [int(v) for v in masked_argmax(scores, visited)]

    def request(self, state: EpisodeState) -> StateRequest:
        """This episode's state, for a batched decision (:mod:`nbv.policies.lockstep`)."""
        return StateRequest(self, state)

    def __call__(self, state: EpisodeState) -> int:
        return self.choose_many([state])[0]
