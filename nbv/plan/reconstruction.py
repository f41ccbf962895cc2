"""The plan's reconstruction: its depth views fused into ``reconstruction.ply``
(:func:`nbv.geometry.fusion.fuse_depth`), and for mesh input its scores against the mesh
(:func:`nbv.geometry.reconstruction.mesh_scores`). World frame and units throughout.
"""

from __future__ import annotations

import numpy as np

from nbv.assets.meshes import load_mesh
from nbv.geometry.camera import Intrinsics
from nbv.geometry.fusion import fuse_depth
from nbv.geometry.reconstruction import mesh_scores
from nbv.plan.captures import Capture
from nbv.plan.config import PlanSettings
from nbv.plan.frame import ObjectFrame
from nbv.plan.result import VIEWSPACE, PlanResult, Reconstruction
from nbv.utils.seeding import named_rng

#: Points sampled on each surface for the mesh-input scores (adds about 0.5 sqrt(area / n) to
#: each mean distance: 0.003 at most for the object's sphere of radius 0.5).
SCORE_SAMPLES = 100_000


def fuse_views(
    settings: PlanSettings,
    frame: ObjectFrame,
    depths: list[np.ndarray],
    poses: np.ndarray,
    cameras: list[Intrinsics],
    views: list[int],
) -> Reconstruction:
    """Fuse world-unit depth images with their OpenCV camera-to-world poses."""
    vertices, triangles = fuse_depth(
        depths, poses, cameras, settings.reconstruction, radius=frame.radius
    )
    voxel = settings.reconstruction.voxel_size(frame.radius)
    return Reconstruction(vertices, triangles, views, voxel)


def reconstruct_episode(
    settings: PlanSettings, result: PlanResult, depth: np.ndarray
) -> Reconstruction:
    """Mesh input: fuse the episode's views (``plan_mesh``'s normalised depth, turned back into
    world units as ``save_episode_captures`` does) and score the mesh against the input mesh."""
    frame = result.frame
    views = result.visited + result.chosen
    poses = frame.poses_to_world(result.model.views[VIEWSPACE].poses[views])
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


def reconstruct_captures(
    settings: PlanSettings, captures: list[Capture], frame: ObjectFrame
) -> Reconstruction | None:
    """Captures input: fuse every depth-image capture (``Capture.depth``: world units, 0 / NaN /
    inf where nothing was measured; the pixels beyond the view's ``max_range`` are dropped
    here); None when every view is a point cloud. ``views`` are capture indices, in order."""
    fused = [i for i, c in enumerate(captures) if c.depth is not None]
    if not fused:
        return None
    depths = []
    for i in fused:
        c = captures[i]
        depth = np.asarray(c.depth, dtype=np.float64)
        if c.max_range is not None:
            depth = np.where(depth > c.max_range, 0.0, depth)
        depths.append(depth)
    return fuse_views(settings, frame, depths, np.stack([captures[i].pose for i in fused]),
                      [captures[i].intrinsics for i in fused], fused)  # fmt: skip
