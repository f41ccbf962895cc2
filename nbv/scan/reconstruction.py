"""The scan's reconstruction: its depth views fused into a mesh
(:func:`nbv.geometry.fusion.fuse_depth`; ``python -m nbv.plan`` writes it as
``reconstruction.ply``). World frame and units throughout.
"""

from __future__ import annotations

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.geometry.fusion import fuse_depth
from nbv.scan.capture import Capture
from nbv.scan.frame import ObjectFrame
from nbv.scan.result import Reconstruction
from nbv.scan.settings import ScanSettings


def fuse_views(
    settings: ScanSettings,
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


def reconstruct_captures(
    settings: ScanSettings, captures: list[Capture], frame: ObjectFrame
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
