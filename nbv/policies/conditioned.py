"""The viewspace-conditioned network (:mod:`nbv.models.conditioned`) as a view-selection policy."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.geometry.clouds import farthest_points
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import cloud_or_origin, record_time


def unit_directions(positions: np.ndarray) -> np.ndarray:
    """(V, 3) camera positions -> (V, 3) float32 unit directions from the object's centre."""
    positions = np.asarray(positions, dtype=np.float64)
    return (positions / np.linalg.norm(positions, axis=1, keepdims=True)).astype(np.float32)


@dataclass
class ConditionedPolicy:
    """Scores every unvisited view of the episode's viewspace from its direction, the
    accumulated cloud (farthest point sampled to ``n_points``) and the visited directions;
    takes the best. ``timings``: ``sampling`` and ``network`` seconds per decision.
    ``selected_on``: the models whose episodes chose the checkpoint (never to be scored)."""

    # nbv.models.conditioned.ViewConditionedNet, untyped so that importing needs no torch
    model: object
    n_points: int = 256
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    selected_on: tuple[str, ...] = ()
    input: str = "directions"

    @classmethod
    def from_checkpoint(cls, path: str | Path) -> ConditionedPolicy:
        """Load a checkpoint of :mod:`train.conditioned`.

        Raises:
            nbv.models.checkpoints.CheckpointError: missing or unusable (naming the file).
        """
        from nbv.models.conditioned import load_conditioned

        net, extra = load_conditioned(path)
        return cls(
            net.requires_grad_(False),
            n_points=int(extra.get("eval_points", 256)),
            selected_on=tuple(extra.get("selection_keys", ())),
        )

    def fresh(self) -> ConditionedPolicy:
        """The same network with empty ``timings`` and ``notes``."""
        return ConditionedPolicy(self.model, self.n_points, selected_on=self.selected_on)

    def scores(self, cloud: np.ndarray, positions: np.ndarray, view_state: np.ndarray):
        """(V,) float32 scores of every view (higher is better; visited ones included)."""
        import torch

        t0 = time.perf_counter()
        points = farthest_points(cloud_or_origin(cloud), self.n_points)
        t1 = time.perf_counter()
        with torch.no_grad():
            out = self.model(
                torch.from_numpy(np.ascontiguousarray(points, dtype=np.float32))[None],
                torch.from_numpy(unit_directions(positions))[None],
                torch.from_numpy(np.asarray(view_state, dtype=np.float32))[None],
            )[0].numpy()
        record_time(self.timings, "sampling", t1 - t0)
        record_time(self.timings, "network", time.perf_counter() - t1)
        return out

    def __call__(self, state: EpisodeState) -> int:
        positions = state.model.views[state.viewspace].poses[:, :3, 3]
        scores = self.scores(state.cloud(), positions, state.view_state)
        return int(np.argmax(np.where(state.view_state, -np.inf, scores)))
