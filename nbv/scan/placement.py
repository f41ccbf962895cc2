"""The steps of a plan from captures before the policy, each a function a stateful caller
(:class:`nbv.scan.decision.Decider`) calls on its own: the object placed (:func:`place_object`:
the ``object`` settings, a region of interest, ``views.json``'s, else estimated among its
surroundings by :mod:`nbv.scan.object_estimate`); the candidates a robot cannot reach dropped
(:func:`limited_candidates`, :mod:`nbv.scan.candidates`); each capture matched to the candidate it
was taken from (:func:`match_views`, within ``match_degrees`` seen from the object's centre) or an
extra visited view; what each view's missing pixels mean in the planners' units
(:func:`sensed_misses`); the planner's camera (:func:`planner_camera`).
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.geometry.viewspace import angular_distances
from nbv.geometry.viewspace_generators import up_rotation
from nbv.infogain.occupancy import Misses
from nbv.scan.candidates import declared_plane, limit_candidates
from nbv.scan.capture import Capture, CaptureError, check_views_see
from nbv.scan.frame import ObjectFrame, candidate_poses, object_frame
from nbv.scan.object_estimate import (
    ObjectEstimate,
    Plane,
    estimate_object,
    find_planes,
    thinned,
)
from nbv.scan.settings import ScanSettings

log = logging.getLogger(__name__)


def match_views(
    captured: np.ndarray, candidates: np.ndarray, degrees: float, taken: set[int] | None = None
) -> list[int | None]:
    """The viewspace view each capture was taken from, or None (an extra view).

    Args:
        captured: (C, 3) capture camera centres, normalised frame.
        candidates: (V, 3) candidate camera centres, normalised frame.
        degrees: the largest angle (at the origin) a match may be off.
        taken: candidates matched by earlier captures (updated in place), for a caller that
            matches captures one at a time.

    Returns:
        For each capture the nearest candidate within ``degrees`` not matched before, or None.
    """
    angles = angular_distances(captured, candidates)
    taken = set() if taken is None else taken
    out: list[int | None] = []
    for row in angles:
        order = [int(v) for v in np.argsort(row, kind="stable") if row[v] <= degrees]
        free = [v for v in order if v not in taken]
        out.append(free[0] if free else None)
        if free:
            taken.add(free[0])
    return out


def up_vector(up: str) -> np.ndarray:
    """(3,) the rig's up axis (``viewspace.up``) in the world frame."""
    return up_rotation(up) @ np.array([0.0, 1.0, 0.0])


def place_object(
    settings: ScanSettings, captures: list[Capture], given: dict | None, where: str
) -> tuple[ObjectFrame, str, ObjectEstimate | None]:
    """The object's frame: the ``object`` settings (a sphere, or a region of interest), else the
    folder's ``object``, else estimated (:func:`estimate_object`); every view checked to look at
    it. ``where`` names the views in messages.

    Returns:
        ``(frame, source, estimate)`` (``source`` as :attr:`PlanResult.object_source`; the
        estimate when one ran).

    Raises:
        CaptureError: the estimate found nothing (naming the settings to give), or a view does
            not look at the object.
    """
    obj = settings.object
    estimate = None
    if obj.center is not None and obj.radius is not None:
        source, center, radius = "object settings", obj.center, obj.radius
    elif obj.box_sphere is not None:
        source, (center, radius) = "region of interest", obj.box_sphere
    elif given is not None:
        source, center, radius = "views.json", given["center"], given["radius"]
    else:
        source = "estimated"
        try:
            estimate = estimate_object(
                np.stack([c.pose for c in captures]), [c.points for c in captures],
                up_vector(settings.viewspace.up), obj.estimate, settings.seed,
            )  # fmt: skip
        except ValueError as err:
            raise CaptureError(f"{where}: {err}") from None
        center, radius = estimate.center, estimate.radius
        log.info("object estimated from the captures: centre %s, radius %.4g (%d of %d points; "
                 "%d planes removed, support %s)", np.round(center, 4).tolist(), radius,
                 estimate.counts["object"], estimate.counts["captured"], len(estimate.planes),
                 "found" if estimate.support is not None else "none")  # fmt: skip
        for warning in estimate.warnings:
            log.warning("%s", warning)
    frame = object_frame(settings, np.asarray(center, dtype=np.float64), float(radius))
    check_views_see(captures, frame.center, frame.radius, settings.camera)
    return frame, source, estimate


def support_of(
    settings: ScanSettings,
    captures: list[Capture],
    frame: ObjectFrame,
    estimate: ObjectEstimate | None,
) -> Plane | None:
    """The support's plane the candidate limits read: declared, else the estimate's, else
    (with a limit set) found in the captures below the object's centre; None without one."""
    limits = settings.candidates
    if limits.support is not None:
        return declared_plane(limits.support)
    if estimate is not None:
        return estimate.support_plane
    if not limits.active:
        return None
    reach = float(np.median(np.linalg.norm([c.pose[:3, 3] - frame.center for c in captures],
                                           axis=1)))  # fmt: skip
    est = settings.object.estimate
    # Coarser than the estimate's thinning: a plane needs few points, and RANSAC's time grows
    # with them.
    points = thinned(np.concatenate([c.points for c in captures]), est.voxel or reach / 100)
    cameras = np.stack([c.pose[:3, 3] for c in captures])
    _, planes, support = find_planes(
        points, frame.center, cameras, up_vector(settings.viewspace.up),
        est.plane_distance or reach / 100, est, settings.seed,
    )  # fmt: skip
    return None if support is None else planes[support]


def limited_candidates(
    settings: ScanSettings, frame: ObjectFrame, support: Plane | None, where: str
) -> tuple[np.ndarray, np.ndarray, dict | None]:
    """The candidates a robot can use, normalised poses (``where`` names the views in messages).

    Returns:
        ``(poses, kept, record)``: (K, 4, 4) the kept candidates' poses, (K,) their viewspace
        indices, and :attr:`PlanResult.candidate_limits` (None when nothing limits them).
    """
    candidates = candidate_poses(settings.viewspace.directions(), frame, settings.viewspace.radius)
    if not settings.candidates.active and support is None:
        return candidates, np.arange(len(candidates)), None
    world = frame.poses_to_world(candidates)[:, :3, 3]
    try:
        keep, by_reason = limit_candidates(world, frame.center, settings.candidates, support)
    except ValueError as err:
        raise CaptureError(f"{where}: {err}") from None
    kept = np.flatnonzero(keep)
    record = {
        "dropped": int(len(candidates) - len(kept)),
        "by_reason": by_reason,
        "dropped_views": np.flatnonzero(~keep).tolist(),
        "kept_views": kept.tolist(),
        "support": None if support is None else support.record(),
    }
    log.info("candidates: %d of %d kept, %d dropped (%s)", len(kept), len(candidates),
             record["dropped"], ", ".join(f"{k} {v}" for k, v in by_reason.items() if v)
             or "none")  # fmt: skip
    if len(kept) == 0:
        raise CaptureError(
            f"{where}: the candidate limits (candidates.*) drop all {len(candidates)} candidates"
        )
    return candidates[kept], kept, record


def sensed_misses(captures: list[Capture], frame: ObjectFrame) -> list[Misses | None]:
    """Each capture's :class:`Misses`, its range in the planners' normalised units."""
    out: list[Misses | None] = []
    for c in captures:
        m = c.misses
        if m is not None and m.reach is not None:
            m = dataclasses.replace(m, reach=m.reach * frame.scale)
        out.append(m)
    return out


def planner_camera(captures: list[Capture], default: Intrinsics) -> Intrinsics:
    """The camera the planner simulates candidates with: the captures' depth camera when every
    capture is a depth image taken with the same intrinsics, else ``default`` (the ``camera``
    setting)."""
    cameras = {c.intrinsics for c in captures}
    if len(cameras) == 1 and None not in cameras:
        return cameras.pop()
    return default
