"""One captured view of a scan: :class:`Capture`, made from a depth image
(:func:`depth_capture`) or a point cloud (:func:`cloud_capture`), its pose checked rigid, and
:func:`check_views_see`, which refuses a view that does not look at the object.

What a view's missing pixels mean (``no_return``) and its range (``max_range``) are described
with the capture folder's format, in :mod:`nbv.scan.captures`. Bad input raises one
:class:`CaptureError` naming the view and what is wrong.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nbv.geometry.camera import Intrinsics, backproject, project, valid_depth
from nbv.infogain.occupancy import Misses

#: Pose axes conventions.
AXES = ("opencv", "blender")
#: Tolerance of the rigidity checks (|R^T R - I| and |det R - 1|): poses written as text with
#: six decimals still pass, a scaled or sheared matrix does not.
RIGID_TOL = 1e-4
#: A float depth image whose median is this many times the camera's distance to the object is
#: in other units than the poses (millimetres against metres is 1000).
UNIT_RATIO = 20.0
#: What a pixel without a measurement means (``no_return``); the first is the default.
NO_RETURN = ("unknown", "free")


class CaptureError(ValueError):
    """A capture folder that cannot be used; the message names the file and what is wrong."""


@dataclass(frozen=True)
class Capture:
    """One captured view.

    Attributes:
        file: the view's file.
        points: (N, 3) float64 world points, N >= 1.
        pose: (4, 4) float64 camera-to-world, OpenCV axes.
        intrinsics: the depth camera (None for a point cloud view).
        median_depth: median planar depth of the view's points, world units.
        misses: what its rays that returned nothing mean, world units (None: unknown; see
            ``no_return`` and ``max_range`` in the module docstring).
        no_return: the view's ``no_return``; max_range: its ``max_range`` (world units, or None).
        depth: a depth image view's (H, W) float64 depth in world units as read (before the
            range cut: 0, NaN or inf where nothing was measured); None for a point cloud view.
    """

    file: Path
    points: np.ndarray
    pose: np.ndarray
    intrinsics: Intrinsics | None
    median_depth: float
    misses: Misses | None = None
    no_return: str = NO_RETURN[0]
    max_range: float | None = None
    depth: np.ndarray | None = None


def check_rigid(pose: object, where: str) -> np.ndarray:
    """A camera-to-world pose as a (4, 4) float64 array, refused unless rigid.

    Raises:
        CaptureError: not a 4x4 of finite numbers, a last row other than ``0 0 0 1``, a rotation
            part with ``R^T R != I`` or ``det R != 1`` (beyond :data:`RIGID_TOL`).
    """
    try:
        m = np.array(pose, dtype=np.float64)
    except (TypeError, ValueError):
        raise CaptureError(f"{where}: pose must be a 4x4 matrix of numbers") from None
    if m.shape != (4, 4):
        raise CaptureError(f"{where}: pose must be 4x4, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise CaptureError(f"{where}: pose has NaN or infinite entries")
    if not np.allclose(m[3], [0, 0, 0, 1], atol=RIGID_TOL):
        raise CaptureError(f"{where}: pose's last row is {m[3].tolist()}, must be [0, 0, 0, 1]")
    r = m[:3, :3]
    off = float(np.abs(r.T @ r - np.eye(3)).max())
    if off > RIGID_TOL:
        raise CaptureError(
            f"{where}: pose is not rigid: R^T R differs from I by {off:.3g} (scaled or sheared "
            "rotation part)"
        )
    det = float(np.linalg.det(r))
    if abs(det - 1.0) > RIGID_TOL:
        raise CaptureError(f"{where}: pose is not rigid: det R = {det:.6g}, must be 1 (a mirror)")
    return m


def depth_capture(
    depth: np.ndarray,
    intrinsics: Intrinsics,
    pose: np.ndarray,
    file: Path,
    no_return: str = NO_RETURN[0],
    max_range: float | None = None,
) -> Capture:
    """A depth image view as the planner reads it (a file's, or one given to
    :class:`nbv.scan.planner.Planner`).

    Args:
        depth: (H, W) float64 planar depth, world units; 0, NaN or inf where nothing was
            measured.
        intrinsics: its camera ((H, W) must be its size).
        pose: (4, 4) rigid camera-to-world, OpenCV axes.
        file: the view's file (named in messages).
        no_return, max_range: what its missing pixels mean (module docstring).

    Raises:
        CaptureError: a size other than the camera's, or no pixel with a depth (within the range).
    """
    where = f"{file}"
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise CaptureError(
            f"{where}: depth is {depth.shape[1]} x {depth.shape[0]}, the intrinsics say "
            f"{intrinsics.width} x {intrinsics.height}"
        )
    measured = valid_depth(depth)
    beyond = measured & (depth > max_range) if max_range is not None else None
    kept = measured & ~beyond if beyond is not None else measured
    points = backproject(depth, intrinsics, pose, kept)
    if len(points) == 0:
        raise CaptureError(
            f"{where}: empty view: no pixel holds a depth"
            + (f" within max_range={max_range}" if max_range is not None else "")
        )
    mask = ~measured if no_return == "free" else np.zeros(depth.shape, dtype=bool)
    if beyond is not None:
        mask |= beyond
    declared = no_return == "free" or bool(mask.any())
    misses = Misses(mask, max_range, intrinsics) if declared else None
    # A pixel's planar depth is its point's: no projection needed.
    return Capture(file, points, pose, intrinsics, float(np.median(depth[kept])), misses,
                   no_return, max_range, depth)  # fmt: skip


def cloud_capture(
    points: np.ndarray,
    pose: np.ndarray,
    file: Path,
    no_return: str = NO_RETURN[0],
    max_range: float | None = None,
) -> Capture:
    """A point cloud view (N, 3) float64 world points (finite) with its (4, 4) camera-to-world
    pose, as the planner reads it; ``max_range`` drops the points beyond it (planar depth).

    Raises:
        CaptureError: no point is left (within the range).
    """
    if max_range is not None:
        _, z = project(points, Intrinsics(), pose)
        points = points[z <= max_range]
        if len(points) == 0:
            raise CaptureError(f"{file}: empty view: no point within max_range={max_range}")
    misses = Misses(None, max_range) if no_return == "free" else None
    _, z = project(points, Intrinsics(), pose)
    return Capture(file, points, pose, None, float(np.median(z)), misses, no_return, max_range)


def check_views_see(
    captures: list[Capture], center: np.ndarray, radius: float, camera: Intrinsics
) -> None:
    """Refuse a view whose camera does not look at the object, or whose depth is in other units.

    The object's centre must lie in front of the camera and inside its image (a depth view's
    own intrinsics; ``camera`` for a point cloud view); a float depth image whose median depth
    is :data:`UNIT_RATIO` times the camera's distance to the object is in other units.

    Raises:
        CaptureError: naming the file.
    """
    for c in captures:
        cam = c.intrinsics or camera
        (u, v), z = (x[0] for x in project(np.asarray(center)[None], cam, c.pose))
        distance = float(np.linalg.norm(c.pose[:3, 3] - center))
        if distance <= radius:
            raise CaptureError(
                f"{c.file}: the camera is inside the object's sphere (distance {distance:.4g} to "
                f"the centre, radius {radius:.4g})"
            )
        if not (z > 0 and -0.5 <= u <= cam.width - 0.5 and -0.5 <= v <= cam.height - 0.5):
            raise CaptureError(
                f"{c.file}: the camera does not look at the object: its centre "
                f"{np.round(center, 4).tolist()} is "
                + ("behind the camera" if z <= 0 else f"outside the image, at pixel ({u:.0f}, "
                   f"{v:.0f}) of {cam.width} x {cam.height}")
                + " (wrong pose, or axes: blender?)"
            )  # fmt: skip
        if c.intrinsics is not None and c.median_depth > UNIT_RATIO * distance:
            raise CaptureError(
                f"{c.file}: depth is {c.median_depth / distance:.0f}x the camera's distance to "
                f"the object ({c.median_depth:.4g} against {distance:.4g}): another unit than the "
                "poses (millimetres?); give depth_scale"
            )
