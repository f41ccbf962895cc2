"""A whole episode on simulated captures of a mesh (``python -m nbv.plan mesh=...``).

The mesh is placed as the dataset normalises it (bounding-box centre, farthest vertex; or the
``object`` settings), every viewspace view is ray cast (:func:`nbv.render.raycast.render_raycast`)
and turned into the dataset's view record (:func:`nbv.dataset.views.view_data`), and
:func:`nbv.policies.episode.run_episode` plays the episode from ``start_view``; coverage by view
is measured against ``n_gt`` points sampled on the mesh, and the fused views against the mesh
(:func:`reconstruct_episode`). :func:`save_episode_captures` writes the
first views as a capture folder (:mod:`nbv.scan.captures`), in the mesh's units, declaring
``no_return: free`` (a rendered background is empty space).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from nbv.assets.meshes import Mesh, MeshError, load_mesh, normalise, sample_surface
from nbv.dataset.records import ModelData
from nbv.dataset.views import view_data
from nbv.geometry.hull import QhullFailure, hull_volume
from nbv.geometry.reconstruction_metrics import mesh_scores
from nbv.plan.config import PlanSettings
from nbv.policies.episode import run_episode, stage_seconds
from nbv.policies.registry import METHODS
from nbv.render.job import RenderError
from nbv.render.raycast import render_raycast
from nbv.scan.captures import write_captures
from nbv.scan.frame import candidate_poses, object_frame
from nbv.scan.method import GainRecorder, policy_rng, scan_context
from nbv.scan.reconstruction import fuse_views
from nbv.scan.result import VIEWSPACE, PlanResult, Reconstruction
from nbv.utils.seeding import named_rng

log = logging.getLogger(__name__)


def plan_mesh(settings: PlanSettings) -> tuple[PlanResult, np.ndarray]:
    """Play a whole episode on simulated captures of ``settings.mesh``.

    Returns:
        ``(result, depth)``: the plan, and the (V, H, W) float32 depth images of every
        candidate in normalised units (for :func:`save_episode_captures`).
    """
    mesh = load_mesh(settings.mesh)
    _, center, scale = normalise(mesh)
    frame = object_frame(settings, center, 0.5 / scale)
    normalised_vertices = frame.points_to_normalised(mesh.vertices)
    poses = candidate_poses(settings.viewspace.directions(), frame, settings.viewspace.radius)
    rng = named_rng(settings.seed, "plan", "mesh")
    normalised = Mesh(normalised_vertices, mesh.faces, mesh.source_path)
    gt = sample_surface(normalised, settings.n_gt, rng)
    log.info("ray casting %d views of %s", len(poses), settings.mesh)
    depth = render_raycast(normalised.vertices, normalised.faces, poses, settings.camera)
    try:
        view = view_data(depth, poses, settings.camera, gt, settings.eps,
                         settings.points_per_view, rng)  # fmt: skip
    except RenderError as err:
        # Parts far apart leave each below a pixel once the whole fits the views: no plan.
        raise MeshError(
            f"{settings.mesh}: {err} ({len(poses)} views of {settings.camera.width} x "
            f"{settings.camera.height} pixels; are its parts far apart?); nothing to plan from"
        ) from err
    try:
        gt_volume = hull_volume(gt)
    except QhullFailure:
        gt_volume = float("nan")
    model = ModelData(
        key=Path(settings.mesh).stem, category="", split="", source="mesh",
        source_path=str(settings.mesh), center=frame.center, scale=frame.scale,
        seed=settings.seed, gt_points=gt, gt_hull_volume=gt_volume, views={VIEWSPACE: view},
    )  # fmt: skip
    ctx = scan_context(settings, settings.camera, len(poses))
    policy = METHODS[settings.method].build(ctx, policy_rng(settings.seed, settings.method))
    recorder = GainRecorder(policy)
    episode = run_episode(model, VIEWSPACE, settings.start_view, recorder, settings.n_views)
    gains = recorder.gains[: len(episode.views) - 1]
    return PlanResult(
        frame=frame,
        views=model.captured(VIEWSPACE),
        n_candidates=len(poses),
        visited=[settings.start_view],
        chosen=episode.views[1:],
        gains=None if any(g is None for g in gains) else gains,
        gain_unit=recorder.unit,
        coverage=[float(c) for c in episode.coverage],
        decisions=recorder.seconds,
        stages=stage_seconds(policy),
        notes=list(policy.notes) + episode.notes,
        camera=settings.camera,
    ), depth


def save_episode_captures(settings: PlanSettings, result: PlanResult, depth: np.ndarray) -> Path:
    """Write the episode's first ``save_captures`` views as a capture folder, in world units."""
    folder = settings.captures_out or settings.out_dir / "captures"
    views = (result.visited + result.chosen)[: settings.save_captures]
    poses = result.frame.poses_to_world(result.views.poses[views])
    # Rendered views: their background is empty space, and the folder says so.
    write_captures(folder, depth[views] / result.frame.scale, poses, settings.camera,
                   result.frame.center, result.frame.radius, no_return="free")  # fmt: skip
    return folder


#: Points sampled on each surface for the mesh-input scores (adds about 0.5 sqrt(area / n) to
#: each mean distance: 0.003 at most for the object's sphere of radius 0.5).
SCORE_SAMPLES = 100_000


def reconstruct_episode(
    settings: PlanSettings, result: PlanResult, depth: np.ndarray
) -> Reconstruction:
    """Mesh input: fuse the episode's views (``plan_mesh``'s normalised depth, turned back into
    world units as ``save_episode_captures`` does) and score the mesh against the input mesh."""
    frame = result.frame
    views = result.visited + result.chosen
    poses = frame.poses_to_world(result.views.poses[views])
    out = fuse_views(settings, frame, list(depth[views] / frame.scale), poses,
                     [settings.camera] * len(views), views)  # fmt: skip
    if len(out.triangles):
        mesh = load_mesh(settings.mesh)  # the world frame and units
        out.scores = mesh_scores(
            out.vertices, out.triangles, mesh.vertices, mesh.faces,
            eps=settings.eps / frame.scale,  # eps is in normalised units
            rng=named_rng(settings.seed, "plan", "reconstruction"), n=SCORE_SAMPLES,
        )  # fmt: skip
    return out
