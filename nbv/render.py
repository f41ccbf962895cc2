"""Depth rendering of meshes: Blender Cycles (the default) or Open3D ray casting.

Both backends share the camera model of :mod:`nbv.camera` and return planar depth, ``inf`` for
background, as (V, H, W) float32 arrays, one per mesh:

* ``"blender"`` runs ``blender_scripts/render_depth.py`` in ONE subprocess (the bpy wheel, or a
  Blender binary given by path) for a whole stream of meshes and yields each mesh's depth as soon
  as it is done, so the caller overlaps its own work with rendering.
* ``"raycast"`` casts one ray per pixel centre with Open3D's Embree scene, in this process.

Per-mesh failures come back as :class:`RenderError` values in the stream instead of exceptions,
so one bad mesh never costs the rest of a shard.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nbv.camera import Intrinsics, opencv_to_blender, pixel_rays

#: The Blender script, run as a subprocess (it imports bpy, never nbv).
BLENDER_SCRIPT = Path(__file__).resolve().parent.parent / "blender_scripts" / "render_depth.py"
BACKENDS = ("blender", "raycast")
DEVICES = ("CPU", "GPU", "AUTO")
_STDERR_TAIL_LINES = 20


class RenderError(RuntimeError):
    """Rendering one mesh failed; the message names its key and the reason."""


@dataclass(frozen=True)
class RenderJob:
    """One mesh to render from several cameras.

    Attributes:
        key: unique name of the mesh in the stream (echoed back with its depth).
        vertices: (N, 3) float vertex positions, world units.
        faces: (F, 3) integer vertex indices of triangles.
        poses: (V, 4, 4) camera-to-world matrices in the OpenCV convention of :mod:`nbv.camera`.
    """

    key: str
    vertices: np.ndarray
    faces: np.ndarray
    poses: np.ndarray


def _check_mesh(vertices: np.ndarray, faces: np.ndarray, poses: np.ndarray) -> None:
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"vertices must be (N, 3), got shape {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise ValueError(f"faces must be integer (F, 3), got {faces.dtype} {faces.shape}")
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise ValueError(
            f"face indices must lie in [0, {len(vertices)}), got [{faces.min()}, {faces.max()}]"
        )
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise ValueError(f"poses must be (V, 4, 4), got shape {poses.shape}")


def render_raycast(
    vertices: np.ndarray, faces: np.ndarray, poses: np.ndarray, intrinsics: Intrinsics
) -> np.ndarray:
    """Planar depth images of a triangle mesh by ray casting (Open3D / Embree).

    Rays go through the pixel centres of :func:`nbv.camera.pixel_rays` with unit camera-z, so the
    hit distance along the unnormalised ray is the planar depth.

    Args:
        vertices: (N, 3) vertex positions, world units.
        faces: (F, 3) integer triangle indices.
        poses: (V, 4, 4) camera-to-world, OpenCV convention.
        intrinsics: the camera.

    Returns:
        (V, H, W) float32 planar depth, world units; ``inf`` where no triangle is hit.
    """
    import open3d as o3d  # imported here: heavy, and only this backend needs it

    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    poses = np.asarray(poses, dtype=np.float64)
    _check_mesh(vertices, faces, poses)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.ascontiguousarray(vertices, dtype=np.float32)),
        o3d.core.Tensor(np.ascontiguousarray(faces, dtype=np.uint32)),
    )
    rays_cam = pixel_rays(intrinsics).reshape(-1, 3)
    depth = np.empty((len(poses), intrinsics.height, intrinsics.width), dtype=np.float32)
    rays = np.empty((rays_cam.shape[0], 6), dtype=np.float32)
    for i, pose in enumerate(poses):
        rays[:, :3] = pose[:3, 3]
        rays[:, 3:] = rays_cam @ pose[:3, :3].T
        hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        depth[i] = hit.reshape(intrinsics.height, intrinsics.width)
    return depth
