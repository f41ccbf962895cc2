"""View-selection methods behind one interface: ``policy(state: EpisodeState) -> view | [views]``.

* :class:`RandomPolicy`: a seeded random unvisited view.
* :class:`OraclePolicy`: the unvisited view with the largest true gain (coverage or VIG); it reads
  the ground truth, so it is the upper reference, not a method.
* :class:`NetworkPolicy`: a trained PCNBV / PCNBV-sph checkpoint; visited views are masked.
* :class:`HullSCOPolicy`: convex-hull set cover (the paper's Algorithms 2 and 3), one-shot: on
  its first call it plans every remaining view from the start view's cloud (optionally after
  ``probes`` random probe views, of which only ``probe_points`` points each are used), on the
  cloud's hull or (``sph=True``) on the hull of its spherical signature.
* :class:`HullSCOReplanPolicy`: the same planner, rerun on the whole accumulated cloud after
  every captured view; its plan's first view is taken each time.

Every policy but the oracle reads only what the captured views saw (their stored points, the
view state) and the camera poses, never the ground truth. Each one records the seconds of every
decision in ``timings`` (a dict ``stage -> [seconds per decision]``), stages among
``sampling`` (farthest point sampling), ``signature``, ``network``, ``hull`` (Qhull and points
drawn on the hull), ``simulation`` (which hull points each candidate view sees), ``set_cover``
(bit sets and greedy cover) and ``gains`` (the oracle's true gains). ``notes`` collects what a
policy had to work around (a flat cloud, an empty view), for the report.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv import sco
from nbv.camera import Intrinsics
from nbv.episodes import EPISODE_VIEWS, EpisodeState
from nbv.samples import farthest_points
from nbv.scores import DEFAULT_EPS, coverage_gains, vig_gains
from nbv.sph import signature

#: Relative thickness given to a cloud whose hull has no volume (see :func:`thicken`).
THICKEN_RTOL = 1e-3


def _record(timings: dict[str, list[float]], key: str, seconds: float) -> None:
    timings.setdefault(key, []).append(seconds)


def _cloud_or_origin(cloud: np.ndarray) -> np.ndarray:
    """The cloud, or the origin as its only point when the views saw nothing (an empty view of
    a flat object seen edge-on): every downstream step needs at least one point."""
    return cloud if len(cloud) else np.zeros((1, 3), dtype=np.float32)


_NO_SPREAD = "every point at one place (the views saw nothing): no signature"


def _has_spread(cloud: np.ndarray) -> bool:
    """A radius function needs a point away from the centroid."""
    return bool(len(cloud)) and bool(np.ptp(cloud, axis=0).max() > 0)


def _signature(cloud: np.ndarray, lmax: int, notes: list[str]) -> np.ndarray:
    """The spherical signature, or all zeros (every radius 0) for a cloud without spread."""
    if _has_spread(cloud):
        return signature(cloud, lmax)
    notes.append(_NO_SPREAD + "; zeros used")
    return np.zeros((4 * (lmax + 1) ** 2, 3), dtype=np.float32)


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


@dataclass
class NetworkPolicy:
    """A PCNBV network: the accumulated cloud (farthest point sampled to ``n_points``) or its
    spherical signature (``input == "signature"``, degree ``lmax``) and the view state in, the
    best unvisited view of its predicted gains out.

    ``precision`` is the arithmetic of the forward pass (:data:`nbv.net.PRECISIONS`; ``"auto"``
    is bfloat16 autocast where the CPU runs it natively). ``timings`` collects seconds per
    decision: ``sampling`` (or ``signature``) and ``network``.
    """

    model: object  # nbv.net.PCNBV, kept untyped so that importing this module needs no torch
    input: str = "points"
    n_points: int = 512
    lmax: int = 3
    precision: str = "auto"
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @classmethod
    def from_checkpoint(
        cls, path: str | Path, n_views: int | None = None, precision: str | None = None
    ) -> NetworkPolicy:
        """Load a training checkpoint (``best.pt``); its ``extra`` says the input kind, the
        number of points and (unless ``precision`` is given) the precision it was trained with.

        Raises:
            nbv.net.CheckpointError: the file is missing or unusable (the message names it).
        """
        from nbv.net import for_inference, load_checkpoint

        net, extra = load_checkpoint(path, n_views=n_views)
        precision = precision or str(extra.get("precision", "fp32"))
        return cls(
            for_inference(net, precision),
            input=str(extra.get("input", "points")),
            n_points=int(extra.get("eval_points", 1024)),
            lmax=int(extra.get("lmax", 3)),
            precision=precision,
        )

    def fresh(self) -> NetworkPolicy:
        """The same network with empty ``timings`` and ``notes`` (one per episode)."""
        return NetworkPolicy(self.model, self.input, self.n_points, self.lmax, self.precision)

    def features(self, cloud: np.ndarray) -> np.ndarray:
        """The network input for a cloud: (n_points, 3) or the (4 (lmax+1)^2, 3) signature."""
        cloud = _cloud_or_origin(cloud)
        if self.input == "signature":
            return _signature(cloud, self.lmax, self.notes)
        return farthest_points(cloud, self.n_points)

    def decide(
        self, cloud: np.ndarray, view_state: np.ndarray, visited: np.ndarray | None = None
    ) -> int:
        """The best view of the network's prediction for ``cloud`` and ``view_state``.

        Args:
            cloud: (N, 3) float accumulated cloud, world units.
            view_state: (V,) bool, the state the network is shown.
            visited: (V,) bool, the views that may not be chosen; default ``view_state``. (The
                disturbance checks show the network another state than the true one.)

        Returns:
            The index of the highest-scoring view not in ``visited``.
        """
        import torch

        from nbv.net import autocast, flush_denormals, masked_argmax

        t0 = time.perf_counter()
        points = self.features(cloud)
        t1 = time.perf_counter()
        device = next(self.model.parameters()).device
        with torch.no_grad(), flush_denormals(), autocast(self.precision, device):
            x = torch.from_numpy(np.ascontiguousarray(points, dtype=np.float32))[None]
            s = torch.from_numpy(np.asarray(view_state, dtype=bool))[None]
            scores = self.model(x.to(device), s.float().to(device)).cpu()
            mask = s if visited is None else torch.from_numpy(np.asarray(visited, bool))[None]
            choice = int(masked_argmax(scores, mask)[0])
        t2 = time.perf_counter()
        _record(self.timings, "signature" if self.input == "signature" else "sampling", t1 - t0)
        _record(self.timings, "network", t2 - t1)
        return choice

    def __call__(self, state: EpisodeState) -> int:
        return self.decide(state.cloud(), state.view_state)


def thicken(points: np.ndarray, rtol: float = THICKEN_RTOL) -> np.ndarray:
    """A cloud with volume around a flat (or colinear, or single-point) one.

    Every point is copied six times, shifted by ``+-delta`` along each axis, with ``delta =
    rtol * max(extent, 1)`` (``extent`` = the largest side of the bounding box, cloud units), so
    a flat cloud becomes a slab ``2 delta`` thick whose two sides face the two half-spaces.

    Args:
        points: (N, 3) float, N >= 1.
        rtol: thickness relative to the cloud's extent.

    Returns:
        (6 N, 3) float64.
    """
    pts = np.asarray(points, dtype=np.float64)
    extent = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
    delta = rtol * max(extent, 1.0)
    shifts = np.concatenate([np.eye(3), -np.eye(3)]) * delta
    return (pts[None] + shifts[:, None]).reshape(-1, 3)


@dataclass
class HullSCOPolicy:
    """Convex-hull set cover, one-shot (the paper's Algorithms 2 and 3).

    On the first call, with ``probes == 0``: plan every remaining view from the start view's
    cloud (:func:`nbv.sco.plan`, or :func:`nbv.sco.plan_sph` with ``sph``), excluding the
    visited views, and return the plan; the episode takes it in order. With ``probes = k``:
    first return ``k`` seeded random unvisited views (they count in the episode); on the next
    call plan from the start view's cloud plus ``probe_points`` random points of each probe
    view (the paper's "three random views with 100 points").

    A cloud whose hull has no volume (a flat object, a view that saw a plane) is planned on
    :func:`thicken`'s slab around it, and a note says so.

    Attributes:
        rng: generator of the probe views, probe points and the hull samples.
        sph: plan on the hull of the cloud's spherical signature of degree ``lmax``.
        probes, probe_points: see above.
        n_views: views in an episode (start view included): the plan fills it.
        n_samp: points drawn on the hull.
        method: view simulation, ``analytic`` (fast) or ``raycast`` (see :mod:`nbv.sco`).
        dilate: with ``analytic``, dilate each view's visible hull points by ``eps``
            (:mod:`nbv.dilation`): closer to ``raycast``, but slower (see :mod:`nbv.sco`).
            Off by default.
        intrinsics: the camera of the dataset.
        eps: capture distance: of the ``raycast`` simulation, and of the ``analytic`` one's
            dilation with ``dilate`` (the hull points within ``eps`` of a pixel's point count
            as captured).
    """

    rng: np.random.Generator
    sph: bool = False
    lmax: int = 3
    probes: int = 0
    probe_points: int = 100
    n_views: int = EPISODE_VIEWS
    n_samp: int = 16384
    method: str = "analytic"
    dilate: bool = False
    intrinsics: Intrinsics = field(default_factory=Intrinsics)
    eps: float = DEFAULT_EPS
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def plan_from(
        self, cloud: np.ndarray, poses: np.ndarray, visited: list[int], n_iter: int
    ) -> list[int]:
        """Plan ``n_iter`` views on the hull of ``cloud`` (or its signature's).

        Args:
            cloud: (N, 3) float partial cloud, world units.
            poses: (V, 4, 4) camera-to-world poses of the viewspace.
            visited: views already captured (never chosen; what they see counts as covered).
            n_iter: views to plan.

        Returns:
            The planned views in order.
        """
        cloud = np.asarray(_cloud_or_origin(cloud), dtype=np.float64)
        t0 = time.perf_counter()
        if self.sph:
            if _has_spread(cloud):
                cloud = sco.sph_hull_points(cloud, self.lmax)
            else:
                self.notes.append(_NO_SPREAD + "; planned on the cloud itself")
            _record(self.timings, "signature", time.perf_counter() - t0)

        def run(points: np.ndarray) -> sco.Plan:
            return sco.plan(
                points,
                poses[:, :3, 3],
                n_iter=n_iter,
                exclude=visited,
                n_samp=self.n_samp,
                rng=self.rng,
                method=self.method,
                intrinsics=self.intrinsics,
                eps=self.eps,
                poses=poses,
                dilate=self.dilate,
            )

        try:
            result = run(cloud)
        except ValueError as err:
            try:
                sco.convex_hull(cloud)
            except ValueError:
                # The hull fails before any random draw, so the retry sees the same generator.
                self.notes.append(f"flat cloud thickened for the hull: {err}")
                result = run(thicken(cloud))
            else:
                raise
        t = result.timings
        _record(self.timings, "hull", t["hull"] + t["sampling"])
        _record(self.timings, "simulation", t["simulation"])
        _record(self.timings, "set_cover", t["sets"] + t["greedy"])
        return result.views

    def _probe_cloud(self, state: EpisodeState) -> np.ndarray:
        """The start view's cloud plus ``probe_points`` random points of each later view."""
        view = state.model.views[state.viewspace]
        parts = [view.view_points(state.order[0])]
        for v in state.order[1:]:
            pts = view.view_points(v)
            keep = self.rng.choice(len(pts), min(self.probe_points, len(pts)), replace=False)
            parts.append(pts[np.sort(keep)])
        return np.concatenate(parts)

    def __call__(self, state: EpisodeState) -> list[int]:
        remaining = self.n_views - len(state.order)
        if self.probes > 0 and len(state.order) == 1:
            free = np.flatnonzero(~state.view_state)
            k = min(self.probes, remaining, len(free))
            return [int(v) for v in self.rng.choice(free, k, replace=False)]
        poses = state.model.views[state.viewspace].poses
        remaining = min(remaining, len(poses) - len(state.order))
        return self.plan_from(self._probe_cloud(state), poses, list(state.order), remaining)


@dataclass
class HullSCOReplanPolicy(HullSCOPolicy):
    """Convex-hull set cover rerun after every captured view on the whole accumulated cloud;
    the first view of each plan is taken. (The greedy's first pick does not depend on how many
    views it plans, so each plan is of one view.) ``probes`` is not used."""

    def __call__(self, state: EpisodeState) -> int:
        poses = state.model.views[state.viewspace].poses
        return self.plan_from(state.cloud(), poses, list(state.order), 1)[0]
