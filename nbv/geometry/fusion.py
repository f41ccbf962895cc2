"""Depth images fused into a triangle mesh: truncated signed distance (TSDF) integration.

:func:`fuse_depth` integrates planar depth images, their camera-to-world poses (the project's
OpenCV axes, :mod:`nbv.geometry.camera`) and their intrinsics into Open3D's tensor
``VoxelBlockGrid`` (Curless and Levoy's running average of the truncated distance along each
camera's rays, in a sparse grid of 16^3-voxel blocks allocated where the images hold a surface)
and extracts its zero crossing by marching cubes.

Sensor semantics: a pixel with depth 0, NaN, infinite, at or beyond
:data:`nbv.geometry.camera.BACKGROUND_DEPTH`, or beyond ``max_depth`` is *no measurement*: it
changes no voxel. So a view with a hole in its depth never carves away a surface other views saw,
and a real sensor's dropouts do not read as free space. (A rendered image's background pixels are
no measurement here too: TSDF fusion only needs the surface and the band of ``truncation`` voxels
in front of it, which the measured pixels give.)

Accuracy: with exact depth, a voxel's distance is off by up to half a pixel's footprint times the
surface's slope in that view (Open3D reads the nearest pixel's depth, not an interpolated one), and
marching cubes interpolates linearly between voxels; on a smooth surface seen by several views the
mean error stays under half a voxel while the pixel footprint at the object is under the voxel
(``tests/test_fusion.py`` measures a quarter of a voxel), and grazing views reach about 1.5
voxels at worst. So choose ``voxel`` near the pixel footprint at the object's distance, or coarser.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from nbv.geometry.camera import BACKGROUND_DEPTH, Intrinsics, backproject, valid_depth
from nbv.utils.fields import at_least, check_ranges, setting

__all__ = ["VOXELS_PER_RADIUS", "FusionSettings", "fuse_depth"]

log = logging.getLogger(__name__)

#: The default voxel is the object's radius over this: 2 % of it (a 0.5-radius object gets 0.01,
#: a 10 cm one 2 mm), finer than the planners' occupancy map (radius / 25), and near a 640 x 480
#: camera's pixel footprint at twice the radius.
VOXELS_PER_RADIUS = 50
#: Voxels per block edge of the sparse grid (Open3D's default).
BLOCK_RESOLUTION = 16
#: Blocks reserved at first; Open3D's hash map grows past it when a scene needs more.
INITIAL_BLOCKS = 1024


def _null_or_positive(value: float | None) -> bool:
    return value is None or value > 0


@dataclass(frozen=True)
class FusionSettings:
    """How depth images are fused into a mesh (``reconstruction:`` of a config).

    Attributes:
        voxel: voxel edge, world units; null = the object's radius / :data:`VOXELS_PER_RADIUS`.
        truncation: the signed distance is truncated at this many voxels (Open3D's
            ``trunc_voxel_multiplier``): larger bridges more depth noise, smaller keeps thin
            parts apart. Each view updates the voxels within it of the surface it saw.
        max_depth: depth beyond this (world units) is no measurement, as a sensor's range
            limit; null = no limit.
        min_views: a voxel takes part in the surface once this many views measured it (each
            adds a weight of 1): 1 keeps everything seen once, which next-best-view captures
            need (much of the object is seen by one view); 2 or more drops stray measurements.
    """

    voxel: float | None = setting(
        None, check=_null_or_positive, allowed="null or a positive distance"
    )
    truncation: float = setting(4.0, allows=at_least(1, "a number of voxels"))
    max_depth: float | None = setting(
        None, check=_null_or_positive, allowed="null or a positive distance"
    )
    min_views: int = setting(1, allows=at_least(1))

    def __post_init__(self) -> None:
        check_ranges(self)

    def voxel_size(self, radius: float | None = None) -> float:
        """The voxel edge in world units: ``voxel``, else ``radius / VOXELS_PER_RADIUS``.

        Raises:
            ValueError: ``voxel`` is null and no positive ``radius`` is given.
        """
        if self.voxel is not None:
            return float(self.voxel)
        if radius is None or not (np.isfinite(radius) and radius > 0):
            raise ValueError(
                f"reconstruction.voxel=null takes the object's radius / {VOXELS_PER_RADIUS}, "
                f"but the radius is {radius!r}; give reconstruction.voxel (world units)"
            )
        return float(radius) / VOXELS_PER_RADIUS


def _views(
    depths: np.ndarray | Sequence[np.ndarray],
    poses: np.ndarray,
    intrinsics: Intrinsics | Sequence[Intrinsics],
) -> tuple[list[np.ndarray], np.ndarray, list[Intrinsics]]:
    """Check the inputs' shapes: one depth image, pose and camera a view."""
    images = [np.asarray(d) for d in depths]
    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) != len(images):
        raise ValueError(
            f"poses must be (V, 4, 4) for V = {len(images)} depth images, got {poses.shape}"
        )
    if not np.all(np.isfinite(poses)):
        raise ValueError("poses hold NaN or infinite entries")
    cameras = [intrinsics] * len(images) if isinstance(intrinsics, Intrinsics) else list(intrinsics)
    if len(cameras) != len(images):
        raise ValueError(f"{len(cameras)} intrinsics for {len(images)} depth images")
    for i, (image, camera) in enumerate(zip(images, cameras, strict=True)):
        if image.shape != (camera.height, camera.width):
            raise ValueError(
                f"depth image {i} is {image.shape}, its intrinsics expect "
                f"{(camera.height, camera.width)} (H, W)"
            )
    return images, poses, cameras


def _canonical(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The same mesh in one order: vertices sorted by (x, y, z), each triangle turned (keeping
    its winding) to start at its least index, triangles sorted. Open3D's threads emit the
    surface in an order that changes from run to run; the geometry does not."""
    order = np.lexsort(vertices.T[::-1])
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    triangles = rank[triangles]
    first = np.argmin(triangles, axis=1)
    triangles = np.take_along_axis(triangles, (first[:, None] + np.arange(3)) % 3, axis=1)
    triangles = triangles[np.lexsort(triangles.T[::-1])]
    return vertices[order], triangles


def fuse_depth(
    depths: np.ndarray | Sequence[np.ndarray],
    poses: np.ndarray,
    intrinsics: Intrinsics | Sequence[Intrinsics],
    settings: FusionSettings | None = None,
    *,
    radius: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Fuse depth images into a triangle mesh by TSDF integration (Open3D ``VoxelBlockGrid``).

    Args:
        depths: (V, H, W) planar depth, world units, or a sequence of V (H_i, W_i) images;
            0, NaN, infinite, ``>= BACKGROUND_DEPTH`` or beyond ``settings.max_depth`` is no
            measurement (see the module docstring).
        poses: (V, 4, 4) camera-to-world, OpenCV axes (x right, y down, z forward).
        intrinsics: the camera of every view, or one per view.
        settings: voxel, truncation, range, views a voxel needs (:class:`FusionSettings`);
            None takes the defaults.
        radius: the object's radius, world units: sets the voxel when ``settings.voxel`` is
            null.

    Returns:
        ``(vertices, triangles)``: (N, 3) float64 world points and (M, 3) int64 indices into
        them, in a canonical order (the same inputs give the same arrays); both empty when no
        surface was measured.
    """
    import open3d as o3d  # imported here: heavy, and only fusion needs its integration

    settings = FusionSettings() if settings is None else settings
    images, poses, cameras = _views(depths, poses, intrinsics)
    voxel = settings.voxel_size(radius)
    max_depth = BACKGROUND_DEPTH if settings.max_depth is None else float(settings.max_depth)
    grid = o3d.t.geometry.VoxelBlockGrid(
        attr_names=("tsdf", "weight"),
        attr_dtypes=(o3d.core.float32, o3d.core.float32),
        attr_channels=((1,), (1,)),
        voxel_size=voxel,
        block_resolution=BLOCK_RESOLUTION,
        block_count=INITIAL_BLOCKS,
    )
    threshold = settings.min_views - 0.5  # Open3D keeps voxels of weight > threshold
    measured = 0
    for image, pose, camera in zip(images, poses, cameras, strict=True):
        # Open3D skips depth <= 0 and > depth_max, but would integrate a NaN: every kind of
        # "no measurement" becomes 0 first.
        mask = valid_depth(image) & (image <= max_depth)
        if not mask.any():
            continue
        measured += int(mask.sum())
        clean = np.where(mask, image, 0.0)
        depth = o3d.t.geometry.Image(o3d.core.Tensor(clean.astype(np.float32)))
        intrinsic = o3d.core.Tensor(camera.matrix, o3d.core.float64)
        extrinsic = o3d.core.Tensor(np.linalg.inv(pose), o3d.core.float64)  # world-to-camera
        # Blocks from every measured point: Open3D's depth-image overload samples every 4th
        # pixel only, which misses a thin part or a patchy real image's isolated measurements.
        points = o3d.t.geometry.PointCloud(
            o3d.core.Tensor(backproject(clean, camera, pose).astype(np.float32))
        )
        blocks = grid.compute_unique_block_coordinates(points, settings.truncation)
        grid.integrate(blocks, depth, intrinsic, extrinsic, 1.0, max_depth, settings.truncation)
    empty = np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    if measured == 0 or not (grid.attribute("weight").numpy() > threshold).any():
        return empty
    try:
        mesh = grid.extract_triangle_mesh(weight_threshold=threshold)
    except RuntimeError as err:
        # Open3D 0.20 fails, instead of returning an empty mesh, when no voxel pair crosses
        # zero (a few isolated pixels): "Tensor has shape {0}, but is expected ... {None, 3}".
        if "shape {0}" not in str(err):
            raise
        return empty
    vertices, triangles = _canonical(
        mesh.vertex.positions.numpy().astype(np.float64),
        mesh.triangle.indices.numpy().astype(np.int64),
    )
    log.debug("fused %d views (%d pixels) at voxel %.4g: %d vertices, %d triangles",
              len(images), measured, voxel, len(vertices), len(triangles))  # fmt: skip
    return vertices, triangles
