"""Voxel traversal of line segments through a cubic grid (Amanatides and Woo 1987), vectorised
over the segments.

The grid is the cube ``[-bound, bound]^3`` cut into ``n^3`` voxels of edge ``2 bound / n``; its
voxel faces sit at multiples of the edge when ``bound`` is one, as OctoMap's keys do. Voxel
``(i, j, k)`` has the flat index ``(i n + j) n + k``, ``i`` along x.
"""

from __future__ import annotations

import numba
import numpy as np


def flat_index(ijk: np.ndarray, n: int) -> np.ndarray:
    """Flat voxel indices ``(i n + j) n + k`` of ``(..., 3)`` integer voxel coordinates."""
    return (ijk[..., 0] * n + ijk[..., 1]) * n + ijk[..., 2]


def clip_to_box(origins: np.ndarray, deltas: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Segment parameters ``(t_in, t_out)`` (each ``(R,)``, 0 at the origin, 1 at the end) of
    the part of each segment inside the box ``[0, n]^3`` of grid coordinates; ``t_in >= t_out``
    for a segment that misses it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / deltas
        ta = (0.0 - origins) * inv
        tb = (n - origins) * inv
    # A coordinate that does not change keeps the segment in the slab for all t, or never.
    inside = (origins >= 0) & (origins <= n)
    lo = np.where(deltas == 0, np.where(inside, -np.inf, np.inf), np.minimum(ta, tb))
    hi = np.where(deltas == 0, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb))
    return np.maximum(lo.max(axis=1), 0.0), np.minimum(hi.min(axis=1), 1.0)


@numba.njit(cache=True, nogil=True)
def _walk(start, delta, t_in, t_out, n, out):  # pragma: no cover - compiled
    """Amanatides-Woo from ``start + t_in delta`` to ``start + t_out delta`` (grid units) for
    every row; writes the flat voxel indices into ``out`` rows and returns each row's count."""
    counts = np.zeros(len(start), dtype=np.int64)
    for r in range(len(start)):
        if t_in[r] >= t_out[r]:
            continue
        cell = np.empty(3, dtype=np.int64)
        step = np.empty(3, dtype=np.int64)
        t_max = np.empty(3)
        t_delta = np.empty(3)
        for a in range(3):
            p = start[r, a] + t_in[r] * delta[r, a]
            cell[a] = min(max(int(np.floor(p)), 0), n - 1)
            d = delta[r, a]
            if d > 0:
                step[a], t_delta[a] = 1, 1.0 / d
                t_max[a] = t_in[r] + (cell[a] + 1 - p) / d
            elif d < 0:
                step[a], t_delta[a] = -1, -1.0 / d
                t_max[a] = t_in[r] + (cell[a] - p) / d
            else:
                step[a], t_delta[a], t_max[a] = 0, np.inf, np.inf
        k = 0
        while True:
            out[r, k] = (cell[0] * n + cell[1]) * n + cell[2]
            k += 1
            a = 0
            if t_max[1] < t_max[a]:
                a = 1
            if t_max[2] < t_max[a]:
                a = 2
            if t_max[a] >= t_out[r] or k >= out.shape[1]:
                break
            cell[a] += step[a]
            if cell[a] < 0 or cell[a] >= n:
                break
            t_max[a] += t_delta[a]
        counts[r] = k
    return counts


def traverse(
    origins: np.ndarray, ends: np.ndarray, n: int, bound: float, include_end: bool = True
) -> np.ndarray:
    """The voxels each segment passes through inside the grid, in order from its origin.

    Args:
        origins: (R, 3) segment starts, world units (inside or outside the grid).
        ends: (R, 3) segment ends.
        n: voxels along each axis.
        bound: half the grid's edge, world units.
        include_end: keep the voxel holding a segment's end when the end is inside the grid.
            False gives OctoMap's free cells of a measurement: every voxel before the hit's.

    Returns:
        (R, S) int32 flat voxel indices, each row in the order the segment crosses them and
        padded with -1 (S is the longest row, at least 1). A segment through a voxel edge or
        corner takes one of the voxels that meet there.
    """
    origins = np.asarray(origins, dtype=np.float64)
    ends = np.asarray(ends, dtype=np.float64)
    if origins.shape != ends.shape or origins.ndim != 2 or origins.shape[1] != 3:
        raise ValueError(
            f"origins and ends must both be (R, 3), got {origins.shape} and {ends.shape}"
        )
    scale = n / (2.0 * bound)
    start = np.ascontiguousarray((origins + bound) * scale)  # voxel i spans [i, i + 1)
    delta = np.ascontiguousarray((ends - origins) * scale)
    t_in, t_out = clip_to_box(start, delta, n)
    # A segment crosses at most 3 n voxel faces inside the grid.
    out = np.full((len(origins), 3 * n + 1), -1, dtype=np.int32)
    counts = _walk(start, delta, t_in, t_out, n, out)
    if not include_end:
        drop_end_voxels(out, counts, start + delta, t_out, n)
    return out[:, : max(int(counts.max(initial=0)), 1)]


def drop_end_voxels(
    out: np.ndarray, counts: np.ndarray, ends: np.ndarray, t_out: np.ndarray, n: int
) -> None:
    """Blank (-1) the end voxel of every segment that ends inside the grid, in place: it is a
    segment's last voxel there.

    Args:
        out: (R, S) voxel rows of the traversal.
        counts: (R,) voxels in each row.
        ends: (R, 3) segment ends, grid coordinates.
        t_out: (R,) segment parameter where each leaves the grid (>= 1: it ends inside).
        n: voxels along each axis.
    """
    rows = np.flatnonzero((t_out >= 1.0) & (counts > 0))
    end_flat = flat_index(np.clip(np.floor(ends[rows]), 0, n - 1).astype(np.int64), n)
    last = counts[rows] - 1
    hit = out[rows, last] == end_flat
    out[rows[hit], last[hit]] = -1
