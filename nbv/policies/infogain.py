"""Volumetric information gain: the classical generate-and-test next-best view on an occupancy map.

After every captured view the map (:mod:`nbv.infogain.occupancy`) takes the view's rays, and each
unvisited candidate is scored by casting rays through the map
(:mod:`nbv.infogain.gain`); the best one is taken. The policy reads the captured
views' points and poses and the candidates' poses, nothing else.

A dataset's view (a rendered one) carves free space along the image blocks no stored point falls
in: its background is empty. A depth sensor's views come with ``misses``
(:attr:`nbv.geometry.views.CapturedViews.misses`), which say per view what its missing pixels
mean (:class:`nbv.infogain.occupancy.Misses`); by default nothing, and the map leaves them
unknown.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.geometry.viewspace import angular_distances
from nbv.infogain.gain import candidate_voxels, view_gains
from nbv.infogain.occupancy import OccupancyMap
from nbv.infogain.settings import InfoGainSettings
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import record_time
from nbv.utils.selection import masked_argmax


@dataclass
class InfoGainPolicy:
    """The unvisited view of the highest information gain on the map of the captured views;
    ties to the lowest index. ``counts`` holds its picks (``planned``) and those of zero gain
    (``zero_gain``: the lowest-index fill once no candidate sees anything unknown)."""

    settings: InfoGainSettings
    intrinsics: Intrinsics
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=lambda: {"planned": 0, "zero_gain": 0})
    occupancy: OccupancyMap | None = None
    integrated: list[int] = field(default_factory=list)
    #: Candidate voxels already traced, by viewspace poses and settings: they depend on nothing
    #: else, so the episodes of a run share them (pass the run's dict).
    traced: dict = field(default_factory=dict)
    #: The information gain of the last chosen view (one value).
    last_gains: list[float] = field(default_factory=list)

    @property
    def gain_unit(self) -> str:
        """What ``last_gains`` counts."""
        if self.settings.metric == "area_factor":
            return "information gain (area factor, 0 to 2)"
        return f"information gain ({self.settings.metric} voxels)"

    def update(self, state: EpisodeState) -> None:
        """Insert the captured views not in the map yet."""
        view = state.views
        if self.occupancy is None:
            self.occupancy = OccupancyMap(self.settings.occupancy())
        for v in state.order:
            if v in self.integrated:
                continue
            self.occupancy.apply_view(self._view_voxels(view, v))
            self.integrated.append(v)

    def _view_voxels(self, view, v: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`OccupancyMap.view_voxels` of view ``v``, kept in ``traced`` for the episodes of
        the same views (keyed by the view's points and pose, so a disturbed cloud is traced
        afresh; only the last model's views are kept)."""
        points, pose = view.view_points(v), view.poses[v]
        digest = hashlib.blake2b(points.tobytes(), digest_size=16)
        digest.update(np.asarray(pose).tobytes())
        sensed = view.sensed
        misses = view.misses_of(v) if sensed else None
        if sensed:
            digest.update(b"sensed" + (b"" if misses is None else misses.digest()))
        key = (digest.hexdigest(), self.intrinsics, self.settings.block, self.settings.occupancy())
        kept = self.traced.setdefault("views", {})
        if key not in kept:
            if len(kept) >= 4 * 66:  # about two models' views of both viewspaces
                kept.clear()
            if sensed:
                kept[key] = self.occupancy.sensed_voxels(
                    points, pose, self.intrinsics, self.settings.block, misses
                )
            else:
                kept[key] = self.occupancy.captured_voxels(
                    points, pose, self.intrinsics, self.settings.block
                )
        return kept[key]

    def _traced_key(self, poses: np.ndarray) -> tuple:
        """The ``traced`` key of the candidates' rays from ``poses`` (and what else they
        depend on)."""
        poses = np.asarray(poses, dtype=np.float64)
        return (poses.tobytes(), self.intrinsics, self.settings.columns, self.settings.occupancy())

    def candidate_voxels(self, poses: np.ndarray) -> np.ndarray:
        """(V, R, S) voxels of the rays of every view of ``poses`` (traced once per poses)."""
        key = self._traced_key(poses)
        if key not in self.traced:
            self.traced[key] = candidate_voxels(
                poses, self.intrinsics, self.settings.columns, self.settings.occupancy()
            )
        return self.traced[key]

    def retrace_candidates(self, poses: np.ndarray, previous: np.ndarray) -> None:
        """The warm path of a planner whose candidate poses change a few rows at a time (a
        captured view's own pose replaces its candidate's, an extra view is appended): put the
        rays' voxels of ``poses`` into ``traced``, where :meth:`candidate_voxels` finds them,
        tracing only the rows that differ from ``previous`` (traced before; its entry is
        dropped). Equal to :meth:`candidate_voxels` of ``poses`` up to the width of the -1
        padding, which no gain reads.

        Args:
            poses: (V, 4, 4) the candidates' poses now.
            previous: (W, 4, 4) those of the last decision, W <= V (rows beyond W are new).
        """
        poses = np.asarray(poses, dtype=np.float64)
        previous = np.asarray(previous, dtype=np.float64)
        key = self._traced_key(poses)
        if key in self.traced:
            return
        old = self.traced.pop(self._traced_key(previous), None)
        if old is None or len(previous) > len(poses):
            self.candidate_voxels(poses)
            return
        n = len(previous)
        changed = np.flatnonzero(~np.all(poses[:n] == previous, axis=(1, 2)))
        changed = np.concatenate([changed, np.arange(n, len(poses))])
        if len(changed) == 0:  # equal values in other bytes (a -0.0 for a 0.0)
            self.traced[key] = old
            return
        fresh = candidate_voxels(poses[changed], self.intrinsics, self.settings.columns,
                                 self.settings.occupancy())  # fmt: skip
        out = np.full((len(poses), old.shape[1], max(old.shape[2], fresh.shape[2])), -1,
                      dtype=old.dtype)  # fmt: skip
        out[:n, :, : old.shape[2]] = old
        out[changed] = -1
        out[changed, :, : fresh.shape[2]] = fresh
        self.traced[key] = out

    def _gains(self, state: EpisodeState) -> tuple[np.ndarray, np.ndarray]:
        """``(gains, score)``, each (V,): every unvisited view's information gain (0 for the
        visited ones) on the map of the captured views, and the score it is picked by (the gain,
        or with ``spread_weight`` the normalised gain plus the weighted angle to the nearest
        visited view)."""
        t0 = time.perf_counter()
        self.update(state)
        t1 = time.perf_counter()
        candidates = self.candidate_voxels(state.views.poses)
        gains = np.zeros(len(candidates))
        open_ = np.flatnonzero(~state.view_state)
        gains[open_] = view_gains(
            self.occupancy, candidates[open_], self.settings.metric, self.settings.depth
        )
        score = gains
        if self.settings.spread_weight > 0 and gains.max() > 0:
            positions = state.views.poses[:, :3, 3]
            nearest = angular_distances(positions, positions[state.view_state]).min(axis=1)
            score = gains / gains.max() + self.settings.spread_weight * nearest / 180.0
        record_time(self.timings, "map", t1 - t0)
        record_time(self.timings, "gains", time.perf_counter() - t1)
        return gains, score

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) the scores this policy picks by in ``state`` (0 for visited views)."""
        return self._gains(state)[1]

    def __call__(self, state: EpisodeState) -> int:
        gains, score = self._gains(state)
        choice = masked_argmax(score, state.view_state)
        self.last_gains = [float(gains[choice])]
        self.counts["planned"] += 1
        self.counts["zero_gain"] += int(gains[choice] <= 0)
        return int(choice)
