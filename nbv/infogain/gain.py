"""Volumetric information gain of candidate views on an occupancy map, by ray casting.

Each candidate casts a grid of rays through its image (``columns`` across and ``3/4`` as many rows,
through the centres of equal image blocks) from its camera centre through the map. Along a ray
the voxels are visited in order; ``p`` is a voxel's occupancy probability (0.5 unknown) and the
*visibility* of a voxel is the product of ``1 - p`` over the voxels before it. The metrics, each
summed over the candidate's rays (Delmerico et al., Autonomous Robots 2018; Isler et al., ICRA
2016):

* ``unobserved``: unknown voxels before the ray's first occupied voxel;
* ``entropy``: occlusion-aware entropy, the sum of visibility times the voxel's binary entropy;
* ``rear_side_voxel``: rays whose first occupied voxel is seen from an unknown voxel, that is
  rays that would see the unobserved back of a captured surface;
* ``rear_side_entropy``: the visibility-weighted entropy of the unknown voxels of those rays;
* ``frontier``: unknown voxels before the first occupied voxel that touch an occupied voxel (of
  their 26 neighbours): the unseen continuation of the captured surface, where the object's
  uncovered surface can be;
* ``proximity_count``: Proximity Count (Isler et al. 2016; Delmerico et al. 2018): unknown voxels
  before the first occupied voxel, each weighted by its proximity to the captured surface,
  ``max(0, 1 - d / PROXIMITY_RANGE)`` for ``d`` the distance between its centre and the nearest
  occupied voxel's (:func:`proximity`);
* ``area_factor``: Vasquez-Gomez et al.'s Area Factor (J. Adv. Robotic Systems 2014, as
  Delmerico et al. 2018 compare it): not a sum over rays. Each ray is classed by the first
  voxel it meets that is occupied or *occplane* (an unknown voxel touching an occupied one:
  the ``frontier`` voxels), or as unobserved when it meets neither; with ``x_occ`` and
  ``x_occplane`` the fractions of the candidate's rays of the first two classes, the view scores
  ``area_factor(x_occ, AREA_OCCUPIED) + area_factor(x_occplane, AREA_OCCPLANE)``
  (:func:`area_factor`, in [0, 2]): a view is best when it sees a set share of the captured
  surface (for registration) and of its unseen continuation.

Choices in the two published metrics, where our map differs from theirs. Their implementation
(Delmerico et al.'s ``ig_active_reconstruction``) marks the unknown voxels *behind* each captured
point along its capture ray up to a range (an occlusion pass of the map update), and measures a
voxel's proximity as its distance behind the surface along that ray; Area Factor's occplane
voxels are those marked voxels. This map keeps no capture rays, so both read the occupied voxels
instead: proximity is the Euclidean distance to the nearest occupied voxel, and the occplane is
the unknown layer touching an occupied voxel. The voxel just behind a captured surface point
is both in their shadow and in our layer; our layer also holds the unknown voxels beside the
surface's edges, where the object continues unseen. The weight ``1 - d / range`` is theirs
``range - d`` over ``range`` (the same ranking). The desired fractions are the ones their
implementation ships (0.2 occupied, 0.8 occplane).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy import ndimage

from nbv.geometry.camera import Intrinsics, rays_through
from nbv.infogain.occupancy import OccupancyMap, OccupancySettings
from nbv.infogain.raytrace import traverse

#: The metrics of :func:`view_gains`.
METRICS = ("unobserved", "entropy", "rear_side_voxel", "rear_side_entropy", "frontier",
           "area_factor", "proximity_count")  # fmt: skip
# The kernel's branch for each metric: frontier and proximity_count count like unobserved, with
# their own weights; area_factor classes each ray (branch 4).
_KERNEL = {"unobserved": 0, "entropy": 1, "rear_side_voxel": 2, "rear_side_entropy": 3,
           "frontier": 0, "area_factor": 4, "proximity_count": 0}  # fmt: skip
#: Proximity Count's range, object units (the object fits in radius 0.5): an unknown voxel this
#: far or farther from every occupied voxel weighs 0; 5 voxels at the default 2 cm.
PROXIMITY_RANGE = 0.1
#: Area Factor's desired fraction of a view's rays that meet the captured surface first.
AREA_OCCUPIED = 0.2
#: Area Factor's desired fraction of a view's rays that meet the occplane first.
AREA_OCCPLANE = 0.8
#: :func:`ray_gains`' classes of ``area_factor`` rays.
UNOBSERVED_RAY, OCCUPIED_RAY, OCCPLANE_RAY = 0, 1, 2


def candidate_rays(intrinsics: Intrinsics, columns: int) -> np.ndarray:
    """Camera-frame directions (unit z) of a ``columns x rows`` grid of rays through the image,
    ``rows`` in proportion to the image's aspect: ``(columns * rows, 3)``."""
    rows = max(1, round(columns * intrinsics.height / intrinsics.width))
    u = ((np.arange(columns) + 0.5) * intrinsics.width / columns).astype(int)
    v = ((np.arange(rows) + 0.5) * intrinsics.height / rows).astype(int)
    uu, vv = np.meshgrid(u, v)
    return rays_through(intrinsics, uu.ravel(), vv.ravel())


@numba.njit(cache=True, nogil=True)
def _ray_gains(voxels, log_odds, weights, metric, depth):  # pragma: no cover - compiled
    """Per-ray gains of kernel branch ``metric`` (see :func:`ray_gains`), one pass along each
    row; branch 0 sums ``weights`` of the unknown voxels before the first occupied one, at most
    ``depth`` of them (0: all); branch 4 gives the ray's class, the first voxel of positive
    ``weights`` (occplane: 2) or occupied (1) it meets, else 0."""
    out = np.zeros(len(voxels))
    for r in range(len(voxels)):
        visibility, unknown_before, entropy_before, entropy_all = 1.0, 0.0, 0.0, 0.0
        previous_unknown, rear, blocked = False, False, False
        ray_class = 0.0
        for k in range(voxels.shape[1]):
            v = voxels[r, k]
            if v < 0:
                break
            value = log_odds[v]
            unknown = np.isnan(value)
            if metric == 4:
                if weights[v] > 0:
                    ray_class = 2.0
                    break
                if not unknown and value >= 0:
                    ray_class = 1.0
                    break
                continue
            if not unknown and value >= 0 and not blocked:  # the first occupied voxel
                blocked, rear = True, k > 0 and previous_unknown
                if metric != 1:
                    break
            previous_unknown = unknown
            if unknown and not blocked:
                unknown_before += weights[v]
            if metric == 0 or metric == 2:  # counts: no probabilities needed
                continue
            p = 0.5 if unknown else 1.0 / (1.0 + np.exp(-value))
            q = min(max(p, 1e-12), 1.0 - 1e-12)
            h = -(q * np.log2(q) + (1.0 - q) * np.log2(1.0 - q))
            entropy_all += visibility * h
            if unknown and not blocked:
                entropy_before += visibility * h
            visibility *= 1.0 - p
        if metric == 0:
            out[r] = min(unknown_before, depth) if depth > 0 else unknown_before
        elif metric == 1:
            out[r] = entropy_all
        elif metric == 2:
            out[r] = 1.0 if rear else 0.0
        elif metric == 4:
            out[r] = ray_class
        else:
            out[r] = entropy_before if rear else 0.0
    return out


def ray_gains(
    occupancy: OccupancyMap, voxels: np.ndarray, metric: str, depth: int = 0
) -> np.ndarray:
    """The gain of each ray from its voxels: ``(R, S)`` flat indices padded with -1 in, ``(R,)``
    float out (see the module docstring for ``metric``; ``depth`` caps the ``unobserved`` and
    ``frontier`` count of a ray, 0 for no cap). For ``area_factor``, whose score is not a sum
    over rays, each ray's class: :data:`UNOBSERVED_RAY`, :data:`OCCUPIED_RAY` or
    :data:`OCCPLANE_RAY` (:func:`view_gains` turns them into the score)."""
    if metric not in METRICS:
        raise ValueError(f"metric={metric!r}: must be one of {', '.join(METRICS)}")
    if metric in ("frontier", "area_factor"):
        weights = frontier(occupancy).astype(np.float64)
    elif metric == "proximity_count":
        weights = proximity(occupancy)
    else:
        weights = np.ones(len(occupancy.log_odds))
    cap = depth if metric in ("unobserved", "frontier") else 0
    voxels = np.ascontiguousarray(voxels)
    return _ray_gains(voxels, occupancy.log_odds, weights, _KERNEL[metric], cap)


def area_factor(x: np.ndarray | float, desired: float) -> np.ndarray:
    """Vasquez-Gomez et al.'s area factor of a fraction ``x`` in [0, 1] (array or scalar): the
    cubic that rises from 0 at ``x = 0`` to 1 at ``x = desired`` and falls back to 0 at
    ``x = 1``, flat at all three (``3 s^2 - 2 s^3`` of ``s = x / desired`` below, of
    ``s = (1 - x) / (1 - desired)`` above). ``desired`` in (0, 1)."""
    x = np.asarray(x, dtype=np.float64)
    s = np.where(x <= desired, x / desired, (1.0 - x) / (1.0 - desired))
    return 3.0 * s**2 - 2.0 * s**3


def proximity(occupancy: OccupancyMap, distance_range: float = PROXIMITY_RANGE) -> np.ndarray:
    """(n^3,) Proximity Count's weight of each voxel: ``max(0, 1 - d / distance_range)`` for an
    unknown voxel, ``d`` the distance (object units) between its centre and the nearest occupied
    voxel's; 0 for known voxels, and for all when nothing is occupied.

    The Euclidean distance transform runs on the occupied voxels' bounding box grown by the
    range (beyond it every weight is 0): 27 ms on the whole default grid, less on the box."""
    s = occupancy.settings
    n, log_odds = s.n, occupancy.log_odds
    weights = np.zeros(len(log_odds))
    occupied = (log_odds >= 0).reshape(n, n, n)  # NaN (unknown) compares False
    if not occupied.any():
        return weights
    reach = math.ceil(distance_range / s.resolution)
    cells = np.argwhere(occupied)
    lo = np.maximum(cells.min(axis=0) - reach, 0)
    hi = np.minimum(cells.max(axis=0) + reach + 1, n)
    box = tuple(slice(a, b) for a, b in zip(lo, hi, strict=True))
    distance = ndimage.distance_transform_edt(~occupied[box], sampling=s.resolution)
    near = np.zeros((n, n, n))
    near[box] = np.maximum(0.0, 1.0 - distance / distance_range)
    weights = near.ravel()
    weights[~np.isnan(log_odds)] = 0.0
    return weights


def frontier(occupancy: OccupancyMap) -> np.ndarray:
    """(n^3,) bool: the unknown voxels with an occupied voxel among their 26 neighbours.

    The occupied voxels are dilated by the 3 x 3 x 3 cube as three one-voxel dilations, one
    along each axis (the cube is their product): six shifted ORs of the boolean grid, about
    a tenth of the cost of marking each occupied voxel's 27 neighbours by index."""
    n = occupancy.settings.n
    log_odds = occupancy.log_odds
    near = (log_odds >= 0).reshape(n, n, n)
    for axis in range(3):
        grown = near.copy()
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        grown[tuple(lo)] |= near[tuple(hi)]
        grown[tuple(hi)] |= near[tuple(lo)]
        near = grown
    return near.ravel() & np.isnan(log_odds)


def candidate_segments(
    poses: np.ndarray, intrinsics: Intrinsics, columns: int, settings: OccupancySettings
) -> tuple[np.ndarray, np.ndarray]:
    """Every candidate's rays (:func:`candidate_rays`) as segments from its camera centre to
    beyond the map's far corner: ``(origins, ends)``, each ``(C R, 3)``, candidate after
    candidate."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    rays = candidate_rays(intrinsics, columns)
    reach = 2.0 * math.sqrt(3.0) * settings.bound
    origins = np.repeat(poses[:, :3, 3], len(rays), axis=0)
    directions = np.einsum("cij,rj->cri", poses[:, :3, :3], rays).reshape(-1, 3)
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return origins, origins + directions * (np.linalg.norm(origins, axis=1, keepdims=True) + reach)


def candidate_voxels(
    poses: np.ndarray, intrinsics: Intrinsics, columns: int, settings: OccupancySettings
) -> np.ndarray:
    """The voxels of every candidate's rays (:func:`candidate_segments`) through the map:
    ``(C, R, S)`` flat indices padded with -1. They depend on the poses and the grid only, so
    a planner computes them once per viewspace."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    origins, ends = candidate_segments(poses, intrinsics, columns, settings)
    voxels = traverse(origins, ends, settings.n, settings.bound)
    return voxels.reshape(len(poses), -1, voxels.shape[1])


def view_gains(
    occupancy: OccupancyMap, voxels: np.ndarray, metric: str = "unobserved", depth: int = 0
) -> np.ndarray:
    """Information gain of each candidate view on the map: the sum of its rays' gains
    (:func:`ray_gains`).

    Args:
        occupancy: the map of the captured views.
        voxels: (C, R, S) from :func:`candidate_voxels` on the map's settings.
        metric: one of :data:`METRICS`.
        depth: the ``unobserved`` and ``frontier`` counts of a ray stop at this many voxels
            (0: no cap).

    Returns:
        (C,) float64 gains: for ``area_factor`` the view's area factor (in [0, 2], from the
        fractions of its rays of each class), for the others the sum over its rays.
    """
    c, r, s = voxels.shape
    gains = ray_gains(occupancy, voxels.reshape(c * r, s), metric, depth).reshape(c, r)
    if metric == "area_factor":
        occupied = (gains == OCCUPIED_RAY).mean(axis=1)
        occplane = (gains == OCCPLANE_RAY).mean(axis=1)
        return area_factor(occupied, AREA_OCCUPIED) + area_factor(occplane, AREA_OCCPLANE)
    return gains.sum(axis=1)
