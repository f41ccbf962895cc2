"""Which points of a cloud each camera sees: a z-buffer of the points themselves.

A cloud has no surface to ray cast, so each camera gets a coarse depth image made of the points:
the image plane is cut into square cells, each cell keeps the nearest depth of the points that
project into it, and a point is visible when it lies in the camera's image, in front of the
camera, no farther than ``tolerance`` behind the nearest point of its own cell (a surface
slanted away from the camera does not hide itself), and its cell is no hole: a cell whose
nearest point lies more than ``hole`` behind the nearest of the nine cells around it sees
through a gap between a sparse cloud's points, and its points are hidden.

The seen surface stays in the cloud, so it occludes what lies behind it: the rule agrees with
the coverage test of a rendered view (a point is covered when the camera's image holds a point
near it), where hidden-point removal on the unseen points alone does not (FACTS.md, "Shape
completion in the view-planning loop").

Sizes are set from the cloud's spacing (:func:`cloud_spacing`), so the same settings serve a
dense true surface (16,384 points) and a network's completion (a few thousand).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import minimum_filter
from scipy.spatial import cKDTree

from nbv.geometry.camera import Intrinsics


@dataclass(frozen=True)
class SplatSettings:
    """The z-buffer's sizes, in units of the cloud's spacing (:func:`cloud_spacing`).

    Attributes:
        cell: side of a z-buffer cell at the camera's distance from the origin.
        tolerance: depth a point may lie behind the nearest one of its cell and still be seen.
        hole: depth the nearest point of a cell may lie behind the nearest of the cells around
            it before the cell is a hole.
    """

    cell: float = 1.5
    tolerance: float = 4.0
    hole: float = 8.0

    def __post_init__(self) -> None:
        if not (self.cell > 0 and self.tolerance >= 0 and self.hole >= 0):
            raise ValueError(
                f"splat settings cell={self.cell}, tolerance={self.tolerance}, hole={self.hole}: "
                "cell must be > 0, tolerance and hole >= 0"
            )


def cloud_spacing(points: np.ndarray) -> float:
    """The median distance from a point of ``points`` (N, 3), N >= 2, to its nearest other point
    (cloud units); 0 for fewer than two distinct points."""
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 2:
        return 0.0
    d, _ = cKDTree(pts).query(pts, k=2)
    return float(np.median(d[:, 1]))


def visible_points(
    points: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    cell: float,
    tolerance: float,
    hole: float,
) -> np.ndarray:
    """(V, N) bool: point ``n`` is seen from camera ``v`` (see the module docstring).

    Args:
        points: (N, 3) world points.
        poses: (V, 4, 4) camera-to-world, OpenCV convention (z forward).
        intrinsics: the cameras' intrinsics; the image bounds are theirs.
        cell: z-buffer cell side, world units at the camera's distance from the origin (its
            size in pixels is ``cell * fx / distance``, at least one pixel).
        tolerance: world units a point may lie behind the nearest point of its cell.
        hole: world units the nearest point of a cell may lie behind the nearest of the nine
            cells around it before the cell counts as a hole in the surface in front (its
            points are hidden).

    Returns:
        (V, N) bool.
    """
    pts = np.asarray(points, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64)
    n_views, n = len(poses), len(pts)
    if n == 0 or n_views == 0:
        return np.zeros((n_views, n), dtype=bool)
    rot, centre = poses[:, :3, :3], poses[:, :3, 3]
    cam = np.einsum("vij,vni->vnj", rot, pts[None] - centre[:, None])
    z = cam[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = intrinsics.fx * cam[..., 0] / z + intrinsics.cx
        v = intrinsics.fy * cam[..., 1] / z + intrinsics.cy
    w, h = intrinsics.width, intrinsics.height
    inside = (z > 0) & (u >= -0.5) & (u < w - 0.5) & (v >= -0.5) & (v < h - 0.5)
    distance = np.linalg.norm(centre, axis=1)
    px = np.maximum(cell * intrinsics.fx / np.maximum(distance, 1e-9), 1.0)  # (V,)
    gw = int(np.ceil(w / px.min())) + 2
    gh = int(np.ceil(h / px.min())) + 2
    cu = np.where(inside, np.floor((u + 0.5) / px[:, None]), 0).astype(np.int64) + 1
    cv = np.where(inside, np.floor((v + 0.5) / px[:, None]), 0).astype(np.int64) + 1
    flat = (np.arange(n_views)[:, None] * gh + cv) * gw + cu
    zbuf = np.full(n_views * gh * gw, np.inf)
    np.minimum.at(zbuf, flat[inside], z[inside])
    near = minimum_filter(zbuf.reshape(n_views, gh, gw), size=(1, 3, 3), mode="constant",
                          cval=np.inf).ravel()  # fmt: skip
    own = zbuf[flat]
    return inside & (z <= own + tolerance) & (own <= near[flat] + hole)


def visible_from(
    points: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    settings: SplatSettings = SplatSettings(),
    spacing: float | None = None,
) -> np.ndarray:
    """:func:`visible_points` with sizes from ``settings`` times ``spacing`` (default: the
    cloud's own, :func:`cloud_spacing`)."""
    s = cloud_spacing(points) if spacing is None else spacing
    s = max(s, 1e-6)
    return visible_points(points, poses, intrinsics, settings.cell * s, settings.tolerance * s,
                          settings.hole * s)  # fmt: skip
