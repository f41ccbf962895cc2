"""Convex hulls of clouds of any rank: volume and vertices (Qhull through scipy)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from nbv.geometry.clouds import as_cloud

#: Principal extents of a cloud below this fraction of the largest count as zero: the cloud is
#: flat, colinear or a single point and its hull has no volume.
_RANK_RTOL = 1e-7


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


class QhullFailure(ValueError):
    """Qhull failed on a cloud that is not degenerate (it passed the rank test): its volume is
    unknown, not zero. The message holds Qhull's first line and the cloud's size."""


def _hull(points: np.ndarray) -> ConvexHull | None:
    """Qhull's 3-D hull of a float64 ``(N, 3)`` cloud, or None when it has no volume.

    Raises:
        QhullFailure: Qhull refused a cloud of full rank.
    """
    if len(points) < 4:
        return None
    _, _, rank = _principal_frame(points)
    if rank < 3:
        return None
    try:
        return ConvexHull(points)
    except QhullError as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else "QhullError"
        raise QhullFailure(f"Qhull failed on {len(points)} points of full rank: {first}") from None


def hull_volume(points: np.ndarray) -> float:
    """Volume of the convex hull of an ``(N, 3)`` cloud (Qhull), in cubed cloud units.

    Degenerate input (fewer than 4 points, duplicates only, colinear or flat points, an empty
    cloud) has no volume and gives 0.0; it never raises for those.

    Raises:
        QhullFailure: Qhull failed on a cloud that is not degenerate (its volume is unknown,
            which is not the same as flat).
        ValueError: non-finite values.
    """
    hull = _hull(as_cloud(points, "points"))
    return 0.0 if hull is None else float(hull.volume)


def hull_volume_vertices(points: np.ndarray) -> tuple[float, np.ndarray]:
    """:func:`hull_volume` and :func:`hull_vertices` of an ``(N, 3)`` cloud from one Qhull run:
    ``(volume, (K, 3) float64 vertices)``.

    Raises:
        QhullFailure: as :func:`hull_volume`.
        ValueError: non-finite values.
    """
    pts = as_cloud(points, "points")
    hull = _hull(pts)
    if hull is None:
        return 0.0, hull_vertices(pts)
    return float(hull.volume), pts[hull.vertices]


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
