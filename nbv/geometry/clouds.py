"""Point-cloud helpers: checked ``(N, 3)`` clouds and farthest point sampling."""

from __future__ import annotations

import fpsample
import numpy as np


def as_cloud(points: np.ndarray, name: str) -> np.ndarray:
    """``points`` as a float64 ``(N, 3)`` array with finite values, or a clear ValueError."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} holds non-finite values (nan or inf); only finite points allowed")
    return arr


def farthest_points(points: np.ndarray, n: int) -> np.ndarray:
    """Farthest point sampling (fpsample's bucket QuickFPS): (N, 3) -> (n, 3).

    Exact farthest point sampling; the first point is the first of fpsample's internal kd-tree
    order (``start_idx=0`` indexes that order, not the input), so the result is deterministic.

    Clouds with fewer than ``n`` points are returned whole, then repeated cyclically to ``n``.
    """
    if len(points) <= n:
        return points[np.arange(n) % len(points)]
    # Bucket height 7 was fastest on 10^4-10^5 points; fpsample needs 2**h <= len(points).
    # It runs a third faster on float32 than on float64.
    height = min(7, int(np.log2(len(points))))
    coords = np.ascontiguousarray(points, dtype=np.float32)
    return points[fpsample.bucket_fps_kdline_sampling(coords, n, height, start_idx=0)]


def near(captured: np.ndarray, points: np.ndarray, distance: float) -> np.ndarray:
    """(M,) bool: each of ``points`` (M, 3) lies nearer than ``distance`` to a point of
    ``captured`` (N, 3) (scipy's ``distance_upper_bound`` is strict); all False when
    ``captured`` is empty."""
    from scipy.spatial import cKDTree

    if len(captured) == 0:
        return np.zeros(len(points), dtype=bool)
    d, _ = cKDTree(np.asarray(captured, dtype=np.float64)).query(
        np.asarray(points, dtype=np.float64), distance_upper_bound=distance
    )
    return d <= distance


def fill_in(captured: np.ndarray, predicted: np.ndarray, distance: float) -> np.ndarray:
    """The captured cloud completed by the predicted points it lacks: ``captured`` (N, 3) and
    the points of ``predicted`` (M, 3) at ``distance`` or more from every captured point, in
    that order ((N + K, 3) float64). A prediction near the capture adds nothing the capture has
    not, and is less accurate than it."""
    captured = np.asarray(captured, dtype=np.float64)
    predicted = np.asarray(predicted, dtype=np.float64)
    return np.concatenate([captured, predicted[~near(captured, predicted, distance)]])


def random_subset(points: np.ndarray, keep: int, rng: np.random.Generator) -> np.ndarray:
    """A seeded random ``keep`` of the ``(N, 3)`` points, in their order (all of them when
    ``keep`` is 0 or not below N): how a dataset keeps a view's points (``points_per_view``),
    and how the planner keeps a capture's."""
    if 0 < keep < len(points):
        return points[np.sort(rng.choice(len(points), keep, replace=False))]
    return points
