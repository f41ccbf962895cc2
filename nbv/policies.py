"""View-selection methods behind one interface: ``policy(state: EpisodeState) -> view | [views]``.

* :class:`RandomPolicy`: a seeded random unvisited view.
* :class:`OraclePolicy`: the unvisited view with the largest true gain (coverage or VIG); it reads
  the ground truth, so it is the upper reference, not a method.
* :class:`NetworkPolicy`: a trained PCNBV / PCNBV-sph checkpoint; visited views are masked.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.episodes import EpisodeState
from nbv.samples import farthest_points
from nbv.scores import coverage_gains, vig_gains
from nbv.sph import signature


@dataclass
class RandomPolicy:
    """A uniformly random unvisited view, from an explicit generator."""

    rng: np.random.Generator

    def __call__(self, state: EpisodeState) -> int:
        return int(self.rng.choice(np.flatnonzero(~state.view_state)))


@dataclass
class OraclePolicy:
    """Greedy by the true gain of ``score`` (``coverage`` or ``vig``), ties to the lowest index."""

    score: str = "coverage"

    def __call__(self, state: EpisodeState) -> int:
        model, view = state.model, state.model.views[state.viewspace]
        if self.score == "coverage":
            gains = coverage_gains(view.coverage, state.view_state, len(model.gt_points))
        else:
            gains = vig_gains(view.view_hulls(), state.view_state, model.gt_hull_volume)
        return int(np.argmax(np.where(state.view_state, -np.inf, gains)))


@dataclass
class NetworkPolicy:
    """A PCNBV network: the accumulated cloud (farthest point sampled to ``n_points``) or its
    spherical signature (``input == "signature"``, degree ``lmax``) and the view state in, the
    best unvisited view of its predicted gains out.

    ``timings`` collects seconds per decision: ``sampling`` (or ``signature``) and ``network``.
    """

    model: object  # nbv.net.PCNBV, kept untyped so that importing this module needs no torch
    input: str = "points"
    n_points: int = 1024
    lmax: int = 3
    timings: dict[str, list[float]] = field(default_factory=dict)

    @classmethod
    def from_checkpoint(cls, path: str | Path, n_views: int | None = None) -> NetworkPolicy:
        """Load a training checkpoint (``best.pt``); its ``extra`` says the input kind."""
        from nbv.net import load_checkpoint

        net, extra = load_checkpoint(path, n_views=n_views)
        return cls(
            net,
            input=str(extra.get("input", "points")),
            n_points=int(extra.get("eval_points", 1024)),
            lmax=int(extra.get("lmax", 3)),
        )

    def features(self, cloud: np.ndarray) -> np.ndarray:
        """The network input for a cloud: (n_points, 3) or the (4 (lmax+1)^2, 3) signature."""
        if self.input == "signature":
            return signature(cloud, self.lmax)
        return farthest_points(cloud, self.n_points)

    def __call__(self, state: EpisodeState) -> int:
        import time

        import torch

        from nbv.net import masked_argmax

        t0 = time.perf_counter()
        points = self.features(state.cloud())
        t1 = time.perf_counter()
        with torch.no_grad():
            x = torch.from_numpy(np.ascontiguousarray(points, dtype=np.float32))[None]
            s = torch.from_numpy(state.view_state)[None]
            scores = self.model(x, s.float())
            choice = int(masked_argmax(scores, s)[0])
        t2 = time.perf_counter()
        key = "signature" if self.input == "signature" else "sampling"
        self.timings.setdefault(key, []).append(t1 - t0)
        self.timings.setdefault("network", []).append(t2 - t1)
        return choice
