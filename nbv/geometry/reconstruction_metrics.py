"""The field's reconstruction and path metrics of a set of views: Chamfer distance, F-score,
views to reach a coverage, great-circle camera paths and the shortest path through views.

* **Chamfer distance** between a reconstruction ``R`` (the accumulated cloud of the captured
  views) and the ground truth ``G``: *accuracy* is the mean over ``r`` in ``R`` of
  ``min_g |r - g|``, *completeness* the mean over ``g`` in ``G`` of ``min_r |g - r|``, and the
  Chamfer distance their mean, ``(accuracy + completeness) / 2``. Distances are Euclidean, not
  squared (PoinTr's "CD-l1" convention), in the units of the clouds (the dataset's normalised
  object frame: the object fits in a sphere of radius 0.5).
* **F-score** at a distance ``d`` (Tanks and Temples): precision ``P`` = the fraction of ``R``
  closer than ``d`` to ``G``, recall ``Q`` = the fraction of ``G`` closer than ``d`` to ``R``,
  ``F = 2 P Q / (P + Q)`` (0 when both are 0). "Closer than" is strict, as the coverage test.
* An empty reconstruction has no accuracy (NaN), infinite completeness (so a NaN Chamfer
  distance) and precision, recall and F-score 0.
* **A mesh against a mesh** (:func:`mesh_scores`, e.g. a fused reconstruction against the true
  surface): both surfaces are sampled uniformly by area (seeded) and scored as clouds. Sampling
  adds about ``0.5 sqrt(area / n)`` to each direction's mean (the mean distance to the nearest of
  ``n`` uniform points on a surface of that area), so ``n`` should make that small against the
  distances of interest.
* **Views to reach** a target coverage: the 1-based number of views (the start view counts)
  after which a coverage curve first reaches the target; None (censored) when it never does.
* **Camera paths** on a viewspace sphere: the great-circle arc between two camera positions at
  the viewspace's radius, the length of a visiting order, and the shortest open path through a
  set of views that starts at a given view (exact, Held-Karp).

Pure numpy and scipy: arrays in, numbers out. :class:`ViewDistances` memoises per-view distances
so that the scores of any union of a model's views cost a few vector operations.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

#: The most views :func:`shortest_open_path` takes (the start included): Held-Karp holds
#: ``2^(n-1) x (n-1)`` partial paths, 14 views about 106,000.
MAX_TOUR_VIEWS = 14
#: Slack of :func:`views_to_reach`: a curve value within this of the target reaches it (the
#: coverage curve and its target are ratios of integer counts, computed in float64).
REACH_TOLERANCE = 1e-12


def nearest_distances(query: np.ndarray, points: np.ndarray, tree: cKDTree | None = None):
    """Distance from every query point to its nearest point of ``points``.

    Args:
        query: (N, 3) points.
        points: (M, 3) points (ignored when ``tree`` is given).
        tree: a ``cKDTree`` of ``points``, to reuse one built before.

    Returns:
        (N,) float64 Euclidean distances; all ``inf`` when ``points`` is empty.
    """
    query = np.asarray(query, dtype=np.float64).reshape(-1, 3)
    if tree is None:
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if len(points) == 0:
            return np.full(len(query), np.inf)
        tree = cKDTree(points)
    if len(query) == 0:
        return np.zeros(0)
    dist, _ = tree.query(query, k=1)
    return np.asarray(dist, dtype=np.float64)


def fscore(precision: float, recall: float) -> float:
    """``2 P Q / (P + Q)``; 0 when both are 0."""
    total = precision + recall
    return float(2.0 * precision * recall / total) if total > 0 else 0.0


def threshold_name(multiple: float) -> str:
    """The key suffix of the threshold ``multiple * eps`` in :func:`distance_scores`: ``eps``,
    ``2eps``, ``0.5eps``, ..."""
    return "eps" if multiple == 1 else f"{multiple:g}eps"


def _scores(
    to_gt_sum: float,
    n_recon: int,
    within: Sequence[int],
    to_recon: np.ndarray,
    eps: float,
    multiples: Sequence[float],
) -> dict[str, float]:
    completeness = float(to_recon.mean()) if len(to_recon) else float("nan")
    accuracy = to_gt_sum / n_recon if n_recon else float("nan")
    out = {
        "chamfer_accuracy": float(accuracy),
        "chamfer_completeness": completeness,
        "chamfer": (accuracy + completeness) / 2 if n_recon else float("nan"),
    }
    for m, near in zip(multiples, within, strict=True):
        p = near / n_recon if n_recon else 0.0
        q = float(np.mean(to_recon < m * eps)) if len(to_recon) else 0.0
        name = threshold_name(m)
        out[f"precision_{name}"], out[f"recall_{name}"] = float(p), q
        out[f"fscore_{name}"] = fscore(p, q)
    return out


def distance_scores(
    to_gt: np.ndarray, to_recon: np.ndarray, eps: float, multiples: Sequence[int] = (1, 2)
) -> dict[str, float]:
    """Chamfer distance and F-scores from the two directions' nearest distances.

    Args:
        to_gt: (N,) distance of each reconstruction point to the ground truth.
        to_recon: (M,) distance of each ground-truth point to the reconstruction (``inf`` for
            an empty one).
        eps: the base distance; the F-scores are at ``m * eps`` for ``m`` in ``multiples``.
        multiples: the thresholds, as multiples of ``eps``.

    Returns:
        ``chamfer_accuracy`` (mean of ``to_gt``), ``chamfer_completeness`` (mean of
        ``to_recon``), ``chamfer`` (their mean), and ``precision_<t>``, ``recall_<t>``,
        ``fscore_<t>`` for ``t`` = :func:`threshold_name` of each multiple: ``eps``, ``2eps``
        (see the module docstring).
    """
    to_gt = np.asarray(to_gt, dtype=np.float64).ravel()
    to_recon = np.asarray(to_recon, dtype=np.float64).ravel()
    within = [int(np.count_nonzero(to_gt < m * eps)) for m in multiples]
    return _scores(float(to_gt.sum()), len(to_gt), within, to_recon, eps, multiples)


def cloud_scores(
    recon: np.ndarray, gt: np.ndarray, eps: float, multiples: Sequence[int] = (1, 2)
) -> dict[str, float]:
    """:func:`distance_scores` of a reconstruction cloud ``(N, 3)`` against the ground truth
    ``(M, 3)``, both in the same frame (two KD-tree queries)."""
    recon = np.asarray(recon, dtype=np.float64).reshape(-1, 3)
    gt = np.asarray(gt, dtype=np.float64).reshape(-1, 3)
    return distance_scores(
        nearest_distances(recon, gt), nearest_distances(gt, recon), eps, multiples
    )


class ViewDistances:
    """Chamfer and F-score of any union of one model's views, from distances memoised per view.

    A reconstruction point's distance to the ground truth does not depend on the other views,
    and a ground-truth point's distance to a union of views is the least of its distances to
    each view. So each view is queried once (lazily, on first use): its points against the
    ground truth's KD-tree, and the ground truth against the view's KD-tree. A union's scores
    are then sums and an elementwise minimum over its views.

    Args:
        gt: (M, 3) ground-truth points.
        points: (sum N_v, 3) the views' points, view after view.
        offsets: (V + 1,) int; view ``v`` is ``points[offsets[v]:offsets[v + 1]]``.
        eps: the base distance of the F-scores.
        multiples: the F-score thresholds as multiples of ``eps``.
        gt_tree: a ``cKDTree`` of ``gt`` to reuse (one per model serves all its viewspaces).
    """

    def __init__(
        self,
        gt: np.ndarray,
        points: np.ndarray,
        offsets: np.ndarray,
        eps: float,
        multiples: Sequence[int] = (1, 2),
        gt_tree: cKDTree | None = None,
    ) -> None:
        self.gt = np.asarray(gt, dtype=np.float64).reshape(-1, 3)
        self.points = points
        self.offsets = np.asarray(offsets, dtype=np.int64)
        self.eps = float(eps)
        self.multiples = tuple(multiples)
        self.gt_tree = gt_tree if gt_tree is not None else cKDTree(self.gt)
        n = len(self.offsets) - 1
        self._done = np.zeros(n, dtype=bool)
        self._sum = np.zeros(n)
        self._count = np.zeros(n, dtype=np.int64)
        self._within = np.zeros((n, len(self.multiples)), dtype=np.int64)
        self._to_view = np.empty((n, len(self.gt)))

    def _view(self, v: int) -> None:
        pts = np.asarray(self.points[self.offsets[v] : self.offsets[v + 1]], dtype=np.float64)
        to_gt = nearest_distances(pts, self.gt, self.gt_tree)
        self._sum[v] = to_gt.sum()
        self._count[v] = len(pts)
        self._within[v] = [np.count_nonzero(to_gt < m * self.eps) for m in self.multiples]
        self._to_view[v] = nearest_distances(self.gt, pts)
        self._done[v] = True

    def scores(self, views: Sequence[int]) -> dict[str, float]:
        """:func:`distance_scores` of the union of ``views`` (the concatenation of their
        points, as :func:`cloud_scores` of it gives)."""
        views = np.unique(np.asarray(views, dtype=np.int64))
        for v in views[~self._done[views]]:
            self._view(int(v))
        to_recon = self._to_view[views].min(axis=0) if len(views) else np.full(len(self.gt), np.inf)
        return _scores(
            float(self._sum[views].sum()),
            int(self._count[views].sum()),
            self._within[views].sum(axis=0).tolist(),
            to_recon,
            self.eps,
            self.multiples,
        )


def surface_points(
    vertices: np.ndarray, triangles: np.ndarray, n: int, rng: np.random.Generator
) -> np.ndarray:
    """``n`` points drawn uniformly by area on a triangle mesh (trimesh's sampler, seeded).

    Args:
        vertices: (N, 3) vertex positions.
        triangles: (M, 3) integer indices into ``vertices``.
        n: points to draw, >= 0.
        rng: the random generator; the same state gives the same points.

    Returns:
        (n, 3) float64 points; (0, 3) when the mesh has no area (no triangles, or all
        degenerate).
    """
    import trimesh  # imported here: only the mesh scores sample surfaces

    if int(n) != n or n < 0:
        raise ValueError(f"number of points must be a non-negative integer, got {n!r}")
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    triangles = np.asarray(triangles).reshape(-1, 3)
    if not np.issubdtype(triangles.dtype, np.integer):
        raise ValueError(f"triangles must be integer indices, got {triangles.dtype}")
    if len(triangles) and (triangles.min() < 0 or triangles.max() >= len(vertices)):
        raise ValueError(
            f"triangle indices must lie in [0, {len(vertices)}), got "
            f"[{triangles.min()}, {triangles.max()}]"
        )
    mesh = trimesh.Trimesh(vertices, triangles, process=False, validate=False)
    if n == 0 or not len(triangles) or not mesh.area > 0:
        return np.zeros((0, 3))
    points, _ = trimesh.sample.sample_surface(mesh, int(n), seed=rng)
    return np.asarray(points, dtype=np.float64)


def mesh_scores(
    vertices: np.ndarray,
    triangles: np.ndarray,
    gt_vertices: np.ndarray,
    gt_triangles: np.ndarray,
    eps: float,
    rng: np.random.Generator,
    multiples: Sequence[float] = (1, 2),
    n: int = 100_000,
) -> dict[str, float]:
    """:func:`cloud_scores` of a reconstructed mesh against a ground-truth mesh, both sampled
    with :func:`surface_points` (``n`` points each, the reconstruction's first, from ``rng``).

    Args:
        vertices, triangles: the reconstruction, (N, 3) and (M, 3) integer.
        gt_vertices, gt_triangles: the ground truth, in the same frame and units.
        eps: the base distance of the F-scores (world units).
        rng: the random generator of both samples.
        multiples: the F-score thresholds, as multiples of ``eps``.
        n: points sampled on each surface (see the module docstring for the error it adds).

    Returns:
        :func:`distance_scores`' keys; an empty reconstruction scores as the module docstring
        says (NaN Chamfer distance, F-scores 0).
    """
    recon = surface_points(vertices, triangles, n, rng)
    gt = surface_points(gt_vertices, gt_triangles, n, rng)
    if len(gt) == 0:
        raise ValueError("the ground-truth mesh has no area: nothing to score against")
    return cloud_scores(recon, gt, eps, multiples)


def views_to_reach(curve: Sequence[float], target: float) -> int | None:
    """The number of views after which ``curve`` first reaches ``target``.

    Args:
        curve: (n,) a coverage curve: the value after 1, 2, ..., n views.
        target: the value to reach (within :data:`REACH_TOLERANCE`).

    Returns:
        1-based: 1 when the first view reaches it; None (censored) when no value does.
    """
    reached = np.flatnonzero(np.asarray(curve, dtype=np.float64) >= target - REACH_TOLERANCE)
    return int(reached[0]) + 1 if len(reached) else None


def great_circle_matrix(positions: np.ndarray, radius: float | None = None) -> np.ndarray:
    """Great-circle distances between camera positions on a sphere about the origin.

    Args:
        positions: (V, 3) camera positions (a viewspace's ``poses[:, :3, 3]``).
        radius: the sphere's radius; None takes the positions' mean distance from the origin.

    Returns:
        (V, V) float64 arc lengths ``radius * angle``, the angle between the positions' directions
        (``atan2(|a x b|, a . b)``, accurate for small and near-opposite angles too).
    """
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    norms = np.linalg.norm(p, axis=1)
    if not (norms > 0).all():
        raise ValueError("a camera position lies at the origin: it has no direction")
    r = float(norms.mean()) if radius is None else float(radius)
    u = p / norms[:, None]
    cross = np.linalg.norm(np.cross(u[:, None, :], u[None, :, :]), axis=-1)
    angle = np.arctan2(cross, u @ u.T)
    np.fill_diagonal(angle, 0.0)
    return r * angle


def path_length(distances: np.ndarray, order: Sequence[int]) -> float:
    """The length of visiting ``order`` (indices into ``distances``, (V, V)) in turn: the sum of
    ``distances[order[i], order[i + 1]]``; 0 for fewer than two stops."""
    order = np.asarray(order, dtype=np.int64)
    return float(distances[order[:-1], order[1:]].sum()) if len(order) > 1 else 0.0


def shortest_open_path(distances: np.ndarray) -> tuple[float, list[int]]:
    """The shortest path that starts at stop 0 and visits every stop once (open: it ends
    anywhere), exactly, by Held-Karp's dynamic programme over subsets.

    Args:
        distances: (n, n) symmetric or not, ``distances[i, j]`` the cost of going from i to j;
            n <= :data:`MAX_TOUR_VIEWS`.

    Returns:
        (length, order): ``order`` a permutation of ``0..n-1`` starting with 0.

    Raises:
        ValueError: more than :data:`MAX_TOUR_VIEWS` stops, or not a square matrix.
    """
    d = np.asarray(distances, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1] or d.shape[0] == 0:
        raise ValueError(f"distances must be a non-empty square matrix, got shape {d.shape}")
    n = d.shape[0]
    if n > MAX_TOUR_VIEWS:
        raise ValueError(f"{n} stops: the exact shortest path takes at most {MAX_TOUR_VIEWS}")
    m = n - 1  # the stops after the start, bit j of a subset = stop j + 1
    if m == 0:
        return 0.0, [0]
    masks = np.arange(1 << m)
    bit = (masks[:, None] >> np.arange(m)[None, :]) & 1  # (2^m, m): stop j + 1 in subset
    size = bit.sum(axis=1)
    inner = d[1:, 1:]
    best = np.full((1 << m, m), np.inf)
    parent = np.full((1 << m, m), -1, dtype=np.int64)
    best[1 << np.arange(m), np.arange(m)] = d[0, 1:]
    # Subsets by size: every (subset, last stop)'s predecessor, the subset less its last stop,
    # is one smaller, so one vector step per size fills them all.
    for k in range(2, m + 1):
        rows, ends = np.nonzero(bit[masks[size == k]])
        subsets = masks[size == k][rows]
        before = best[subsets ^ (1 << ends)] + inner[:, ends].T
        pick = np.argmin(before, axis=1)
        parent[subsets, ends] = pick
        best[subsets, ends] = before[np.arange(len(ends)), pick]
    full = (1 << m) - 1
    last = int(np.argmin(best[full]))
    length = float(best[full, last])
    order, mask = [], full
    while last >= 0:
        order.append(last + 1)
        last, mask = int(parent[mask, last]), mask ^ (1 << last)
    return length, [0, *reversed(order)]
