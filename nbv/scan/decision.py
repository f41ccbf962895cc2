"""The warm part of a plan from captures: the object placed, the candidates limited and the
policy built once, then views added one at a time and decisions made on them
(:class:`Decider`; :class:`nbv.scan.planner.Planner` and ``python -m nbv.plan captures=...`` both
run on it).

Each view is matched to the candidate it was taken from as it comes (the nearest free one
within ``match_degrees``, seen from the object's centre), or joins the candidates as an extra
visited view; its points are normalised and subsampled with the generator of its index, and
what its missing pixels mean is kept (:attr:`nbv.geometry.views.CapturedViews.misses`). A decision
builds the state of the views so far (:func:`nbv.policies.episode.captured_state`) and calls the
same policy again: ``ig``'s map takes only the views it has not seen, and the candidates' rays are
traced again only where a pose changed
(:meth:`~nbv.policies.infogain.InfoGainPolicy.retrace_candidates`).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.geometry.clouds import random_subset
from nbv.infogain.occupancy import Misses
from nbv.policies.episode import captured_state, stage_seconds
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.registry import METHODS, NETWORK_INPUTS
from nbv.scan.capture import Capture, CaptureError, check_views_see
from nbv.scan.frame import ObjectFrame
from nbv.scan.method import policy_rng, predicted_gains, scan_context
from nbv.scan.object_estimate import Plane
from nbv.scan.placement import (
    limited_candidates,
    match_views,
    place_object,
    planner_camera,
    sensed_misses,
    support_of,
)
from nbv.scan.result import PlanResult
from nbv.scan.settings import ScanSettings
from nbv.utils.seeding import named_rng

log = logging.getLogger(__name__)


def _reads_any_candidates(method: str) -> bool:
    """Whether the method scores any candidate poses (not only its viewspace's views)."""
    return NETWORK_INPUTS.get(method, "directions") == "directions"


class Decider:
    """The object's frame, the candidates and the policy of a plan, and its views so far.

    Args:
        settings: the plan's settings.
        captures: the views to start from (at least one).
        given: ``views.json``'s object, or None.
        restored: a saved planner's placement (:meth:`placement`), or None: placed from the
            settings and the views.
        where: what the views are called in messages (their folder).

    Raises:
        CaptureError: the object cannot be placed, a view does not look at it, the candidate
            limits or an extra view do not suit the method.
    """

    def __init__(
        self,
        settings: ScanSettings,
        captures: list[Capture],
        given: dict | None,
        restored: dict | None = None,
        where: str = "the views",
    ) -> None:
        self.settings = settings
        self.where = where
        if restored is not None:
            obj = restored["frame"]
            self.frame = ObjectFrame(np.asarray(obj["center"], np.float64), float(obj["radius"]),
                                     obj["up"])  # fmt: skip
            self.source = restored.get("source", "planner.json")
            self.estimate = restored.get("estimate")
            self.estimate_warnings = list((self.estimate or {}).get("warnings", []))
            record = restored.get("support")
            support = None if record is None else Plane(
                np.asarray(record["normal"], np.float64), float(record["offset"]),
                int(record["points"]))  # fmt: skip
            check_views_see(captures, self.frame.center, self.frame.radius, settings.camera)
        else:
            self.frame, self.source, found = place_object(settings, captures, given, where)
            self.estimate = None if found is None else found.record()
            self.estimate_warnings = [] if found is None else list(found.warnings)
            support = support_of(settings, captures, self.frame, found)
        self.support = support
        candidates, self.kept, self.limits = limited_candidates(
            settings, self.frame, support, where
        )
        if (
            self.limits is not None
            and self.limits["dropped"]
            and not _reads_any_candidates(settings.method)
        ):
            raise CaptureError(
                f"{where}: the candidate limits drop {self.limits['dropped']} views, "
                f"and {settings.method} scores only the views of its whole viewspace; use a "
                "method that reads any candidates, or no candidates.* limits"
            )
        self.n = len(candidates)
        self.poses = candidates.copy()
        self.parts: list[np.ndarray] = [np.zeros((0, 3), np.float32)] * self.n
        self.misses: list[Misses | None] = [None] * self.n
        self.captures: list[Capture] = []
        self.index: list[int] = []
        self.matched: list[int | None] = []
        self._taken: set[int] = set()
        self.policy = None
        self.camera: Intrinsics | None = None
        self._traced_poses: np.ndarray | None = None
        self._last: tuple[int, PlanResult] | None = None
        for c in captures:
            self.add(c)

    def add(self, capture: Capture) -> None:
        """Match a view to its candidate (or append it as an extra one) and keep its points."""
        settings, frame = self.settings, self.frame
        i = len(self.captures)
        pose = frame.poses_to_normalised(capture.pose)
        (m,) = match_views(pose[None, :3, 3], self.poses[: self.n, :3, 3], settings.match_degrees,
                           self._taken)  # fmt: skip
        if m is None and not _reads_any_candidates(settings.method):
            raise CaptureError(
                f"{capture.file}: no viewspace view within {settings.match_degrees} degrees, and "
                f"{settings.method} scores only the views of its viewspace"
            )
        if m is None:
            index = len(self.poses)
            self.poses = np.concatenate([self.poses, pose[None]])
            self.parts.append(np.zeros((0, 3), np.float32))
            self.misses.append(None)
        else:
            index = m
            self.poses[index] = pose
        rng = named_rng(settings.seed, "plan", "capture", i)
        # Subsampled first (the draw reads only the count): a 640 x 480 view's 300k points are
        # not all normalised to keep 2048 of them.
        points = frame.points_to_normalised(random_subset(capture.points, settings.points_per_view,
                                                       rng))  # fmt: skip
        self.parts[index] = points.astype(np.float32)
        (self.misses[index],) = sensed_misses([capture], frame)
        self.captures.append(capture)
        self.index.append(index)
        self.matched.append(m)

    def _policy(self):
        """The method's policy, built once for the planner's camera (again if that changes: a
        point cloud view after depth views of one camera)."""
        camera = planner_camera(self.captures, self.settings.camera)
        if self.policy is None or camera != self.camera:
            if self.policy is not None:
                log.info("planner camera changed to %s: the policy is built again", camera)
            self.camera = camera
            log.info("planner camera: %s", camera)
            ctx = scan_context(self.settings, camera, self.n)
            self.policy = METHODS[self.settings.method].build(
                ctx, policy_rng(self.settings.seed, self.settings.method)
            )
            self._traced_poses = None
        return self.policy

    def decide(self) -> PlanResult:
        """The policy's decision on the views so far, as ``python -m nbv.plan`` reports it
        (asked again without a new view: the same decision, not a new draw).

        Raises:
            ValueError: the views already fill ``n_views``.
        """
        settings = self.settings
        if self._last is not None and self._last[0] == len(self.captures):
            return self._last[1]  # no view since: the same decision (a policy may draw)
        if len(self.captures) >= settings.n_views:
            raise ValueError(
                f"n_views={settings.n_views}: the captures already hold {len(self.captures)} "
                "views; raise n_views to plan more"
            )
        policy = self._policy()
        # A sensor's views: what a missing pixel means is the captures' declaration, not the
        # dataset's "background is free" (points subsampled create no misses either).
        state = captured_state(self.poses, self.parts, self.index, settings.points_per_view,
                               self.misses)  # fmt: skip
        if isinstance(policy, InfoGainPolicy) and self._traced_poses is not None:
            policy.retrace_candidates(self.poses, self._traced_poses)
        t0 = time.perf_counter()
        choice = policy(state)
        seconds = time.perf_counter() - t0
        self._traced_poses = self.poses.copy()
        chosen = [int(v) for v in (choice if isinstance(choice, list | tuple) else [choice])]
        gains, unit = predicted_gains(policy, chosen)
        result = PlanResult(
            frame=self.frame, views=state.views, n_candidates=self.n, visited=list(self.index),
            chosen=chosen, gains=gains, gain_unit=unit, decisions=[seconds],
            stages=stage_seconds(policy), captured_files=self._files(), notes=self._notes(),
            frame_estimated=self.source == "estimated", camera=self.camera,
            object_source=self.source, estimate=self.estimate, candidate_limits=self.limits,
        )  # fmt: skip
        self._last = (len(self.captures), result)
        return result

    def _files(self) -> list[dict]:
        return [
            {"file": str(c.file), "view": int(m) if m is not None else None,
             "points": len(c.points), "no_return": c.no_return, "max_range": c.max_range}
            for c, m in zip(self.captures, self.matched, strict=True)
        ]  # fmt: skip

    def _notes(self) -> list[str]:
        notes = list(self.policy.notes)
        extras = sum(m is None for m in self.matched)
        if extras:
            notes.append(f"{extras} captures off the viewspace joined the plan as extra views")
        notes.extend(self.estimate_warnings)
        if self.limits is not None and self.limits["dropped"]:
            notes.append(
                f"{self.limits['dropped']} of {self.limits['dropped'] + self.n} candidates dropped "
                "by candidates.* (plan indices are of the kept ones: candidate_limits.kept_views "
                "maps them)"
            )
        return notes

    def placement(self) -> dict:
        """What :class:`nbv.scan.planner.Planner` saves to be placed again the same way."""
        return {
            "frame": {"center": self.frame.center.tolist(), "radius": self.frame.radius,
                      "up": self.frame.up},
            "source": self.source,
            "estimate": self.estimate,
            "support": None if self.support is None else self.support.record(),
        }  # fmt: skip
