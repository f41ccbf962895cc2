"""A render job (a mesh and its camera poses) and the error of a failed one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Mesh validation lives with the ray casting; the Blender driver checks its meshes the same way.
from nbv.geometry.raycast import check_mesh

__all__ = ["BACKENDS", "DEVICES", "RenderError", "RenderJob", "check_mesh"]

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
