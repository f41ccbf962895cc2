"""Convex-hull set cover as a policy: one-shot from the start view, or replanned every view."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.geometry.scores import DEFAULT_EPS
from nbv.policies.episode import EPISODE_VIEWS, EpisodeState
from nbv.policies.inputs import NO_SPREAD, cloud_or_origin, has_spread, record_time
from nbv.setcover.hull_sampling import cameras_inside, convex_hull
from nbv.setcover.oneshot import Plan, plan, sph_hull_points
from nbv.setcover.settings import SetCoverSettings

#: Relative thickness given to a cloud whose hull has no volume (see :func:`thicken`).
THICKEN_RTOL = 1e-3


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
class SetCoverPolicy:
    """Convex-hull set cover, one-shot (the paper's Algorithms 2 and 3).

    On the first call, with ``probes == 0``: plan every remaining view from the start view's
    cloud (:func:`nbv.setcover.oneshot.plan`; with ``sph``, on the hull of
    :func:`nbv.setcover.oneshot.sph_hull_points`), excluding the visited views, and return the
    plan; the episode takes it in order. With ``probes = k``: first return ``k`` seeded random
    unvisited views (they count in the episode); on the next call plan from the start view's
    cloud plus ``probe_points`` random points of each probe view (``settings.probe_points``;
    the paper's "three random views with 100 points").

    A cloud whose hull has no volume (a flat object, a view that saw a plane) is planned on
    :func:`thicken`'s slab around it, and a note says so.

    Attributes:
        rng: generator of the probe views, probe points and the hull samples; each plan's
            zero-gain fill breaks its ties with a child of it (:func:`nbv.setcover.oneshot.plan`:
            spawned, so the draws above are those of a plan with a lowest-index fill).
        settings: the planner's settings (:class:`nbv.setcover.settings.SetCoverSettings`):
            hull samples, view simulation, dilation, the signature's degree ``lmax`` and the
            ``probe_points`` of each probe view.
        sph: plan on the hull of the cloud's spherical signature of degree ``settings.lmax``.
        probes: random probe views taken first (0 for none; see above).
        n_views: views in an episode (start view included): the plan fills it.
        intrinsics: the camera of the dataset.
        eps: capture distance: of the ``raycast`` simulation, and of the ``analytic`` one's
            dilation with ``dilate`` (the hull points within ``eps`` of a pixel's point count
            as captured).
    """

    rng: np.random.Generator
    settings: SetCoverSettings = field(default_factory=SetCoverSettings)
    sph: bool = False
    probes: int = 0
    n_views: int = EPISODE_VIEWS
    intrinsics: Intrinsics = field(default_factory=Intrinsics)
    eps: float = DEFAULT_EPS
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: ``planned``: views the planner chose; ``zero_gain``: those among them that newly cover
    #: no hull sample (the greedy's spread-out fill made them, not the planner's score).
    counts: dict[str, int] = field(default_factory=lambda: {"planned": 0, "zero_gain": 0})
    #: The hull samples each view of the last plan newly covers, in plan order.
    last_gains: list[int] = field(default_factory=list)
    #: What ``last_gains`` counts.
    gain_unit: str = "hull samples newly covered"

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
        cloud = np.asarray(cloud_or_origin(cloud), dtype=np.float64)
        t0 = time.perf_counter()
        if self.sph:
            if has_spread(cloud):
                cloud = sph_hull_points(cloud, self.settings.lmax)
            else:
                self.notes.append(NO_SPREAD + "; planned on the cloud itself")
            record_time(self.timings, "signature", time.perf_counter() - t0)

        def run(points: np.ndarray) -> Plan:
            return plan(
                points,
                poses[:, :3, 3],
                n_iter=n_iter,
                exclude=visited,
                rng=self.rng,
                settings=self.settings,
                intrinsics=self.intrinsics,
                eps=self.eps,
                poses=poses,
            )

        self._note_cameras_inside(cloud, poses)
        try:
            result = run(cloud)
        except ValueError as err:
            try:
                convex_hull(cloud)
            except ValueError:
                # The hull fails before any random draw, so the retry sees the same generator.
                self.notes.append(f"flat cloud thickened for the hull: {err}")
                result = run(thicken(cloud))
            else:
                raise
        self.last_gains = [int(g) for g in result.gains]
        self.counts["planned"] += len(result.views)
        self.counts["zero_gain"] += sum(1 for g in result.gains if g <= 0)
        t = result.timings
        record_time(self.timings, "hull", t["hull"] + t["sampling"])
        record_time(self.timings, "simulation", t["simulation"])
        record_time(self.timings, "set_cover", t["sets"] + t["greedy"])
        return result.views

    def _note_cameras_inside(self, cloud: np.ndarray, poses: np.ndarray) -> None:
        """Note the cameras inside the hull planned on: their views cannot be simulated."""
        try:
            inside = np.flatnonzero(cameras_inside(convex_hull(cloud), poses[:, :3, 3]))
        except ValueError:  # a flat hull: no camera is inside it
            return
        if len(inside):
            self.notes.append(
                f"{len(inside)} cameras inside the planning hull (views {inside.tolist()}): the "
                "analytic visibility assumes cameras outside it"
            )

    def _probe_cloud(self, state: EpisodeState) -> np.ndarray:
        """The start view's cloud plus ``probe_points`` random points of each later view."""
        view = state.views
        parts = [view.view_points(state.order[0])]
        for v in state.order[1:]:
            pts = view.view_points(v)
            keep = self.rng.choice(
                len(pts), min(self.settings.probe_points, len(pts)), replace=False
            )
            parts.append(pts[np.sort(keep)])
        return np.concatenate(parts)

    def plan_rest(self, state: EpisodeState, cloud: np.ndarray) -> list[int]:
        """Plan every view the episode has left (``n_views``, at most the viewspace's size, less
        the captured ones) on the hull of ``cloud`` ((N, 3) float, world units), the captured
        views excluded (:meth:`plan_from`)."""
        poses = state.views.poses
        remaining = min(self.n_views, len(poses)) - len(state.order)
        return self.plan_from(cloud, poses, list(state.order), remaining)

    def __call__(self, state: EpisodeState) -> list[int]:
        if self.probes > 0 and len(state.order) == 1:
            free = np.flatnonzero(~state.view_state)
            k = min(self.probes, self.n_views - len(state.order), len(free))
            return [int(v) for v in self.rng.choice(free, k, replace=False)]
        return self.plan_rest(state, self._probe_cloud(state))


@dataclass
class SetCoverReplanPolicy(SetCoverPolicy):
    """Convex-hull set cover rerun after every captured view on the whole accumulated cloud;
    the first view of each plan is taken. (The greedy's first pick does not depend on how many
    views it plans, so each plan is of one view.) ``probes`` is not used."""

    def __call__(self, state: EpisodeState) -> int:
        poses = state.views.poses
        return self.plan_from(state.cloud(), poses, list(state.order), 1)[0]
