"""The next view from a folder of captures (``python -m nbv.plan captures=...``), or a one-shot
planner's whole remaining plan.

The captures are read and checked (:mod:`nbv.plan.captures`), the object is placed (the
``object`` settings, else ``views.json``'s, else estimated from the points), each capture is
matched to the viewspace direction it was taken from (within ``match_degrees``, seen from the
object's centre) or joins the candidates as an extra visited view, and the registry's policy is
called once on the captured state (:func:`nbv.policies.episode.captured_state`).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.geometry.viewspace import angular_distances
from nbv.plan.captures import Capture, CaptureError, check_views_see, estimate_object, read_captures
from nbv.plan.config import PlanSettings
from nbv.plan.frame import ObjectFrame, candidate_poses, object_frame
from nbv.plan.method import method_context, policy_rng, predicted_gains
from nbv.plan.result import VIEWSPACE, PlanResult
from nbv.policies.episode import captured_state, stage_seconds
from nbv.policies.registry import METHODS, NETWORK_INPUTS
from nbv.utils.seeding import named_rng

log = logging.getLogger(__name__)


def _subsample(points: np.ndarray, keep: int, rng: np.random.Generator) -> np.ndarray:
    """A sorted random ``keep`` of the points (all when ``keep`` is 0 or more than there are),
    as the dataset keeps a view's points."""
    if 0 < keep < len(points):
        return points[np.sort(rng.choice(len(points), keep, replace=False))]
    return points


def match_views(captured: np.ndarray, candidates: np.ndarray, degrees: float) -> list[int | None]:
    """The viewspace view each capture was taken from, or None (an extra view).

    Args:
        captured: (C, 3) capture camera centres, normalised frame.
        candidates: (V, 3) candidate camera centres, normalised frame.
        degrees: the largest angle (at the origin) a match may be off.

    Returns:
        For each capture the nearest candidate within ``degrees`` not matched before, or None.
    """
    angles = angular_distances(captured, candidates)
    taken: set[int] = set()
    out: list[int | None] = []
    for row in angles:
        order = [int(v) for v in np.argsort(row, kind="stable") if row[v] <= degrees]
        free = [v for v in order if v not in taken]
        out.append(free[0] if free else None)
        if free:
            taken.add(free[0])
    return out


def load_captures_and_frame(settings: PlanSettings) -> tuple[list[Capture], ObjectFrame, bool]:
    """Read the captures and place the object: the settings' centre and radius, else the
    folder's ``object``, else estimated from the points; every view checked to look at it.

    Returns:
        ``(captures, frame, estimated)``.
    """
    captures, given = read_captures(settings.captures)
    est_center, est_radius = estimate_object(captures)
    obj = settings.object
    center = obj.center or (given["center"] if given else est_center)
    radius = obj.radius or (given["radius"] if given else est_radius)
    estimated = obj.center is None and obj.radius is None and given is None
    if estimated:
        log.info("object estimated from the captures: centre %s, radius %.4g (a lower bound: "
                 "give object.center / object.radius when you know them)",
                 np.round(est_center, 4).tolist(), est_radius)  # fmt: skip
    frame = object_frame(settings, center, radius)
    check_views_see(captures, frame.center, frame.radius, settings.camera)
    return captures, frame, estimated


def planner_camera(captures: list[Capture], default: Intrinsics) -> Intrinsics:
    """The camera the planner simulates candidates with: the captures' depth camera when every
    capture is a depth image taken with the same intrinsics, else ``default`` (the ``camera``
    setting)."""
    cameras = {c.intrinsics for c in captures}
    if len(cameras) == 1 and None not in cameras:
        return cameras.pop()
    return default


def plan_captures(settings: PlanSettings) -> PlanResult:
    """The next view (or a one-shot planner's remaining plan) from a folder of captures."""
    captures, frame, estimated = load_captures_and_frame(settings)
    camera = planner_camera(captures, settings.camera)
    log.info("planner camera: %s", camera)
    candidates = candidate_poses(settings.viewspace.directions(), frame, settings.viewspace.radius)
    n = len(candidates)
    captured_poses = frame.poses_to_normalised(np.stack([c.pose for c in captures]))
    matched = match_views(captured_poses[:, :3, 3], candidates[:, :3, 3], settings.match_degrees)
    extras = [i for i, m in enumerate(matched) if m is None]
    if (
        extras
        and settings.method in NETWORK_INPUTS
        and NETWORK_INPUTS[settings.method] != "directions"
    ):
        raise CaptureError(
            f"{captures[extras[0]].file}: no viewspace view within {settings.match_degrees} "
            f"degrees, and {settings.method} scores only the views of its viewspace"
        )
    index = [m if m is not None else n + extras.index(i) for i, m in enumerate(matched)]
    if len(captures) >= settings.n_views:
        raise ValueError(
            f"n_views={settings.n_views}: the captures already hold {len(captures)} views; raise "
            "n_views to plan more"
        )
    poses = np.concatenate([candidates, captured_poses[extras]])
    parts = [np.zeros((0, 3), np.float32)] * len(poses)
    for i, c in enumerate(captures):
        rng = named_rng(settings.seed, "plan", "capture", i)
        pts = _subsample(frame.points_to_normalised(c.points), settings.points_per_view, rng)
        parts[index[i]] = pts.astype(np.float32)
        poses[index[i]] = captured_poses[i]
    state = captured_state(poses, parts, index, settings.points_per_view, VIEWSPACE)
    state.model.source_path = str(settings.captures)
    ctx = method_context(settings, camera, n)
    policy = METHODS[settings.method].build(ctx, policy_rng(settings.seed, settings.method))
    t0 = time.perf_counter()
    choice = policy(state)
    seconds = time.perf_counter() - t0
    chosen = [int(v) for v in (choice if isinstance(choice, list | tuple) else [choice])]
    gains, unit = predicted_gains(policy, chosen)
    files = [
        {"file": str(c.file), "view": int(m) if m is not None else None, "points": len(c.points)}
        for c, m in zip(captures, matched, strict=True)
    ]
    notes = list(policy.notes)
    if extras:
        notes.append(f"{len(extras)} captures off the viewspace joined the plan as extra views")
    return PlanResult(
        frame=frame, model=state.model, n_candidates=n, visited=index, chosen=chosen, gains=gains,
        gain_unit=unit, decisions=[seconds], stages=stage_seconds(policy),
        captured_files=files, notes=notes, frame_estimated=estimated, camera=camera,
    )  # fmt: skip
