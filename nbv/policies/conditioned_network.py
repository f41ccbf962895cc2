"""The viewspace-conditioned network (:mod:`nbv.models.view_conditioned`) as a view-selection
policy.

A network that reads map features (``vcnbv_map``) keeps the occupancy map of ``ig`` beside it
(an :class:`~nbv.policies.infogain.InfoGainPolicy`, the ``mapper``) and gives it the
captured views; each decision reads the unvisited candidates' features off that map.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.geometry.clouds import farthest_points
from nbv.geometry.viewspace import unit_directions
from nbv.infogain.view_features import unvisited_features
from nbv.policies.episode import EpisodeState
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.inputs import cloud_or_origin, record_time
from nbv.policies.lockstep import StateRequest


@dataclass
class ConditionedPolicy:
    """Scores every unvisited view of the episode's viewspace from its direction, the
    accumulated cloud (farthest point sampled to ``n_points``) and the visited directions;
    takes the best. ``timings``: ``sampling``, ``map`` (map features only) and ``network``
    seconds per decision. ``selected_on``: the models whose episodes chose the checkpoint (never
    to be scored). ``mapper``: the occupancy map of a network that reads map features (module
    docstring); ignored by one that does not."""

    # nbv.models.view_conditioned.ViewConditionedNet, untyped so that importing needs no torch
    model: object
    n_points: int = 256
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    last_gains: list[float] = field(default_factory=list)
    selected_on: tuple[str, ...] = ()
    input: str = "directions"
    mapper: InfoGainPolicy | None = None

    @classmethod
    def from_checkpoint(cls, path: str | Path) -> ConditionedPolicy:
        """Load a checkpoint of :mod:`train.conditioned`.

        Raises:
            nbv.models.checkpoints.CheckpointError: missing or unusable (naming the file).
        """
        from nbv.models.view_conditioned import load_conditioned

        net, extra = load_conditioned(path)
        return cls(
            net.requires_grad_(False),
            n_points=int(extra.get("eval_points", 256)),
            selected_on=tuple(extra.get("selection_keys", ())),
        )

    @property
    def reads_map(self) -> bool:
        """The network reads map features (it needs a ``mapper``)."""
        return int(self.model.config.map_features) > 0

    def fresh(self, mapper: InfoGainPolicy | None = None) -> ConditionedPolicy:
        """The same network with empty ``timings`` and ``notes``, and ``mapper`` (a fresh map
        for an episode) as its map."""
        return ConditionedPolicy(
            self.model, self.n_points, selected_on=self.selected_on, mapper=mapper
        )

    def map_features(self, state: EpisodeState) -> np.ndarray:
        """(V, F) float32 map features of the episode's views on the mapper's map
        (:func:`~nbv.infogain.view_features.unvisited_features`: zeros for the visited ones)."""
        if self.mapper is None:
            raise ValueError(
                "this network reads map features: build its policy with fresh(mapper=...), an "
                "InfoGainPolicy of the map settings it was trained on"
            )
        self.mapper.update(state)
        poses = state.views.poses
        voxels = self.mapper.candidate_voxels(poses)
        features = unvisited_features(self.mapper.occupancy, voxels, poses[:, :3, 3], state.order)
        return features.astype(np.float32)

    def scores(
        self,
        cloud: np.ndarray,
        positions: np.ndarray,
        view_state: np.ndarray,
        features: np.ndarray | None = None,
    ) -> np.ndarray:
        """(V,) float32 scores of every view (higher is better; visited ones included);
        ``features`` (V, F): the map features of a network that reads them. The same as
        :meth:`scores_many` of one episode."""
        return self.scores_many([cloud], [positions], [view_state],
                                None if features is None else [features])[0]  # fmt: skip

    def scores_many(
        self,
        clouds: Sequence[np.ndarray],
        positions: Sequence[np.ndarray],
        view_states: Sequence[np.ndarray],
        features: Sequence[np.ndarray] | None = None,
        episodes: Sequence[ConditionedPolicy] | None = None,
    ) -> np.ndarray:
        """(K, V) float32 scores of K episodes in one batched forward pass.

        Each episode's cloud is farthest point sampled alone to ``n_points`` (deterministic; a
        smaller cloud is repeated), so the samples have one size and nothing is padded.

        Args:
            clouds: K (N_k, 3) float accumulated clouds.
            positions: K (V, 3) camera positions of the episodes' viewspaces (one V for all).
            view_states: K (V,) bool.
            features: K (V, F) float32 map features (a network that reads them), else None.
            episodes: the K episodes' own policies (:meth:`fresh` copies of this one) that get
                their ``sampling`` seconds and an equal share of the forward's ``network``
                seconds; None = this one.

        Returns:
            (K, V) float32; row k equals :meth:`scores` of episode k up to the last bits of
            float32 sums.
        """
        import torch

        k = len(clouds)
        episodes = self._episodes(episodes, k)
        if not len(positions) == len(view_states) == k or (
            features is not None and len(features) != k
        ):
            raise ValueError(
                f"{k} clouds, {len(positions)} viewspaces, {len(view_states)} view states"
                + ("" if features is None else f", {len(features)} map features")
                + ": one of each an episode"
            )
        sizes = {len(p) for p in positions}
        if len(sizes) > 1:
            raise ValueError(f"the episodes' viewspaces hold {sorted(sizes)} views: batch one size")
        if not k:
            return np.zeros((0, 0), dtype=np.float32)
        points = []
        for episode, cloud in zip(episodes, clouds, strict=True):
            t0 = time.perf_counter()
            points.append(farthest_points(cloud_or_origin(cloud), self.n_points))
            record_time(episode.timings, "sampling", time.perf_counter() - t0)
        t1 = time.perf_counter()
        with torch.inference_mode():
            out = self.model(
                torch.from_numpy(np.ascontiguousarray(np.stack(points), dtype=np.float32)),
                torch.from_numpy(np.stack([unit_directions(p, np.float32) for p in positions])),
                torch.from_numpy(np.stack([np.asarray(s, dtype=np.float32) for s in view_states])),
                None if features is None else torch.from_numpy(np.stack(features)),
            ).numpy()
        share = (time.perf_counter() - t1) / k
        for episode in episodes:
            record_time(episode.timings, "network", share)
        return out

    def _episodes(
        self, episodes: Sequence[ConditionedPolicy] | None, k: int
    ) -> list[ConditionedPolicy]:
        """The episodes' policies, checked to run this network."""
        if episodes is None:
            if self.reads_map and k > 1:
                raise ValueError(
                    "this network reads each episode's own map: pass the episodes' policies "
                    "(fresh(mapper=...) copies), one an episode"
                )
            return [self] * k
        episodes = list(episodes)
        if len(episodes) != k:
            raise ValueError(f"{k} episodes' inputs but {len(episodes)} episode policies")
        for i, episode in enumerate(episodes):
            if episode.model is not self.model or episode.n_points != self.n_points:
                raise ValueError(
                    f"episode {i}'s policy runs another network or n_points ({episode.n_points}, "
                    f"this one {self.n_points}): batch only the fresh() copies of one policy"
                )
        return episodes

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) the scores this policy picks by in ``state`` (:meth:`scores` on the episode's
        cloud, views and, for a network that reads them, map features)."""
        return self.view_scores_many([state], [self])[0]

    def view_scores_many(
        self, states: Sequence[EpisodeState], episodes: Sequence[ConditionedPolicy] | None = None
    ) -> np.ndarray:
        """(K, V) :meth:`view_scores` of K episodes' states in one batched forward pass;
        ``episodes``: their own policies (for a network that reads map features, each with its
        episode's map: required for more than one state)."""
        episodes = self._episodes(episodes, len(states))
        features = None
        if self.reads_map:
            features = []
            for episode, state in zip(episodes, states, strict=True):
                t0 = time.perf_counter()
                features.append(episode.map_features(state))
                record_time(episode.timings, "map", time.perf_counter() - t0)
        positions = [s.views.poses[:, :3, 3] for s in states]
        return self.scores_many([s.cloud() for s in states], positions,
                                [s.view_state for s in states], features, episodes)  # fmt: skip

    def choose_many(
        self, states: Sequence[EpisodeState], episodes: Sequence[ConditionedPolicy] | None = None
    ) -> list[int]:
        """The next view of K episodes, ``episodes[k](states[k])`` for every k, from one
        batched forward pass (:meth:`view_scores_many`)."""
        scores = self.view_scores_many(states, episodes)
        return [
            int(np.argmax(np.where(s.view_state, -np.inf, row)))
            for s, row in zip(states, scores, strict=True)
        ]

    def request(self, state: EpisodeState) -> StateRequest:
        """This episode's state, for a batched decision
        (:func:`nbv.policies.lockstep.run_lockstep`)."""
        return StateRequest(self, state)

    def __call__(self, state: EpisodeState) -> int:
        return self.choose_many([state], [self])[0]
