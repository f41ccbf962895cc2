"""A probabilistic occupancy map of the object's region, updated as OctoMap updates its octree.

The object fits in a sphere of radius 0.5 and the cameras sit at distance 1, so the map is a
dense cube ``[-bound, bound]^3`` of ``n^3`` voxels (166k at the default 2 cm). A view is a camera
centre, its hit points and the directions of its rays that hit nothing:

* the voxels a hit ray crosses before its hit are *free* (a miss update), the voxel of the hit
  *occupied* (a hit update); a voxel both crossed and hit in one view takes only the hit, and
  each voxel is updated once a view (OctoMap's ``insertPointCloud``);
* a ray that hits nothing carves free space until it leaves the region;
* voxels never crossed are *unknown*, except those outside the sphere the object fits in,
  which start free.

Where the rays that hit nothing come from depends on who took the view. A rendered view's
background is empty space (the renderer knows): :func:`background_directions` takes them from the
blocks of the image that no stored point falls in, the dataset's rule. A depth sensor's pixel
without a measurement is *unknown* (dark, shiny or grazing surfaces, often on the object itself),
so a sensed view carves only where its user declared that no return means free space, and only
up to the sensor's range: :class:`Misses` holds that declaration, :func:`mask_directions` takes
the rays from the full image's mask (subsampling the points never creates a miss) and
:meth:`OccupancyMap.sensed_voxels` traces them.

Log-odds updates are clamped, and a voxel is occupied at log-odds >= 0, with OctoMap's default
probabilities (:class:`OccupancySettings`). The test suite checks the map against OctoMap itself
(the ``octomap-python`` binding) on a scene of many views.

Why not OctoMap's octree: scoring candidate views needs the state of every voxel along tens of
thousands of rays per decision. Through the binding that is a few microseconds a voxel (its
``getLabels`` reads 166k voxel centres in 0.36 s on this machine), far beyond the 50 ms a
decision may take; a dense array of this small region reads them at numpy speed.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from nbv.geometry.camera import Intrinsics, project, rays_through
from nbv.infogain.raytrace import flat_index, traverse
from nbv.utils.fields import ConfigError, between, check_ranges, or_null, positive, setting

#: Voxel states of :meth:`OccupancyMap.labels` (OctoMap's getLabels values).
UNKNOWN, FREE, OCCUPIED = -1, 0, 1


def log_odds_of(p: float) -> float:
    """The log-odds ``log(p / (1 - p))`` of a probability in (0, 1)."""
    return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class OccupancySettings:
    """The map's grid and sensor model.

    Attributes:
        resolution: voxel edge, object units (the object fits in radius 0.5).
        bound: the region is the cube ``[-bound, bound]^3``; a whole number of voxels.
        p_hit: occupancy probability a hit adds (OctoMap's default 0.7).
        p_miss: occupancy probability a ray crossing a voxel adds (OctoMap's default 0.4).
        clamp_min: lower clamp of a voxel's probability (OctoMap's 0.1192).
        clamp_max: upper clamp (OctoMap's 0.971).
        object_radius: voxels whose centre lies farther than this from the origin start free
            at ``clamp_min`` (the object fits in radius 0.5: the cube's corners cannot hold it,
            and no view would be worth taking to look at them); None: every voxel starts
            unknown, as in OctoMap.
    """

    resolution: float = setting(0.02, allows=between(0, 0.5, "(]"))
    bound: float = setting(
        0.56, check=lambda v: v >= 0.5, allowed=">= 0.5 (the object fits in radius 0.5)"
    )
    p_hit: float = setting(0.7, allows=between(0.5, 1, "()"))
    p_miss: float = setting(0.4, allows=between(0, 0.5, "()"))
    clamp_min: float = setting(0.1192, allows=between(0, 0.5, "()"))
    clamp_max: float = setting(0.971, allows=between(0.5, 1, "()"))
    object_radius: float | None = setting(0.5, allows=or_null(positive("distance")))

    def __post_init__(self) -> None:
        check_ranges(self)
        cells = 2 * self.bound / self.resolution
        if abs(cells - round(cells)) > 1e-6:
            raise ConfigError(
                f"bound={self.bound!r}: must be a whole number of voxels of resolution="
                f"{self.resolution!r} from the centre (2 bound / resolution = {cells:.4f})"
            )

    @property
    def n(self) -> int:
        """Voxels along each axis."""
        return round(2 * self.bound / self.resolution)


def background_directions(
    points: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, block: int
) -> np.ndarray:
    """World directions of the rays of a view that hit nothing, from the view's points.

    The image is cut into ``block x block`` pixel blocks; a block that none of ``points``
    projects into is background, and its ray passes through the block's centre. The dataset
    keeps a uniform random subset of each view's pixels (2048 of them), so a block well inside
    the silhouette is left empty only by chance: a 16-pixel block that lies wholly on an object
    covering 100k pixels is empty with probability (1 - 256/100k)^2048, about 0.5 %.

    Args:
        points: (N, 3) world points of the view.
        pose: (4, 4) its camera-to-world pose.
        intrinsics: its camera.
        block: block edge in pixels.

    Returns:
        (M, 3) unit world directions, one per background block.
    """
    if block < 1:
        raise ValueError(f"block={block!r}: must be an integer >= 1 (pixels)")
    rows, cols = -(-intrinsics.height // block), -(-intrinsics.width // block)
    hit = np.zeros((rows, cols), dtype=bool)
    uv, z = project(points, intrinsics, pose)
    ok = (z > 0) & np.isfinite(uv).all(axis=1)
    # Pixel centres sit at integer coordinates: pixel i spans [i - 0.5, i + 0.5).
    px = np.floor(uv[ok] + 0.5).astype(np.int64)
    inside = (px[:, 0] >= 0) & (px[:, 0] < intrinsics.width) & (px[:, 1] >= 0)
    inside &= px[:, 1] < intrinsics.height
    hit[px[inside, 1] // block, px[inside, 0] // block] = True
    rr, cc = np.nonzero(~hit)
    centre_v = np.minimum(rr * block + block // 2, intrinsics.height - 1)
    centre_u = np.minimum(cc * block + block // 2, intrinsics.width - 1)
    cam = rays_through(intrinsics, centre_u, centre_v)
    world = cam @ np.asarray(pose, dtype=np.float64)[:3, :3].T
    return world / np.linalg.norm(world, axis=1, keepdims=True)


def mask_directions(
    mask: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, block: int
) -> np.ndarray:
    """Camera rays of the ``block x block`` pixel blocks every pixel of which is a miss.

    Args:
        mask: (H, W) bool, the pixels whose ray is known to hit nothing (within the range).
        pose: (4, 4) camera-to-world pose.
        intrinsics: the camera.
        block: block edge in pixels.

    Returns:
        (M, 3) unit world directions of the rays through the blocks' centre pixels (the same
        pixels, and the same arithmetic, as :func:`background_directions`).
    """
    if block < 1:
        raise ValueError(f"block={block!r}: must be an integer >= 1 (pixels)")
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != (intrinsics.height, intrinsics.width):
        raise ValueError(f"mask is {mask.shape}, the camera {intrinsics.height, intrinsics.width}")
    rows, cols = -(-intrinsics.height // block), -(-intrinsics.width // block)
    padded = np.ones((rows * block, cols * block), dtype=bool)
    padded[: mask.shape[0], : mask.shape[1]] = mask
    # A block is a miss only when all of it is: one measured (or unknown) pixel keeps it out.
    whole = padded.reshape(rows, block, cols, block).all(axis=(1, 3))
    rr, cc = np.nonzero(whole)
    centre_v = np.minimum(rr * block + block // 2, intrinsics.height - 1)
    centre_u = np.minimum(cc * block + block // 2, intrinsics.width - 1)
    cam = rays_through(intrinsics, centre_u, centre_v)
    world = cam @ np.asarray(pose, dtype=np.float64)[:3, :3].T
    return world / np.linalg.norm(world, axis=1, keepdims=True)


@dataclass(frozen=True)
class Misses:
    """What the rays of a sensed view that return nothing mean (a declaration of its user).

    Attributes:
        mask: (H, W) bool, the pixels known to hit nothing within ``reach`` (no return where no
            return is declared free, and measurements beyond the range); None for a point cloud
            view declared free: its blocks without a point are misses
            (:func:`background_directions`).
        reach: planar depth (map units) up to which a miss is free; None: through the region.
        intrinsics: the camera of ``mask`` (None: the map's user's camera).
    """

    mask: np.ndarray | None
    reach: float | None = None
    intrinsics: Intrinsics | None = None

    def digest(self) -> bytes:
        """Bytes that identify the declaration (a key of traced views)."""
        head = np.float64(np.nan if self.reach is None else self.reach).tobytes()
        head += repr(self.intrinsics).encode()
        if self.mask is None:
            return head
        return head + np.packbits(self.mask).tobytes() + np.int64(self.mask.shape).tobytes()


@functools.lru_cache(maxsize=4)
def _prior(settings: OccupancySettings) -> np.ndarray:
    """(n^3,) log-odds of an empty map: unknown (NaN), but free outside ``object_radius``.
    Memoised (read-only): every episode starts from it."""
    log_odds = np.full(settings.n**3, np.nan)
    if settings.object_radius is not None:
        s = settings
        axis = (np.arange(s.n) + 0.5) * s.resolution - s.bound
        grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
        log_odds[np.linalg.norm(grid, axis=1) > s.object_radius] = log_odds_of(s.clamp_min)
    log_odds.flags.writeable = False
    return log_odds


class OccupancyMap:
    """Clamped log-odds occupancy of the region's voxels; NaN for unknown ones.

    Attributes:
        settings: the grid and sensor model.
        log_odds: (n^3,) float64, flat voxel index as :mod:`nbv.infogain.raytrace`.
    """

    def __init__(self, settings: OccupancySettings | None = None) -> None:
        self.settings = settings or OccupancySettings()
        self.log_odds = _prior(self.settings).copy()

    def voxel_of(self, points: np.ndarray) -> np.ndarray:
        """(N,) flat voxel index of each (N, 3) point; -1 outside the region."""
        s = self.settings
        ijk = np.floor((np.asarray(points, dtype=np.float64) + s.bound) / s.resolution)
        ijk = ijk.astype(np.int64)
        inside = ((ijk >= 0) & (ijk < s.n)).all(axis=1)
        return np.where(inside, flat_index(ijk, s.n), -1)

    def miss_ends(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(M, 3) ends of rays from ``origin`` (3,) along ``directions`` (M, 3) that hit
        nothing: beyond the region's far corner, so that they carve it through."""
        reach = np.linalg.norm(origin) + 2.0 * math.sqrt(3.0) * self.settings.bound
        norms = np.linalg.norm(directions, axis=1, keepdims=True)
        return origin + directions / np.where(norms > 0, norms, 1.0) * reach

    def view_voxels(
        self, origin: np.ndarray, hits: np.ndarray, miss_directions: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """What one view does to the map, before the update: ``(free, occupied)`` sorted flat
        voxel indices, the voxels its rays cross (but do not end in) and those they end in.
        They depend on the view and the grid only, not on the map: a planner may keep them.

        Args: as :meth:`insert_view`.
        """
        origin = np.asarray(origin, dtype=np.float64).reshape(3)
        misses = np.zeros((0, 3)) if miss_directions is None else np.asarray(miss_directions, float)
        return self.segment_voxels(origin, hits, self.miss_ends(origin, misses))

    def segment_voxels(
        self, origin: np.ndarray, hits: np.ndarray, free_ends: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`view_voxels` of rays from ``origin`` (3,) to ``hits`` (N, 3), and of free
        segments from ``origin`` to ``free_ends`` (M, 3) (every voxel they cross, their end's
        included, is free)."""
        s = self.settings
        origin = np.asarray(origin, dtype=np.float64).reshape(3)
        hits = np.asarray(hits, dtype=np.float64).reshape(-1, 3)
        far = np.asarray(free_ends, dtype=np.float64).reshape(-1, 3)
        before_hits = traverse(np.broadcast_to(origin, hits.shape), hits, s.n, s.bound, False)
        carved = traverse(np.broadcast_to(origin, far.shape), far, s.n, s.bound)
        # Each voxel once a view; a voxel both crossed and hit takes the hit (as OctoMap).
        hit = np.zeros(len(self.log_odds), dtype=bool)
        cells = self.voxel_of(hits)
        hit[cells[cells >= 0]] = True
        crossed = np.zeros(len(self.log_odds), dtype=bool)
        for rays in (before_hits, carved):
            crossed[rays[rays >= 0]] = True
        return np.flatnonzero(crossed & ~hit), np.flatnonzero(hit)

    def captured_voxels(
        self, points: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, block: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`view_voxels` of a captured view: rays from the camera centre of ``pose``
        (4, 4) to its ``points`` (N, 3), and along its background blocks
        (:func:`background_directions` of ``block`` pixels) that hit nothing."""
        misses = background_directions(points, pose, intrinsics, block)
        return self.view_voxels(np.asarray(pose)[:3, 3], points, misses)

    def sensed_voxels(
        self,
        points: np.ndarray,
        pose: np.ndarray,
        intrinsics: Intrinsics,
        block: int,
        misses: Misses | None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`view_voxels` of a depth sensor's view: rays from the camera centre of ``pose``
        (4, 4) to its ``points`` (N, 3), and free space only where ``misses`` declares it (None:
        nothing the sensor did not measure is free; a mask: its whole blocks, up to the reach;
        no mask: the blocks without a point, as :meth:`captured_voxels`)."""
        origin = np.asarray(pose, dtype=np.float64)[:3, 3]
        if misses is None:
            return self.segment_voxels(origin, points, np.zeros((0, 3)))
        camera = misses.intrinsics or intrinsics
        if misses.mask is None:
            rays = background_directions(points, pose, camera, block)
        else:
            rays = mask_directions(misses.mask, pose, camera, block)
        if misses.reach is None:
            return self.segment_voxels(origin, points, self.miss_ends(origin, rays))
        # The range is a planar depth: scale the unit directions to unit planar depth.
        camera_z = np.asarray(pose, dtype=np.float64)[:3, 2]
        rays = rays / np.maximum(rays @ camera_z, 1e-12)[:, None]
        # Free up to the range, or to beyond the region's far side when that comes first.
        far = self.miss_ends(origin, rays)
        limit = origin + rays * misses.reach
        shorter = np.linalg.norm(limit - origin, axis=1) < np.linalg.norm(far - origin, axis=1)
        return self.segment_voxels(origin, points, np.where(shorter[:, None], limit, far))

    def apply_view(self, voxels: tuple[np.ndarray, np.ndarray]) -> None:
        """Update the map by a view's :meth:`view_voxels`: misses, then hits."""
        free, occupied = voxels
        self._update(free, log_odds_of(self.settings.p_miss))
        self._update(occupied, log_odds_of(self.settings.p_hit))

    def insert_view(
        self, origin: np.ndarray, hits: np.ndarray, miss_directions: np.ndarray | None = None
    ) -> None:
        """Add one view: rays from ``origin`` (3,) to each of ``hits`` (N, 3), and rays along
        ``miss_directions`` (M, 3) that hit nothing (world units and frame)."""
        self.apply_view(self.view_voxels(origin, hits, miss_directions))

    def _update(self, voxels: np.ndarray, delta: float) -> None:
        s = self.settings
        current = np.nan_to_num(self.log_odds[voxels], nan=0.0)
        self.log_odds[voxels] = np.clip(
            current + delta, log_odds_of(s.clamp_min), log_odds_of(s.clamp_max)
        )

    def labels(self) -> np.ndarray:
        """(n^3,) int8: :data:`UNKNOWN`, :data:`FREE` or :data:`OCCUPIED` per voxel."""
        out = np.full(len(self.log_odds), UNKNOWN, dtype=np.int8)
        known = ~np.isnan(self.log_odds)
        out[known] = np.where(self.log_odds[known] >= 0, OCCUPIED, FREE)
        return out

    def probability(self) -> np.ndarray:
        """(n^3,) occupancy probability per voxel; 0.5 for unknown ones."""
        return 1.0 / (1.0 + np.exp(-np.nan_to_num(self.log_odds, nan=0.0)))

    def centres(self) -> np.ndarray:
        """(n^3, 3) world coordinates of the voxel centres, flat index order."""
        s = self.settings
        axis = (np.arange(s.n) + 0.5) * s.resolution - s.bound
        grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1)
        return grid.reshape(-1, 3)
