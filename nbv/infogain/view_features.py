"""What a candidate view would see on the occupancy map, as a few numbers a learned scorer reads.

:mod:`nbv.infogain.gain` sums one metric over a candidate's rays. Here one pass
along each ray (stopping at its first occupied voxel) records several, and the candidate's
sums are put on a common scale across the candidates of a decision, beside where the candidate
lies relative to the captured views. :mod:`nbv.infogain.gain_scorer` weighs them.

Per ray (the columns of :func:`ray_features`):

0. ``unobserved``: unknown voxels before the first occupied one (``ig``'s default metric);
1. ``touches_unknown``: 1 when the ray crosses any unknown voxel before an occupied one;
2. ``meets_surface``: 1 when the ray reaches an occupied voxel;
3. ``rear``: 1 when the voxel before its first occupied one is unknown (the rear side of a
   captured surface, Isler et al. 2016);
4. ``frontier``: unknown voxels before the first occupied one that touch an occupied voxel;
5. ``unobserved_capped``: ``unobserved`` counted to at most 4 voxels (the unknown *area* a ray
   faces rather than the volume);
6. ``open``: 1 when the ray crosses unknown voxels and leaves the map without meeting an
   occupied one (nothing captured behind what it would see);
7. ``free_run``: the free voxels the ray crosses before its first unknown one, over the grid's
   voxels across (how far the unknown region is; 0 for a ray without unknown voxels).
"""

from __future__ import annotations

import numba
import numpy as np

from nbv.geometry.viewspace import angular_distances
from nbv.infogain.gain import frontier
from nbv.infogain.occupancy import OccupancyMap

#: Names of the per-ray columns (module docstring), summed over a candidate's rays.
RAY_FEATURES = ("unobserved", "touches_unknown", "meets_surface", "rear", "frontier",
                "unobserved_capped", "open", "free_run")  # fmt: skip
#: Where the candidate lies, in units of 180 degrees, and how far the episode is.
POSITION_FEATURES = ("angle_nearest", "angle_last", "angle_start", "views_taken")
#: Every column of :func:`view_features`, in order.
FEATURES = tuple(f"{name}_relative" for name in RAY_FEATURES) + POSITION_FEATURES
#: ``views_taken`` is the number of captured views over this (an episode's 10 views).
EPISODE_SCALE = 10.0
_CAP = 4


@numba.njit(cache=True, nogil=True)
def _ray_features(voxels, log_odds, near_occupied, n):  # pragma: no cover - compiled
    """(R, 8) per-ray features of the module docstring, one pass along each row."""
    out = np.zeros((len(voxels), 8))
    for r in range(len(voxels)):
        unknown, near, free_run = 0.0, 0.0, 0.0
        previous_unknown, meets = False, False
        for k in range(voxels.shape[1]):
            v = voxels[r, k]
            if v < 0:
                break
            value = log_odds[v]
            if np.isnan(value):
                unknown += 1.0
                near += near_occupied[v]
                previous_unknown = True
                continue
            if value >= 0:
                meets = True
                break
            if unknown == 0:
                free_run += 1.0
            previous_unknown = False
        out[r, 0] = unknown
        out[r, 1] = 1.0 if unknown > 0 else 0.0
        out[r, 2] = 1.0 if meets else 0.0
        out[r, 3] = 1.0 if meets and previous_unknown else 0.0
        out[r, 4] = near
        out[r, 5] = min(unknown, 4.0)
        out[r, 6] = 1.0 if unknown > 0 and not meets else 0.0
        out[r, 7] = free_run / n if unknown > 0 else 0.0
    return out


def ray_features(occupancy: OccupancyMap, voxels: np.ndarray) -> np.ndarray:
    """Per-ray features (module docstring) of ``(R, S)`` flat voxel indices padded with -1:
    ``(R, len(RAY_FEATURES))`` float64."""
    near = frontier(occupancy).astype(np.float64)
    return _ray_features(
        np.ascontiguousarray(voxels), occupancy.log_odds, near, float(occupancy.settings.n)
    )


def view_features(
    occupancy: OccupancyMap,
    voxels: np.ndarray,
    positions: np.ndarray,
    order: list[int],
    candidates: np.ndarray,
) -> np.ndarray:
    """The scorer's input for each candidate of one decision.

    Args:
        occupancy: the map of the captured views.
        voxels: (C, R, S) rays' voxels of the candidates (:func:`candidate_voxels` rows of
            ``candidates``).
        positions: (V, 3) camera centres of the whole viewspace, world units.
        order: the captured views in order (indices into ``positions``), at least one.
        candidates: (C,) indices into ``positions`` of the views to score.

    Returns:
        (C, len(FEATURES)) float64: each ray feature summed over the candidate's rays and
        divided by its largest value among ``candidates`` (0 where all are 0), then the
        candidate's angle to the nearest, the last and the first captured view over 180
        degrees, and the captured views over :data:`EPISODE_SCALE`.
    """
    c, r, s = voxels.shape
    sums = ray_features(occupancy, voxels.reshape(c * r, s)).reshape(c, r, -1).sum(axis=1)
    top = sums.max(axis=0)
    relative = np.divide(sums, top, out=np.zeros_like(sums), where=top > 0)
    angles = angular_distances(positions[candidates], positions[order]) / 180.0
    taken = np.full((c, 1), len(order) / EPISODE_SCALE)
    return np.hstack(
        [relative, angles.min(axis=1, keepdims=True), angles[:, -1:], angles[:, :1], taken]
    )


def unvisited_features(
    occupancy: OccupancyMap, voxels: np.ndarray, positions: np.ndarray, order: list[int]
) -> np.ndarray:
    """:func:`view_features` of every view of a viewspace that ``order`` has not captured.

    Args:
        occupancy: the map of the captured views.
        voxels: (V, R, S) rays' voxels of every view of the viewspace.
        positions: (V, 3) their camera centres, world units.
        order: the captured views in order (indices into ``positions``), at least one.

    Returns:
        (V, len(FEATURES)) float64; the rows of the captured views are zeros.
    """
    open_ = np.setdiff1d(np.arange(len(positions)), order)
    out = np.zeros((len(positions), len(FEATURES)))
    out[open_] = view_features(occupancy, voxels[open_], positions, order, open_)
    return out
