"""Pinhole cameras: intrinsics, look-at poses, projection and back-projection.

Conventions (used everywhere in the project):

* Camera frame is OpenCV's: +x right, +y down, +z forward (the optical axis).
* A pose is a camera-to-world 4x4 matrix ``T`` with ``X_world = T @ X_cam``.
* Pixels are indexed ``(row v, column u)``; pixel centres sit at integer coordinates, so the
  image centre of a ``W x H`` image is ``((W - 1) / 2, (H - 1) / 2)``.
* Depth is *planar*: the z coordinate of the surface point in the camera frame (what Blender's
  Z pass and Open3D's ``t_hit`` for unnormalised pinhole rays return). Background pixels hold
  ``inf`` (or any value ``<= 0`` or ``>= BACKGROUND_DEPTH``) and are masked.
* The world is Y-up (ShapeNet's OBJ frame). Blender cameras look along their local -z with +y up;
  :func:`opencv_to_blender` converts a pose.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Depth values at or above this are background (Blender writes 1e10 for empty pixels).
BACKGROUND_DEPTH = 1e9

_WORLD_UP = np.array([0.0, 1.0, 0.0])
#: Image "up" used when the optical axis is parallel to the world up (the poles): world -z.
_POLE_UP = np.array([0.0, 0.0, -1.0])


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels.

    Attributes:
        width, height: image size in pixels.
        fx, fy: focal lengths in pixels.
        cx, cy: principal point in pixels (pixel centres at integer coordinates).
    """

    width: int = 640
    height: int = 480
    fx: float = 476.0
    fy: float = 476.0
    cx: float = 319.5
    cy: float = 239.5

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"image size must be positive, got {self.width} x {self.height}")
        if not (self.fx > 0 and self.fy > 0):
            raise ValueError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")

    @classmethod
    def centred(cls, width: int = 640, height: int = 480, focal: float = 476.0) -> Intrinsics:
        """Square pixels, principal point at the image centre (PC-NBV's camera by default)."""
        return cls(width, height, focal, focal, (width - 1) / 2.0, (height - 1) / 2.0)

    @classmethod
    def from_config(cls, camera: Mapping[str, Any]) -> Intrinsics:
        """A ``camera: {width, height, focal}`` of ``conf/camera/`` (principal point centred)."""
        return cls.centred(camera["width"], camera["height"], camera["focal"])

    def as_dict(self) -> dict[str, int | float]:
        """``{"width", "height", "fx", "fy", "cx", "cy"}``, sizes as int, the rest as float:
        how job files, capture folders and the dataset's root attributes write a camera."""
        return {"width": int(self.width), "height": int(self.height), "fx": float(self.fx),
                "fy": float(self.fy), "cx": float(self.cx), "cy": float(self.cy)}  # fmt: skip

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 calibration matrix K."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def horizontal_fov(self) -> float:
        """Horizontal field of view in radians (for a centred principal point)."""
        return 2.0 * float(np.arctan(self.width / (2.0 * self.fx)))


def look_at(
    eye: np.ndarray, target: np.ndarray | None = None, up: np.ndarray | None = None
) -> np.ndarray:
    """Camera-to-world pose of a camera at ``eye`` looking at ``target``.

    Args:
        eye: (3,) camera centre, world units.
        target: (3,) point on the optical axis; default the origin.
        up: (3,) world direction that should appear up in the image; default +y. When the optical
            axis is (anti)parallel to it, as at the poles of a viewspace, world -z is used instead,
            so every direction gets one well-defined pose.

    Returns:
        (4, 4) float64 camera-to-world matrix in the OpenCV camera convention.
    """
    eye = np.asarray(eye, dtype=np.float64)
    target = np.zeros(3) if target is None else np.asarray(target, dtype=np.float64)
    up = _WORLD_UP if up is None else np.asarray(up, dtype=np.float64)
    forward = target - eye
    norm = np.linalg.norm(forward)
    if not norm > 0:
        raise ValueError(f"camera at {eye.tolist()} coincides with its target")
    forward = forward / norm
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-6:
        right = np.cross(forward, _POLE_UP)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, down, forward, eye
    return pose


def viewspace_poses(viewspace: np.ndarray, target: np.ndarray | None = None) -> np.ndarray:
    """Look-at poses for every camera position of a viewspace.

    Args:
        viewspace: (V, 3) camera positions, world units.
        target: (3,) common look-at point; default the origin.

    Returns:
        (V, 4, 4) float64 camera-to-world poses.
    """
    return np.stack([look_at(eye, target) for eye in np.asarray(viewspace, dtype=np.float64)])


def opencv_to_blender(pose: np.ndarray) -> np.ndarray:
    """Convert camera-to-world poses from the OpenCV to the Blender camera convention.

    Args:
        pose: (..., 4, 4) camera-to-world, camera +z forward and +y down.

    Returns:
        (..., 4, 4) camera-to-world with camera -z forward and +y up (Blender's ``matrix_world``).
    """
    return np.asarray(pose, dtype=np.float64) @ np.diag([1.0, -1.0, -1.0, 1.0])


def pixel_rays(intrinsics: Intrinsics) -> np.ndarray:
    """Camera-frame ray directions through every pixel centre, scaled to unit z.

    Returns:
        (H, W, 3) float64; ``depth * ray`` is the camera-frame point of a pixel with planar depth.
    """
    uu, vv = np.meshgrid(np.arange(intrinsics.width), np.arange(intrinsics.height))
    return rays_through(intrinsics, uu, vv)


def rays_through(intrinsics: Intrinsics, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Camera-frame directions (unit z) through pixel coordinates ``u`` (columns) and ``v``
    (rows) of one shape: float64 of that shape plus a last axis of 3."""
    u, v = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
    return np.stack(
        [(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones_like(u)],
        axis=-1,
    )


def valid_depth(depth: np.ndarray) -> np.ndarray:
    """Boolean mask of pixels that hold a surface (finite, positive, below the background value)."""
    depth = np.asarray(depth)
    return np.isfinite(depth) & (depth > 0) & (depth < BACKGROUND_DEPTH)


def backproject(
    depth: np.ndarray, intrinsics: Intrinsics, pose: np.ndarray, mask: np.ndarray | None = None
) -> np.ndarray:
    """World points of every valid pixel of a planar depth image.

    Args:
        depth: (H, W) planar depth, world units; background as described in the module docstring.
        intrinsics: the camera that produced it.
        pose: (4, 4) camera-to-world.
        mask: (H, W) bool, the pixels to back-project (each must hold a depth); None = every
            valid one (:func:`valid_depth`).

    Returns:
        (N, 3) float64 world points, in row-major pixel order.
    """
    depth = np.asarray(depth)
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise ValueError(
            f"depth image is {depth.shape}, the intrinsics expect "
            f"{(intrinsics.height, intrinsics.width)}"
        )
    # The rays of the valid pixels alone (the same values as pixel_rays(intrinsics)[mask], in
    # the same row-major order): an object fills a fraction of the image.
    rows, cols = np.nonzero(valid_depth(depth) if mask is None else mask)
    cam = rays_through(intrinsics, cols, rows) * depth[rows, cols].astype(np.float64)[:, None]
    return cam @ pose[:3, :3].T + pose[:3, 3]


def project(
    points: np.ndarray, intrinsics: Intrinsics, pose: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project world points into a camera (the inverse of :func:`backproject`).

    Args:
        points: (N, 3) world points.
        intrinsics: the camera.
        pose: (4, 4) camera-to-world.

    Returns:
        ``(uv, z)``: (N, 2) continuous pixel coordinates ``(u, v)`` and (N,) planar depth. Points
        behind the camera get ``z <= 0``; their ``uv`` is meaningless.
    """
    points = np.asarray(points, dtype=np.float64)
    rotation, centre = pose[:3, :3], pose[:3, 3]
    cam = (points - centre) @ rotation
    z = cam[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = intrinsics.fx * cam[:, 0] / z + intrinsics.cx
        v = intrinsics.fy * cam[:, 1] / z + intrinsics.cy
    return np.stack([u, v], axis=1), z
