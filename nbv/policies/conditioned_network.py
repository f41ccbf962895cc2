"""The viewspace-conditioned network (:mod:`nbv.models.view_conditioned`) as a view-selection
policy.

A network that reads map features (``vcnbv_map``) keeps the occupancy map of ``ig`` beside it
(an :class:`~nbv.policies.volumetric.InformationGainPolicy`, the ``mapper``) and gives it the
captured views; each decision reads the unvisited candidates' features off that map.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.geometry.clouds import farthest_points
from nbv.planning.view_features import unvisited_features
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import cloud_or_origin, record_time
from nbv.policies.volumetric import InformationGainPolicy


def unit_directions(positions: np.ndarray) -> np.ndarray:
    """(V, 3) camera positions -> (V, 3) float32 unit directions from the object's centre."""
    positions = np.asarray(positions, dtype=np.float64)
    return (positions / np.linalg.norm(positions, axis=1, keepdims=True)).astype(np.float32)


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
    mapper: InformationGainPolicy | None = None

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

    def fresh(self, mapper: InformationGainPolicy | None = None) -> ConditionedPolicy:
        """The same network with empty ``timings`` and ``notes``, and ``mapper`` (a fresh map
        for an episode) as its map."""
        return ConditionedPolicy(
            self.model, self.n_points, selected_on=self.selected_on, mapper=mapper
        )

    def map_features(self, state: EpisodeState) -> np.ndarray:
        """(V, F) float32 map features of the episode's views on the mapper's map
        (:func:`~nbv.planning.view_features.unvisited_features`: zeros for the visited ones)."""
        if self.mapper is None:
            raise ValueError(
                "this network reads map features: build its policy with fresh(mapper=...), an "
                "InformationGainPolicy of the map settings it was trained on"
            )
        self.mapper.update(state)
        poses = state.model.views[state.viewspace].poses
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
        ``features`` (V, F): the map features of a network that reads them."""
        import torch

        t0 = time.perf_counter()
        points = farthest_points(cloud_or_origin(cloud), self.n_points)
        t1 = time.perf_counter()
        with torch.inference_mode():
            out = self.model(
                torch.from_numpy(np.ascontiguousarray(points, dtype=np.float32))[None],
                torch.from_numpy(unit_directions(positions))[None],
                torch.from_numpy(np.asarray(view_state, dtype=np.float32))[None],
                None if features is None else torch.from_numpy(features)[None],
            )[0].numpy()
        record_time(self.timings, "sampling", t1 - t0)
        record_time(self.timings, "network", time.perf_counter() - t1)
        return out

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) the scores this policy picks by in ``state`` (:meth:`scores` on the episode's
        cloud, views and, for a network that reads them, map features)."""
        positions = state.model.views[state.viewspace].poses[:, :3, 3]
        features = None
        if self.reads_map:
            t0 = time.perf_counter()
            features = self.map_features(state)
            record_time(self.timings, "map", time.perf_counter() - t0)
        return self.scores(state.cloud(), positions, state.view_state, features)

    def __call__(self, state: EpisodeState) -> int:
        return int(np.argmax(np.where(state.view_state, -np.inf, self.view_scores(state))))
