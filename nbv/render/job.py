"""A render job (a mesh and its camera poses) and the error of a failed one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BACKENDS = ("blender", "raycast")


DEVICES = ("CPU", "GPU", "AUTO")


class RenderError(RuntimeError):
    """Rendering one mesh failed; the message names its key and the reason."""


@dataclass(frozen=True)
class RenderJob:
    """One mesh to render from several cameras.

    Attributes:
        key: unique name of the mesh in the stream (echoed back with its depth).
        vertices: (N, 3) float vertex positions, world units.
        faces: (F, 3) integer vertex indices of triangles.
        poses: (V, 4, 4) camera-to-world matrices in the OpenCV convention of
        :mod:`nbv.geometry.camera`.
    """

    key: str
    vertices: np.ndarray
    faces: np.ndarray
    poses: np.ndarray


def check_mesh(vertices: np.ndarray, faces: np.ndarray, poses: np.ndarray) -> None:
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
