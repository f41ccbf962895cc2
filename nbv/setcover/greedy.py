"""Greedy maximum coverage (the paper's Algorithm 3) on packed bit sets."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from nbv.geometry.viewspace import spread_views
from nbv.utils.bits import popcount_rows

#: Number of views a plan picks (the paper's 9 after the start view).
DEFAULT_N_ITER = 9


def pack_sets(sets: np.ndarray) -> np.ndarray:
    """Bit rows of a ``(V, n)`` bool set matrix: ``(V, ceil(n / 64))`` uint64, zero padding.

    The bytes of row ``v`` are ``np.packbits(sets[v], bitorder="little")`` padded with zeros to
    whole 64-bit words.
    """
    sets = _as_sets(sets)
    n_views, n = sets.shape
    n_bytes = 8 * (-(-n // 64))
    packed = np.zeros((n_views, n_bytes), dtype=np.uint8)
    packed[:, : (n + 7) // 8] = np.packbits(sets, axis=1, bitorder="little")
    return packed.view(np.uint64)


def _as_sets(sets: np.ndarray) -> np.ndarray:
    arr = np.asarray(sets)
    if arr.ndim != 2:
        raise ValueError(f"sets must be a (V, n) boolean matrix, got shape {arr.shape}")
    if arr.dtype != np.bool_:
        if not (np.issubdtype(arr.dtype, np.integer) and np.isin(arr, (0, 1)).all()):
            raise ValueError(f"sets must hold booleans (or 0/1 integers), got dtype {arr.dtype}")
        arr = arr.astype(bool)
    return arr


def as_exclude(exclude: Iterable[int], n_views: int) -> np.ndarray:
    idx = np.asarray(list(exclude), dtype=np.int64).reshape(-1)
    bad = idx[(idx < 0) | (idx >= n_views)]
    if bad.size:
        raise ValueError(f"exclude holds view indices {bad.tolist()} outside [0, {n_views})")
    return np.unique(idx)


def _as_positions(positions: np.ndarray, n_views: int) -> np.ndarray:
    arr = np.asarray(positions, dtype=np.float64)
    if arr.shape != (n_views, 3):
        raise ValueError(f"positions must have shape ({n_views}, 3), one per view, got {arr.shape}")
    norm = np.linalg.norm(arr, axis=1)
    if not (np.all(np.isfinite(arr)) and np.all(norm > 0.0)):
        raise ValueError("positions must be finite and away from the origin (they give directions)")
    return arr / norm[:, None]


def greedy_packed(
    rows: np.ndarray,
    n_iter: int,
    exclude: Iterable[int] = (),
    positions: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
) -> tuple[list[int], list[int], int]:
    """Greedy maximum coverage on bit rows, see :func:`greedy_max_coverage`.

    Args:
        rows: ``(V, W)`` uint64 bit rows (:func:`pack_sets`); not modified.
        n_iter: number of views to pick.
        exclude: indices of views already visited.
        positions: ``(V, 3)`` view positions, world units, or None (see
            :func:`greedy_max_coverage`).
        rng: the generator of the spread-out fill's tie-break, or None (see
            :func:`greedy_max_coverage`).

    Returns:
        ``(views, gains, n_covered)``: as :func:`greedy_max_coverage`, plus the number of
        elements covered by the excluded and chosen views together.
    """
    rows = np.asarray(rows)
    if rows.ndim != 2 or rows.dtype != np.uint64:
        raise ValueError(f"rows must be a (V, W) uint64 array, got {rows.dtype} {rows.shape}")
    n_views = rows.shape[0]
    excluded = as_exclude(exclude, n_views)
    directions = None if positions is None else _as_positions(positions, n_views)
    if isinstance(n_iter, bool) or not isinstance(n_iter, int | np.integer) or n_iter < 0:
        raise ValueError(f"n_iter must be an integer >= 0, got {n_iter!r}")
    if n_iter > n_views - len(excluded):
        raise ValueError(
            f"n_iter={n_iter} exceeds the {n_views - len(excluded)} views left to choose from "
            f"({n_views} views, {len(excluded)} excluded)"
        )
    n_covered = 0
    if len(excluded):
        seen = np.bitwise_or.reduce(rows[excluded], axis=0)
        n_covered = int(popcount_rows(seen[None])[0])
        # Algorithm 3 from the start: what a visited view covers counts for no other view.
        left = rows & ~seen
    else:
        left = rows.copy()
    counts = popcount_rows(left)
    closed = np.zeros(n_views, dtype=bool)
    closed[excluded] = True
    counts[closed] = -1
    views: list[int] = []
    gains: list[int] = []
    while len(views) < n_iter:
        best = int(np.argmax(counts))  # the first maximum: ties go to the lowest index
        gain = int(counts[best])
        if gain <= 0:
            # Nothing left to cover: every remaining pick gains 0. In index order they would
            # bunch up (neighbouring indices are neighbouring views), so spread them out.
            count = n_iter - len(views)
            if directions is None:
                rest = np.flatnonzero(~closed)[:count].tolist()
            else:
                rest = spread_views(directions, closed, count, rng)
            views += rest
            gains += [0] * len(rest)
            break
        views.append(best)
        gains.append(gain)
        n_covered += gain
        closed[best] = True
        # Algorithm 3: remove the new elements from every set. Only the words that hold new
        # elements change; samples grouped by triangle make those few after the first picks.
        words = np.flatnonzero(left[best])
        if 2 * len(words) > left.shape[1]:
            left &= ~left[best]
            counts = popcount_rows(left)
        else:
            overlap = left[:, words]
            overlap &= left[best, words]
            counts -= popcount_rows(overlap)
            left[:, words] ^= overlap
        counts[closed] = -1
    return views, gains, n_covered


def greedy_max_coverage(
    sets: np.ndarray,
    n_iter: int = DEFAULT_N_ITER,
    exclude: Iterable[int] = (),
    positions: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
) -> tuple[list[int], list[int]]:
    """Greedy maximum coverage (the paper's Algorithm 3).

    Before the first pick, the elements of the excluded views (the views already visited, such
    as the start view) are removed from every set: the plan continues from what those views saw,
    as the paper plans from the start view's cloud. Then, ``n_iter`` times: pick the not yet
    chosen, not excluded view whose set holds the most elements (ties: the lowest index) and
    remove its elements from every set. The result is within ``1 - 1/e`` of the best ``n_iter``
    views.

    Once no view has anything new, the remaining picks (gain 0) fill the plan up to ``n_iter``
    views: without ``positions``, the lowest indices first; with ``positions``, spread out:
    each is the remaining view whose smallest angle (seen from the origin, which the cameras
    look at) to the excluded and already chosen views is largest
    (:func:`nbv.geometry.viewspace.spread_views`; views tied for it: one at random with
    ``rng``, else the lowest index). The fill alone uses ``rng``: the covering picks never do.

    Args:
        sets: ``(V, n)`` bool (or 0/1): ``sets[v, i]`` is True when view ``v`` covers element
            ``i``.
        n_iter: number of views to choose, ``<= V - len(exclude)``.
        exclude: indices of views that are already visited: never chosen, their elements count
            as covered.
        positions: ``(V, 3)`` view positions, world units (any non-zero distance from the
            origin), for the spread-out zero-gain picks; None picks them by index.
        rng: the generator of the spread-out fill's tie-break; None: the lowest index.

    Returns:
        ``(views, gains)``: the ``n_iter`` chosen view indices in order, and the number of
        elements each newly covered (its marginal gain; non-increasing).
    """
    views, gains, _ = greedy_packed(pack_sets(sets), n_iter, exclude, positions, rng)
    return views, gains
