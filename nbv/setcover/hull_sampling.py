"""The hull of a partial cloud and points drawn on it uniformly by area."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from nbv.geometry.clouds import as_cloud

#: Number of hull samples of the paper.
DEFAULT_N_SAMP = 16384


#: A hull whose volume is below this fraction of its bounding box's is flat.
_FLAT_RTOL = 1e-9


def convex_hull(points: np.ndarray) -> ConvexHull:
    """Qhull's convex hull of a cloud that has volume.

    Args:
        points: ``(N, 3)`` cloud, any float dtype, finite.

    Returns:
        ``scipy.spatial.ConvexHull``: triangles in ``simplices``, outward unit normals and offsets
        in ``equations`` (``n . x + d <= 0`` inside).

    Raises:
        ValueError: for fewer than 4 points or a flat, colinear or single-point cloud (its hull has
            no volume, so there is nothing to sample views on).
    """
    pts = as_cloud(points, "points")
    if len(pts) < 4:
        raise ValueError(f"points has {len(pts)} points; a convex hull with volume needs >= 4")
    try:
        hull = ConvexHull(pts)
    except QhullError as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else "QhullError"
        raise ValueError(
            f"the convex hull of points ({len(pts)} points) has no volume: the cloud is flat, "
            f"colinear or a single point (Qhull: {first})"
        ) from None
    if not hull.volume > _FLAT_RTOL * float(np.prod(np.ptp(pts, axis=0))):
        raise ValueError(
            f"the convex hull of points ({len(pts)} points) has no volume "
            f"({hull.volume:.3g}): the cloud is flat"
        )
    return hull


def _as_rng(rng: np.random.Generator | int) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, int | np.integer) and not isinstance(rng, bool):
        return np.random.default_rng(int(rng))
    raise ValueError(f"rng must be a numpy Generator or an integer seed, got {rng!r}")


def sample_on_hull(
    hull: ConvexHull, n_samp: int, rng: np.random.Generator | int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points drawn uniformly by area on the triangles of a hull, see :func:`sample_hull`."""
    if isinstance(n_samp, bool) or not isinstance(n_samp, int | np.integer) or n_samp < 1:
        raise ValueError(f"n_samp must be a positive integer, got {n_samp!r}")
    gen = _as_rng(rng)
    tri = hull.points[hull.simplices]  # (F, 3, 3)
    edge1, edge2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    area = 0.5 * np.linalg.norm(np.cross(edge1, edge2), axis=1)
    # Multinomial counts then uniform points inside each triangle: the same distribution as n
    # independent area-weighted draws, with the samples grouped by triangle (face ids sorted),
    # which lets the analytic visibility decide whole triangles at once.
    counts = gen.multinomial(n_samp, area / area.sum())
    face = np.repeat(np.arange(len(area)), counts)
    # Uniform on a triangle: sqrt of one uniform for the distance from the first corner.
    s = np.sqrt(gen.random(n_samp))
    r2 = gen.random(n_samp)
    # One row-major repeat of everything a triangle's samples need (faster than gathers).
    per_face = np.concatenate([tri[:, 0], edge1, edge2, hull.equations[:, :3]], axis=1)
    rows = np.repeat(per_face, counts, axis=0)
    samples = rows[:, 0:3] + (s * (1.0 - r2))[:, None] * rows[:, 3:6]
    samples += (s * r2)[:, None] * rows[:, 6:9]
    return samples, np.ascontiguousarray(rows[:, 9:12]), face


def sample_hull(
    points: np.ndarray, n_samp: int = DEFAULT_N_SAMP, rng: np.random.Generator | int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Draw points uniformly by area on the convex hull of a cloud.

    Args:
        points: ``(N, 3)`` cloud with volume (see :func:`convex_hull`).
        n_samp: number of samples ``n``.
        rng: numpy Generator or integer seed.

    Returns:
        ``(samples, normals, face_ids)``: ``(n, 3)`` float64 points on the hull, ``(n, 3)``
        float64 OUTWARD unit normals of their facets, ``(n,)`` int64 index of the triangle of
        ``ConvexHull.simplices`` each sample lies on, in non-decreasing order (samples come
        grouped by triangle).

    Raises:
        ValueError: when the hull has no volume (see :func:`convex_hull`).
    """
    return sample_on_hull(convex_hull(points), n_samp, rng)


def cameras_inside(hull: ConvexHull, positions: np.ndarray) -> np.ndarray:
    """Which camera centres lie inside a hull (on its boundary counts as inside).

    The analytic view simulation assumes every camera outside the hull it plans on: a camera
    inside sees the hull's faces from behind and its view set is meaningless.

    Args:
        hull: from :func:`convex_hull`.
        positions: (V, 3) camera centres, the hull's units.

    Returns:
        (V,) bool.
    """
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    signed = positions @ hull.equations[:, :3].T + hull.equations[:, 3]
    return (signed <= 1e-12).all(axis=1)
