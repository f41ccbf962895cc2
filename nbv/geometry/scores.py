"""Scores of a partial cloud against the ground truth: coverage and volumetric information gain.

* **Coverage** is the fraction of ground-truth points that have a partial-cloud point closer than
  ``eps``: a ground-truth point ``g`` is covered when some partial point ``p`` has
  ``sum((p - g)**2) < eps**2``, both sides in float64 (strict). With :data:`DEFAULT_EPS`
  ``= sqrt(5e-5)``, ``eps**2 == 5e-5`` exactly, so this is PC-NBV's test (squared distance
  ``< 5e-5``) bit for bit. ``eps`` is a setting everywhere; every coverage computation (dataset,
  evaluator's prepared meshes, planner, export) goes through :func:`covered_mask`.
* Coverage of a *view state* (a set of visited views) is computed from packed per-view coverage bits
  (the dataset key ``views/<viewspace>/coverage``): a ground-truth point is covered by the merged
  cloud exactly when one of the visited views covers it, so OR-ing the visited rows and counting
  bits equals the direct computation on the merged cloud.
* **VIG** (the paper's eq. 6) is ``volume(hull(partial)) / volume(hull(ground truth))``. Because
  ``hull(A | B) = hull(vertices(hull(A)) | vertices(hull(B)))``, the VIG of any view state is
  computed exactly from each view's precomputed hull vertices, far cheaper than the hull of the
  merged cloud.

Units are those of the clouds (the normalised object frame: the object fits in a sphere of radius
0.5). Clouds are ``(N, 3)`` arrays of any float dtype; work is done in float64."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from nbv.geometry.clouds import as_cloud
from nbv.geometry.hull import hull_vertices, hull_volume
from nbv.utils.bits import popcount, popcount_rows

#: Coverage threshold: PC-NBV tests squared distance < 5e-5, so eps = sqrt(5e-5) =
#: 0.007071067811865475 (in float64 ``DEFAULT_EPS**2 == 5e-5`` exactly). Datasets made before
#: issue 29 used 0.00707, which leaves 2-28 ground-truth points a model between the two.
DEFAULT_EPS = math.sqrt(5e-5)
#: The coverage criterion in words, recorded where a cache must not outlive a change of it.
COVERAGE_TEST = "float64 (dx*dx + dy*dy) + dz*dz < eps*eps"
#: The KD-tree is asked for neighbours up to ``eps * (1 + _QUERY_MARGIN)``: its own rounding
#: (about 1e-16 relative) can then never drop a point the float64 test would cover.
_QUERY_MARGIN = 1e-6
#: Ground-truth points sampled uniformly on each normalised mesh (PC-NBV's 16384).
DEFAULT_N_GT = 16384
#: Points a dataset keeps of each view (a seeded random subset; 0 keeps all). The coverage bits
#: come from the full view; the policies see the kept points.
DEFAULT_POINTS_PER_VIEW = 2048


def _as_view_state(view_state: np.ndarray, n_views: int) -> np.ndarray:
    state = np.asarray(view_state)
    if state.shape != (n_views,):
        raise ValueError(f"view_state must have shape ({n_views},), got {state.shape}")
    if state.dtype != np.bool_:
        if not np.isin(state, (0, 1)).all():
            raise ValueError("view_state must hold booleans (or 0/1), got other values")
        state = state.astype(bool)
    return state


def squared_distances(partial: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Squared distances of paired points, the coverage test's arithmetic.

    Args:
        partial: ``(K, 3)`` float64 points.
        gt: ``(K, 3)`` float64 points, paired row by row with ``partial``.

    Returns:
        ``(K,)`` float64 ``(dx*dx + dy*dy) + dz*dz`` with ``d = partial - gt``, in that order:
        the one formula every coverage decision uses, so a decision never depends on a library's
        internal summation.
    """
    d = partial - gt
    return (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2]


def covered_mask(partial: np.ndarray, gt: np.ndarray, eps: float = DEFAULT_EPS) -> np.ndarray:
    """Which ground-truth points have a partial-cloud point with squared distance ``< eps**2``.

    The decision for ``g`` is exactly ``any(squared_distances(p, g) < eps * eps)`` over the
    partial points ``p``, in float64 (:func:`squared_distances`); a KD-tree only finds the
    candidates.

    Args:
        partial: ``(M, 3)`` partial cloud (``M`` may be 0).
        gt: ``(N, 3)`` ground-truth cloud.
        eps: distance threshold (> 0), same unit as the clouds; the test is strict.

    Returns:
        ``(N,)`` bool mask.
    """
    partial = as_cloud(partial, "partial")
    gt = as_cloud(gt, "gt")
    if not eps > 0:
        raise ValueError(f"eps must be positive, got {eps}")
    if len(partial) == 0 or len(gt) == 0:
        return np.zeros(len(gt), dtype=bool)
    eps_sq = float(eps) * float(eps)
    bound = float(eps) * (1.0 + _QUERY_MARGIN)
    # A sliding-midpoint tree of 64-point leaves: a fifth faster to build and query than the
    # default for a view's 30k points against 16k ground-truth points; any tree gives the same
    # mask, as the decision below is the float64 formula's.
    tree = cKDTree(partial, leafsize=64, balanced_tree=False)
    # The tree's nearest neighbour within the widened bound (index len(partial) when none).
    _, nearest = tree.query(gt, k=1, distance_upper_bound=bound)
    found = nearest < len(partial)
    mask = np.zeros(len(gt), dtype=bool)
    sq = squared_distances(partial[nearest[found]], gt[found])
    mask[found] = sq < eps_sq
    # The tree's nearest may differ in the last bits from the float64 formula's nearest. Only
    # when its squared distance lies in [eps**2, bound**2) could another point still pass: test
    # every candidate of those (rare) ground-truth points.
    unsure = np.flatnonzero(found)[sq >= eps_sq]
    if unsure.size:
        for j, near in zip(unsure, tree.query_ball_point(gt[unsure], bound), strict=True):
            pts = partial[np.asarray(near, dtype=np.intp)]
            sq_near = squared_distances(pts, np.broadcast_to(gt[j], pts.shape))
            mask[j] = bool((sq_near < eps_sq).any())
    return mask


def coverage(partial: np.ndarray, gt: np.ndarray, eps: float = DEFAULT_EPS) -> float:
    """Fraction in [0, 1] of the ``(N, 3)`` ground truth covered by the ``(M, 3)`` partial cloud.

    A ground-truth point is covered when a partial point lies at squared distance ``< eps**2``
    (:func:`covered_mask`). An empty partial cloud gives 0.0.
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
    return int(popcount(union).sum(dtype=np.int64)) / n_gt


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
    gains = popcount_rows(new) / n_gt
    gains[state] = 0.0
    return gains


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
