"""Scores of a partial cloud against the ground truth: coverage and volumetric information gain.

* **Coverage** is the fraction of ground-truth points that have a partial-cloud point closer than
  ``eps``: a ground-truth point ``g`` is covered when ``min_p |p - g| < eps`` (strict, as PC-NBV's
  code tests the squared distance ``< 5e-5``). ``eps`` defaults to :data:`DEFAULT_EPS` and is a
  setting everywhere.
* Coverage of a *view state* (a set of visited views) is computed from packed per-view coverage bits
  (the dataset key ``views/<viewspace>/coverage``): a ground-truth point is covered by the merged
  cloud exactly when one of the visited views covers it, so OR-ing the visited rows and counting
  bits equals the direct computation on the merged cloud.
* **VIG** (the paper's eq. 6) is ``volume(hull(partial)) / volume(hull(ground truth))``. Because
  ``hull(A | B) = hull(vertices(hull(A)) | vertices(hull(B)))``, the VIG of any view state is
  computed exactly from each view's precomputed hull vertices, far cheaper than the hull of the
  merged cloud.

Units are those of the clouds (the normalised object frame: the object fits in a sphere of radius
0.5). Clouds are ``(N, 3)`` arrays of any float dtype; work is done in float64.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

#: Coverage threshold: PC-NBV tests squared distance < 5e-5, i.e. Euclidean 0.00707.
DEFAULT_EPS = 0.00707

#: Principal extents of a cloud below this fraction of the largest count as zero: the cloud is
#: flat, colinear or a single point and its hull has no volume.
_RANK_RTOL = 1e-7

# Number of set bits of every byte value; a read-only constant, not mutable state.
_POPCOUNT = np.array([bin(i).count("1") for i in range(256)], dtype=np.uint8)
_POPCOUNT.setflags(write=False)


def as_cloud(points: np.ndarray, name: str) -> np.ndarray:
    """``points`` as a float64 ``(N, 3)`` array with finite values, or a clear ValueError."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} holds non-finite values (nan or inf); only finite points allowed")
    return arr


def _as_view_state(view_state: np.ndarray, n_views: int) -> np.ndarray:
    state = np.asarray(view_state)
    if state.shape != (n_views,):
        raise ValueError(f"view_state must have shape ({n_views},), got {state.shape}")
    if state.dtype != np.bool_:
        if not np.isin(state, (0, 1)).all():
            raise ValueError("view_state must hold booleans (or 0/1), got other values")
        state = state.astype(bool)
    return state


# --------------------------------------------------------------------------------------------
# Coverage
# --------------------------------------------------------------------------------------------


def covered_mask(partial: np.ndarray, gt: np.ndarray, eps: float = DEFAULT_EPS) -> np.ndarray:
    """Which ground-truth points have a partial-cloud point closer than ``eps``.

    Args:
        partial: ``(M, 3)`` partial cloud (``M`` may be 0).
        gt: ``(N, 3)`` ground-truth cloud.
        eps: distance threshold (> 0), same unit as the clouds; the test is strict, ``d < eps``.

    Returns:
        ``(N,)`` bool mask.
    """
    partial = as_cloud(partial, "partial")
    gt = as_cloud(gt, "gt")
    if not eps > 0:
        raise ValueError(f"eps must be positive, got {eps}")
    if len(partial) == 0 or len(gt) == 0:
        return np.zeros(len(gt), dtype=bool)
    # cKDTree compares squared distances with eps**2 and returns inf beyond the bound.
    dist, _ = cKDTree(partial).query(gt, k=1, distance_upper_bound=eps)
    return np.isfinite(dist)


def coverage(partial: np.ndarray, gt: np.ndarray, eps: float = DEFAULT_EPS) -> float:
    """Fraction in [0, 1] of the ``(N, 3)`` ground truth covered by the ``(M, 3)`` partial cloud.

    A ground-truth point is covered when a partial point lies at distance ``< eps``. An empty
    partial cloud gives 0.0.
    """
    mask = covered_mask(partial, gt, eps)
    if mask.size == 0:
        raise ValueError("gt is empty: coverage of an empty ground truth is undefined")
    return float(np.count_nonzero(mask)) / mask.size


def coverage_bits(
    view_points: Sequence[np.ndarray], gt: np.ndarray, eps: float = DEFAULT_EPS
) -> np.ndarray:
    """Packed per-view coverage bits (the dataset key ``views/<viewspace>/coverage``).

    Args:
        view_points: ``V`` clouds ``(M_v, 3)``, one per view, at FULL resolution (subsampling
            first would lose covered points).
        gt: ``(N, 3)`` ground-truth cloud.
        eps: distance threshold, see :func:`covered_mask`.

    Returns:
        ``(V, ceil(N / 8))`` uint8: row ``v`` is ``np.packbits(covered_mask(view_v, gt, eps))``
        (big bit order, zero padding).
    """
    gt = as_cloud(gt, "gt")
    rows = [np.packbits(covered_mask(pts, gt, eps)) for pts in view_points]
    if not rows:
        return np.zeros((0, (len(gt) + 7) // 8), dtype=np.uint8)
    return np.stack(rows)


def _check_bits(bits: np.ndarray, n_gt: int) -> None:
    if bits.dtype != np.uint8 or bits.ndim != 2:
        raise ValueError(f"bits must be a (V, B) uint8 array, got {bits.dtype} {bits.shape}")
    if n_gt <= 0 or bits.shape[1] != (n_gt + 7) // 8:
        raise ValueError(
            f"bits have {bits.shape[1]} bytes a view but n_gt={n_gt} needs {(n_gt + 7) // 8}"
        )


def coverage_from_bits(bits: np.ndarray, view_state: np.ndarray, n_gt: int) -> float:
    """Coverage of the merged cloud of the visited views, from packed per-view bits.

    Args:
        bits: ``(V, ceil(n_gt / 8))`` uint8, from :func:`coverage_bits`.
        view_state: ``(V,)`` bool, True for visited views.
        n_gt: number of ground-truth points ``N``.

    Returns:
        Fraction in [0, 1]; 0.0 when no view is visited. Equal to :func:`coverage` of the merged
        clouds of the visited views (computed at the same eps).
    """
    bits = np.asarray(bits)
    _check_bits(bits, n_gt)
    state = _as_view_state(view_state, bits.shape[0])
    selected = bits[state]
    if selected.shape[0] == 0:
        return 0.0
    union = np.bitwise_or.reduce(selected, axis=0)
    return int(_POPCOUNT[union].sum(dtype=np.int64)) / n_gt


def coverage_gains(bits: np.ndarray, view_state: np.ndarray, n_gt: int) -> np.ndarray:
    """Coverage each view would add to the view state (PC-NBV's training target).

    Args:
        bits: ``(V, ceil(n_gt / 8))`` uint8, from :func:`coverage_bits`.
        view_state: ``(V,)`` bool, True for visited views.
        n_gt: number of ground-truth points ``N``.

    Returns:
        ``(V,)`` float64: ``coverage(state + v) - coverage(state)`` for unvisited ``v``, 0 for
        visited views.
    """
    bits = np.asarray(bits)
    _check_bits(bits, n_gt)
    state = _as_view_state(view_state, bits.shape[0])
    if state.any():
        union = np.bitwise_or.reduce(bits[state], axis=0)
    else:
        union = np.zeros(bits.shape[1], dtype=np.uint8)
    # Bits a view covers that the state does not: its gain, counted without a second popcount.
    new = bits & ~union
    gains = _POPCOUNT[new].sum(axis=1, dtype=np.int64) / n_gt
    gains[state] = 0.0
    return gains


# --------------------------------------------------------------------------------------------
# Convex hulls and VIG
# --------------------------------------------------------------------------------------------


def _principal_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Centroid, principal axes (rows of a 3x3, widest first) and numerical rank of a cloud.

    From the 3x3 scatter matrix (an SVD of the whole cloud costs as much as Qhull): it resolves
    extents down to about 1e-8 of the largest, hence the tolerance :data:`_RANK_RTOL`.
    """
    # A matrix-vector product: much faster than points.mean(axis=0) on an (N, 3) array.
    centroid = np.full(len(points), 1.0 / len(points)) @ points
    centred = points - centroid
    eigval, eigvec = np.linalg.eigh(centred.T @ centred)
    spread = np.sqrt(np.clip(eigval[::-1], 0.0, None))
    # Rounding in the centroid leaves spread of order eps * |points| even for identical points.
    noise = 64.0 * np.finfo(np.float64).eps * np.sqrt(len(points)) * np.abs(points).max()
    rank = int(np.count_nonzero(spread > max(_RANK_RTOL * spread[0], noise)))
    return centroid, eigvec[:, ::-1].T, rank


def _hull(points: np.ndarray) -> ConvexHull | None:
    """Qhull's 3-D hull of a float64 ``(N, 3)`` cloud, or None when it has no volume."""
    if len(points) < 4:
        return None
    _, _, rank = _principal_frame(points)
    if rank < 3:
        return None
    try:
        return ConvexHull(points)
    except QhullError:
        # Nearly flat clouds that pass the rank test may still defeat Qhull's initial simplex.
        return None


def hull_volume(points: np.ndarray) -> float:
    """Volume of the convex hull of an ``(N, 3)`` cloud (Qhull), in cubed cloud units.

    Degenerate input (fewer than 4 points, duplicates only, colinear or flat points, an empty
    cloud) has no volume and gives 0.0; it never raises for those. Non-finite values raise a
    ValueError.
    """
    hull = _hull(as_cloud(points, "points"))
    return 0.0 if hull is None else float(hull.volume)


def hull_vertices(points: np.ndarray) -> np.ndarray:
    """Points of an ``(N, 3)`` cloud that span its convex hull: ``(K, 3)`` float64, no duplicates.

    ``hull(hull_vertices(A) | hull_vertices(B)) == hull(A | B)`` for any clouds, which makes
    hulls of view unions cheap. Degenerate clouds keep their lower-dimensional extreme points:
    the 2-D hull vertices of a flat cloud, the two ends of a colinear one, the single point of an
    all-duplicate one. An empty cloud gives ``(0, 3)``.
    """
    pts = as_cloud(points, "points")
    if len(pts) == 0:
        return np.zeros((0, 3))
    centroid, axes, rank = _principal_frame(pts)
    try:
        if rank == 3:
            return pts[ConvexHull(pts).vertices]
        if rank == 2:
            planar = (pts - centroid) @ axes[:2].T
            return pts[ConvexHull(planar).vertices]
    except QhullError:
        return np.unique(pts, axis=0)
    if rank == 1:
        t = (pts - centroid) @ axes[0]
        return pts[[int(np.argmin(t)), int(np.argmax(t))]]
    return pts[:1].copy()


def _gt_volume(gt_volume: float) -> float:
    if not (np.isfinite(gt_volume) and gt_volume > 0):
        raise ValueError(
            f"gt_volume must be a positive finite hull volume, got {gt_volume}: VIG is undefined "
            "for a ground truth whose convex hull has no volume (a flat object)"
        )
    return float(gt_volume)


def vig(partial: np.ndarray, gt: np.ndarray) -> float:
    """Volumetric information gain, the paper's eq. 6: ``hull_volume(partial) / hull_volume(gt)``.

    Args:
        partial: ``(M, 3)`` partial cloud (empty or degenerate gives 0.0).
        gt: ``(N, 3)`` ground-truth cloud.

    Raises:
        ValueError: when the ground truth's hull has no volume (a flat object such as a planar
            mesh): VIG is undefined there.
    """
    gt_vol = hull_volume(gt)
    if gt_vol <= 0.0:
        raise ValueError(
            f"the ground truth's convex hull has no volume ({len(np.asarray(gt))} points, flat, "
            "colinear or degenerate object): VIG is undefined for it"
        )
    return hull_volume(partial) / gt_vol


def view_hull_vertices(view_points: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Hull vertices of each view's cloud: ``V`` arrays ``(K_v, 3)`` float64.

    Computed once per model; :func:`vig_of_state` then needs only these.
    """
    return [hull_vertices(pts) for pts in view_points]


def _state_vertices(hull_verts: Sequence[np.ndarray], state: np.ndarray) -> np.ndarray:
    chosen = [hull_verts[i] for i in np.flatnonzero(state)]
    if not chosen:
        return np.zeros((0, 3))
    return as_cloud(np.concatenate(chosen, axis=0), "hull_verts of the visited views")


def vig_of_state(
    hull_verts: Sequence[np.ndarray], view_state: np.ndarray, gt_volume: float
) -> float:
    """VIG of the merged cloud of the visited views, from per-view hull vertices.

    Args:
        hull_verts: ``V`` arrays ``(K_v, 3)`` from :func:`view_hull_vertices`.
        view_state: ``(V,)`` bool, True for visited views.
        gt_volume: ``hull_volume(gt)``, positive.

    Returns:
        ``hull_volume(union of visited views) / gt_volume``; 0.0 when nothing is visited. Exact:
        equal to :func:`vig` of the merged cloud.

    Cost is one Qhull run on the visited views' hull vertices: about a millisecond for
    polyhedral objects (tens of vertices a view), tens of milliseconds for smooth convex ones,
    where nearly every point of a view is a hull vertex.
    """
    gt_vol = _gt_volume(gt_volume)
    state = _as_view_state(view_state, len(hull_verts))
    return hull_volume(_state_vertices(hull_verts, state)) / gt_vol


def vig_gains(
    hull_verts: Sequence[np.ndarray], view_state: np.ndarray, gt_volume: float
) -> np.ndarray:
    """VIG each view would add to the view state.

    Args:
        hull_verts: ``V`` arrays ``(K_v, 3)`` from :func:`view_hull_vertices`.
        view_state: ``(V,)`` bool, True for visited views.
        gt_volume: ``hull_volume(gt)``, positive.

    Returns:
        ``(V,)`` float64: ``vig_of_state(state + v) - vig_of_state(state)`` for unvisited ``v``,
        0 for visited views. One Qhull run per unvisited view.
    """
    gt_vol = _gt_volume(gt_volume)
    state = _as_view_state(view_state, len(hull_verts))
    # The state's own hull vertices stand in for all its views: fewer points per candidate.
    base = hull_vertices(_state_vertices(hull_verts, state))
    base_volume = hull_volume(base)
    gains = np.zeros(len(hull_verts))
    for v in np.flatnonzero(~state):
        grown = hull_volume(np.concatenate([base, as_cloud(hull_verts[v], "hull_verts")]))
        gains[v] = (grown - base_volume) / gt_vol
    return gains
