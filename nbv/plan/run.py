"""Planning for a user's object: from a mesh (simulated captures, a whole episode) or from a
folder of captures (the next view, or a one-shot planner's whole remaining plan).

Both inputs become what the evaluator's policies read, a :class:`nbv.dataset.records.ModelData`
of one viewspace, in the planners' normalised frame (:mod:`nbv.plan.frame`): the object's centre
at the origin, its radius 0.5, the rig's up axis +y. The policy is the registry's
(:data:`nbv.policies.registry.METHODS`), built with the generator :func:`policy_rng` gives, so a
plan from captures is the evaluator's decision on the same views.

* Mesh: the mesh is normalised as the dataset normalises it, every viewspace view is ray cast
  (:func:`nbv.render.raycast.render_raycast`) and turned into the dataset's view record
  (:func:`nbv.dataset.generate.view_data`), and :func:`nbv.policies.episode.run_episode` plays the
  episode from ``start_view``; coverage by view is measured against ``n_gt`` points sampled on
  the mesh.
* Captures: each capture is matched to the viewspace direction it was taken from (within
  ``match_degrees``, seen from the object's centre) or joins the candidates as an extra visited
  view; the policy is called once on the captured state.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.assets.meshes import Mesh, load_mesh, normalise, sample_surface
from nbv.dataset.generate import view_data
from nbv.dataset.records import ModelData, ViewData
from nbv.geometry.camera import Intrinsics
from nbv.geometry.hull import QhullFailure, hull_volume
from nbv.geometry.viewspace import angular_distances
from nbv.plan.captures import (
    Capture,
    CaptureError,
    check_views_see,
    estimate_object,
    read_captures,
    write_captures,
)
from nbv.plan.config import PlanSettings
from nbv.plan.frame import ObjectFrame, candidate_poses
from nbv.policies.episode import EpisodeState, run_episode
from nbv.policies.registry import METHODS, NETWORK_INPUTS, MethodContext
from nbv.render.raycast import render_raycast
from nbv.utils.seeding import named_rng

log = logging.getLogger(__name__)

#: The viewspace's name in the plan's record.
VIEWSPACE = "plan"


def policy_rng(seed: int, method: str) -> np.random.Generator:
    """The generator a plan's policy is built with (the same for every input)."""
    return named_rng(seed, "plan", method)


@dataclass
class PlanResult:
    """What one plan found, in the planners' normalised frame unless said otherwise.

    Attributes:
        frame: the object's frame (world <-> normalised).
        model: the record the policy read (candidates first, then extra captured views).
        n_candidates: V, the viewspace's views (indices ``0..V-1``).
        visited: the captured views in order (candidate indices; extras ``>= V``).
        chosen: the planned views in order (candidate indices).
        gains: the planner's predicted gain of each chosen view (None when it predicts none),
            and ``gain_unit`` what it counts.
        coverage: mesh input: coverage of the ground truth after each view of the episode.
        decisions: seconds of each policy call; ``stages`` the policy's own timings.
        captured_files: captures input: each capture's file and its view index.
        notes: what the policy or the input had to work around.
        frame_estimated: the object's centre and radius were estimated from the captures.
        camera: the planner's camera (its view simulation, ``ig``'s rays).
    """

    frame: ObjectFrame
    model: ModelData
    n_candidates: int
    visited: list[int]
    chosen: list[int]
    gains: list[float] | None = None
    gain_unit: str = ""
    coverage: list[float] | None = None
    decisions: list[float] = field(default_factory=list)
    stages: dict[str, float] = field(default_factory=dict)
    captured_files: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    frame_estimated: bool = False
    camera: Intrinsics | None = None

    @property
    def cloud(self) -> np.ndarray:
        """(N, 3) float32 accumulated cloud of the visited views, normalised frame."""
        view = self.model.views[VIEWSPACE]
        return np.concatenate([view.view_points(v) for v in self.visited])


def method_context(settings: PlanSettings, camera, n_views: int) -> MethodContext:
    """The registry's context of the plan's method (its network loaded when it has one)."""
    networks = {}
    if settings.method in NETWORK_INPUTS:
        networks[settings.method] = load_network(settings, n_views)
    return MethodContext(
        networks=networks,
        planner=settings.hull,
        intrinsics=camera,
        eps=settings.eps,
        n_views=settings.n_views,
        volumetric=settings.ig,
    )


def load_network(settings: PlanSettings, n_views: int):
    """The network of a network method: ``checkpoint``, else the weights the package ships."""
    from nbv.assets.weights import shipped_weights
    from nbv.models.checkpoints import CheckpointError
    from nbv.policies.conditioned import ConditionedPolicy
    from nbv.policies.network import NetworkPolicy

    path = settings.checkpoint
    if path is None or not Path(path).exists():
        shipped = shipped_weights(settings.method)
        if shipped is None:
            raise ValueError(
                f"method={settings.method} needs trained weights: checkpoint=<best.pt> (none at "
                f"{path})"
            )
        log.info("%s: no checkpoint at %s; using the shipped weights %s", settings.method, path,
                 shipped)  # fmt: skip
        path = shipped
    try:
        if NETWORK_INPUTS[settings.method] == "directions":
            return ConditionedPolicy.from_checkpoint(path)
        return NetworkPolicy.from_checkpoint(path, n_views=n_views)
    except CheckpointError as err:
        raise ValueError(f"checkpoint: {err}") from None


def predicted_gains(policy, state: EpisodeState, chosen: list[int]) -> tuple[list | None, str]:
    """The planner's own predicted gain of each chosen view, and what it counts.

    The convex-hull planners report the hull samples each planned view newly covers; the
    information-gain planner's gains are read off its map after the decision (the unknown
    voxels its rays count). Other methods predict no gain: None.
    """
    if getattr(policy, "last_gains", None) and len(policy.last_gains) == len(chosen):
        return [float(g) for g in policy.last_gains], "hull samples newly covered"
    if getattr(policy, "occupancy", None) is not None and hasattr(policy, "candidate_voxels"):
        from nbv.planning.information_gain import view_gains

        poses = state.model.views[state.viewspace].poses
        voxels = policy.candidate_voxels(poses)[chosen]
        gains = view_gains(policy.occupancy, voxels, policy.settings.metric, policy.settings.depth)
        return [float(g) for g in gains], f"information gain ({policy.settings.metric} voxels)"
    return None, ""


class GainRecorder:
    """A policy that also keeps the planner's predicted gain of every view it picks
    (:func:`predicted_gains`, None where it predicts none) and the seconds of each of its own
    decisions (without the gains' reading)."""

    def __init__(self, policy) -> None:
        self.policy = policy
        self.gains: list[float | None] = []
        self.unit = ""
        self.seconds: list[float] = []

    def __call__(self, state: EpisodeState) -> int | list[int]:
        t0 = time.perf_counter()
        choice = self.policy(state)
        self.seconds.append(time.perf_counter() - t0)
        chosen = [int(v) for v in (choice if isinstance(choice, list | tuple) else [choice])]
        gains, self.unit = predicted_gains(self.policy, state, chosen)
        self.gains += gains if gains is not None else [None] * len(chosen)
        return choice


def _stage_seconds(policy) -> dict[str, float]:
    return {k: float(np.sum(v)) for k, v in getattr(policy, "timings", {}).items()}


def _frame(settings: PlanSettings, center, radius) -> ObjectFrame:
    c = settings.center if settings.center is not None else center
    r = settings.radius if settings.radius is not None else radius
    frame = ObjectFrame(np.asarray(c, dtype=np.float64), float(r), settings.viewspace.up)
    if settings.distance is not None and settings.distance <= frame.radius:
        raise ValueError(
            f"viewspace.radius={settings.distance}: the cameras would sit inside the object's "
            f"sphere (radius {frame.radius:.4g})"
        )
    return frame


def plan_mesh(settings: PlanSettings) -> tuple[PlanResult, np.ndarray]:
    """Play a whole episode on simulated captures of ``settings.mesh``.

    Returns:
        ``(result, depth)``: the plan, and the (V, H, W) float32 depth images of every
        candidate in normalised units (for :func:`save_episode_captures`).
    """
    mesh = load_mesh(settings.mesh)
    _, center, scale = normalise(mesh)
    frame = _frame(settings, center, 0.5 / scale)
    normalised_vertices = frame.points_to_normalised(mesh.vertices)
    poses = candidate_poses(settings.viewspace.directions(), frame, settings.distance)
    rng = named_rng(settings.seed, "plan", "mesh")
    normalised = Mesh(normalised_vertices, mesh.faces, mesh.source_path)
    gt = sample_surface(normalised, settings.n_gt, rng)
    log.info("ray casting %d views of %s", len(poses), settings.mesh)
    depth = render_raycast(normalised.vertices, normalised.faces, poses, settings.camera)
    view = view_data(depth, poses, settings.camera, gt, settings.eps, settings.points_per_view,
                     rng)  # fmt: skip
    try:
        gt_volume = hull_volume(gt)
    except QhullFailure:
        gt_volume = float("nan")
    model = ModelData(
        key=Path(settings.mesh).stem, category="", split="", source="mesh",
        source_path=str(settings.mesh), center=frame.center, scale=frame.scale,
        seed=settings.seed, gt_points=gt, gt_hull_volume=gt_volume, views={VIEWSPACE: view},
    )  # fmt: skip
    ctx = method_context(settings, settings.camera, len(poses))
    policy = METHODS[settings.method].build(ctx, policy_rng(settings.seed, settings.method))
    recorder = GainRecorder(policy)
    episode = run_episode(model, VIEWSPACE, settings.start_view, recorder, settings.n_views)
    gains = recorder.gains[: len(episode.views) - 1]
    return PlanResult(
        frame=frame,
        model=model,
        n_candidates=len(poses),
        visited=[settings.start_view],
        chosen=episode.views[1:],
        gains=None if any(g is None for g in gains) else gains,
        gain_unit=recorder.unit,
        coverage=[float(c) for c in episode.coverage],
        decisions=recorder.seconds,
        stages=_stage_seconds(policy),
        notes=list(getattr(policy, "notes", [])) + episode.notes,
        camera=settings.camera,
    ), depth


def save_episode_captures(settings: PlanSettings, result: PlanResult, depth: np.ndarray) -> Path:
    """Write the episode's first ``save_captures`` views as a capture folder, in world units."""
    folder = settings.captures_out or settings.out_dir / "captures"
    views = (result.visited + result.chosen)[: settings.save_captures]
    poses = result.frame.poses_to_world(result.model.views[VIEWSPACE].poses[views])
    write_captures(folder, depth[views] / result.frame.scale, poses, settings.camera,
                   result.frame.center, result.frame.radius)  # fmt: skip
    return folder


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


def load_capture_frame(settings: PlanSettings) -> tuple[list[Capture], ObjectFrame, bool]:
    """Read the captures and place the object: the settings' centre and radius, else the
    folder's ``object``, else estimated from the points; every view checked to look at it.

    Returns:
        ``(captures, frame, estimated)``.
    """
    captures, given = read_captures(settings.captures)
    est_center, est_radius = estimate_object(captures)
    center = settings.center or (given["center"] if given else est_center)
    radius = settings.radius or (given["radius"] if given else est_radius)
    estimated = settings.center is None and settings.radius is None and given is None
    if estimated:
        log.info("object estimated from the captures: centre %s, radius %.4g (a lower bound: "
                 "give object.center / object.radius when you know them)",
                 np.round(est_center, 4).tolist(), est_radius)  # fmt: skip
    frame = _frame(settings, center, radius)
    check_views_see(captures, frame.center, frame.radius, settings.camera)
    return captures, frame, estimated


def capture_state(
    poses: np.ndarray, parts: list[np.ndarray], order: list[int], points_per_view: int = 0
) -> EpisodeState:
    """The state a policy reads after the captured views ``order``, normalised frame.

    Args:
        poses: (V', 4, 4) camera-to-world of the candidates (and any extra captured views).
        parts: V' arrays (N_v, 3) of each view's points; empty for views not captured.
        order: the captured views in order.
        points_per_view: the subsampling the points were kept with (0 = all), for the record.

    Returns:
        An :class:`EpisodeState` over a one-viewspace record without ground truth (its
        coverage bits and hull vertices are empty: only the oracle would read them).
    """
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)
    view = ViewData(
        poses=poses, points=np.concatenate(parts).astype(np.float32), offsets=offsets,
        coverage=np.zeros((len(poses), 1), np.uint8), hull_points=np.zeros((0, 3), np.float32),
        hull_offsets=np.zeros(len(poses) + 1, dtype=np.int64), points_per_view=points_per_view,
    )  # fmt: skip
    model = ModelData(
        key="captures", category="", split="", source="captures", source_path="",
        center=np.zeros(3), scale=1.0, seed=0, gt_points=np.zeros((0, 3), np.float32),
        gt_hull_volume=float("nan"), views={VIEWSPACE: view},
    )  # fmt: skip
    state = EpisodeState(model, VIEWSPACE, np.zeros(len(poses), dtype=bool), list(order))
    state.view_state[list(order)] = True
    return state


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
    captures, frame, estimated = load_capture_frame(settings)
    camera = planner_camera(captures, settings.camera)
    log.info("planner camera: %s", camera)
    candidates = candidate_poses(settings.viewspace.directions(), frame, settings.distance)
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
    state = capture_state(poses, parts, index, settings.points_per_view)
    state.model.source_path = str(settings.captures)
    ctx = method_context(settings, camera, n)
    policy = METHODS[settings.method].build(ctx, policy_rng(settings.seed, settings.method))
    t0 = time.perf_counter()
    choice = policy(state)
    seconds = time.perf_counter() - t0
    chosen = [int(v) for v in (choice if isinstance(choice, list | tuple) else [choice])]
    gains, unit = predicted_gains(policy, state, chosen)
    files = [
        {"file": str(c.file), "view": int(m) if m is not None else None, "points": len(c.points)}
        for c, m in zip(captures, matched, strict=True)
    ]
    notes = list(getattr(policy, "notes", []))
    if extras:
        notes.append(f"{len(extras)} captures off the viewspace joined the plan as extra views")
    return PlanResult(
        frame=frame, model=state.model, n_candidates=n, visited=index, chosen=chosen, gains=gains,
        gain_unit=unit, decisions=[seconds], stages=_stage_seconds(policy),
        captured_files=files, notes=notes, frame_estimated=estimated, camera=camera,
    )  # fmt: skip
