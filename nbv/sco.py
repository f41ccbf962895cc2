"""Convex-hull set cover: next-best-view planning on the hull of a partial cloud.

The paper's Algorithms 2 and 3:

1. Take the convex hull of the partial cloud (Qhull) and draw ``n_samp`` points on it, uniformly
   by area (:func:`sample_hull`).
2. Simulate every view of the viewspace on the hull: view ``v``'s set is the hull samples it would
   capture (:func:`view_sets`).
3. Greedy maximum coverage (:func:`greedy_max_coverage`): pick the view with the most uncovered
   samples, remove its samples from every other set (Algorithm 3), repeat ``n_iter`` times. The
   chosen views, in order, are the plan. Once nothing is left to cover, the remaining picks
   spread out over the viewspace instead of following the view indices.

:func:`plan` runs all of it on the partial cloud, :func:`plan_sph` on the spherical signature of
the cloud (:mod:`nbv.sph`) placed back at the cloud's centroid.

View simulation has two paths. Both give, for each view, the hull samples within ``eps`` of the
points the view captures:

* ``"raycast"`` renders the hull mesh like the dataset does (:func:`nbv.render.render_raycast`,
  one ray per pixel centre), back-projects every view to a cloud and takes the hull samples
  closer than ``eps`` to that cloud (:func:`nbv.scores.covered_mask`), the coverage test of the
  scores (:func:`raycast_view_sets`). This is the definition; it is slow.
* ``"analytic"`` (the fast one) needs no rendering. A convex surface cannot occlude itself, so
  a view sees exactly the hull samples whose face looks at the camera and that project inside
  the image: sign tests of dot products (:mod:`nbv.visibility`). With ``dilate=True`` these
  visible sets are dilated by ``eps`` (:mod:`nbv.dilation`): the samples the view does not see
  but that lie within ``eps`` of a pixel's point, just behind the silhouette or just outside the
  image, solved exactly per pixel without rendering.

The dilation is off by default in planning (``dilate`` of :func:`plan`): it brings the analytic
sets closer to the ray-cast ones, but costs time. Measured at 640 x 480, ``eps = 0.00707``, 33
views at distance 1, 4096 samples, the analytic and ray-cast sets agree on 99.35 % of
(view, sample) pairs for a sphere and 99.45 % for a box with the dilation, 99.07 and 98.57 %
without; a whole 9-view plan takes about 25 ms with it and 6 ms without (``make bench``), and on
hulls of thousands of small triangles (the merged clouds of replanning) the view simulation goes
from 11 ms to 350 ms.

Cameras sit at the viewspace positions and look at the origin (:func:`nbv.camera.viewspace_poses`).
Distances are in the cloud's units (the normalised object frame, where the object fits in a
sphere of radius 0.5 and the cameras are at distance 1). Times in :class:`Plan` are seconds.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from nbv.camera import Intrinsics, backproject, viewspace_poses
from nbv.dilation import dilate_view_sets, near_triangles
from nbv.scores import DEFAULT_EPS, as_cloud, covered_mask
from nbv.sph import signature_with_centroid
from nbv.visibility import _as_poses, analytic_visibility, analytic_visibility_faces

#: Number of hull samples of the paper.
DEFAULT_N_SAMP = 16384
#: Number of views a plan picks (the paper's 9 after the start view).
DEFAULT_N_ITER = 9
METHODS = ("analytic", "raycast")

#: A hull whose volume is below this fraction of its bounding box's is flat.
_FLAT_RTOL = 1e-9

# Masks of the SWAR popcount of 64-bit words (numpy 1.26 has no bitwise_count).
_M1 = np.uint64(0x5555555555555555)
_M2 = np.uint64(0x3333333333333333)
_M4 = np.uint64(0x0F0F0F0F0F0F0F0F)
_H01 = np.uint64(0x0101010101010101)
_U1, _U2, _U4, _U56 = (np.uint64(k) for k in (1, 2, 4, 56))


@dataclass
class Plan:
    """A set-cover plan.

    Attributes:
        views: the chosen view indices, in the order they were picked (``n_iter`` of them).
        gains: number of hull samples each pick newly covers (non-increasing: greedy on a
            coverage function).
        covered_fraction: fraction of the hull samples covered by the excluded (already visited)
            views and the chosen views together, in [0, 1].
        timings: seconds spent on ``hull``, ``sampling``, ``simulation``, ``sets``, ``greedy``
            and their ``total``.
    """

    views: list[int]
    gains: list[int]
    covered_fraction: float
    timings: dict[str, float] = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# Hull and samples
# --------------------------------------------------------------------------------------------


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


# --------------------------------------------------------------------------------------------
# View simulation: which hull samples each view captures
# --------------------------------------------------------------------------------------------


def _hull_mesh(hull: ConvexHull | tuple[np.ndarray, np.ndarray] | None) -> tuple:
    if hull is None:
        raise ValueError('method="raycast" needs the hull mesh: pass hull=convex_hull(points)')
    if isinstance(hull, ConvexHull):
        return hull.points, hull.simplices
    vertices, faces = hull
    return np.asarray(vertices, dtype=np.float64), np.asarray(faces)


def raycast_view_sets(
    samples: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    hull: ConvexHull | tuple[np.ndarray, np.ndarray],
    eps: float = DEFAULT_EPS,
) -> np.ndarray:
    """Which hull samples each view captures, by rendering the hull like the dataset does.

    Each view's depth (:func:`nbv.render.render_raycast`, one ray a pixel centre) is
    back-projected to a cloud; a sample is captured when a point of that cloud lies closer than
    ``eps`` (:func:`nbv.scores.covered_mask`). ``eps`` must exceed about half the distance
    between neighbouring pixels' points on the surface, or frontal faces get holes: at 640 x 480,
    ``f = 476`` and distance 1 that spacing is 0.0021, below :data:`DEFAULT_EPS`.

    Args:
        samples: ``(n, 3)`` hull samples.
        poses: ``(V, 4, 4)`` camera-to-world.
        intrinsics: the camera to render with.
        hull: the hull as a ``ConvexHull`` or a ``(vertices (K, 3), faces (F, 3))`` mesh.
        eps: capture distance, cloud units.

    Returns:
        ``(V, n)`` bool.
    """
    from nbv.render import render_raycast  # Open3D is heavy; only this path needs it

    samples = as_cloud(samples, "samples")
    poses = _as_poses(poses)
    vertices, faces = _hull_mesh(hull)
    depth = render_raycast(vertices, faces, poses, intrinsics)
    sets = np.zeros((len(poses), len(samples)), dtype=bool)
    for v, pose in enumerate(poses):
        sets[v] = covered_mask(backproject(depth[v], intrinsics, pose), samples, eps)
    return sets


def view_sets(
    samples: np.ndarray,
    normals: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics = Intrinsics(),  # noqa: B008 - frozen dataclass, immutable default
    method: str = "analytic",
    eps: float = DEFAULT_EPS,
    hull: ConvexHull | tuple[np.ndarray, np.ndarray] | None = None,
    face_ids: np.ndarray | None = None,
    dilate: bool = False,
) -> np.ndarray:
    """Each view's set of hull samples (the paper's Algorithm 2).

    A view's set is the hull samples within ``eps`` of the points the view would capture.
    ``"raycast"`` renders the hull and takes exactly that; ``"analytic"`` works from the
    geometry:

    * ``dilate=False``: the samples the view sees, facing the camera and inside the image
      (:func:`nbv.visibility.analytic_visibility`): the exact visible part of the hull.
    * ``dilate=True``: those, plus the samples it does not see that lie within ``eps`` of a
      pixel's point: just behind the silhouette or just outside the image
      (:func:`nbv.dilation.near_triangles`, :func:`nbv.dilation.dilate_view_sets`, exact per
      pixel). The one remaining difference from ``"raycast"``: a sample on a face seen so
      obliquely that its pixels' points lie farther apart than ``eps`` is kept, though no
      point may come that close. See :mod:`nbv.dilation` for the measured agreement.

    Args:
        samples: ``(n, 3)`` points on the hull (:func:`sample_hull`), world units.
        normals: ``(n, 3)`` their outward unit normals.
        poses: ``(V, 4, 4)`` camera-to-world, OpenCV convention.
        intrinsics: the camera.
        method: ``"analytic"`` (fast) or ``"raycast"`` (:func:`raycast_view_sets`, renders the
            hull; needs ``hull``).
        eps: capture distance, world units: the ray-cast coverage distance (``> 0``) and, with
            ``dilate``, the analytic dilation (``>= 0``).
        hull: the hull (``ConvexHull``, or ``(vertices, faces)`` for ``"raycast"``).
        face_ids: ``(n,)`` triangle of each sample (:func:`sample_hull`). With a ``ConvexHull``
            ``hull``, the analytic path decides whole triangles at once
            (:func:`nbv.visibility.analytic_visibility_faces`); otherwise each sample on its own
            (:func:`nbv.visibility.analytic_visibility`). Both give the same sets.
        dilate: analytic path only: dilate the visible sets by ``eps``. It needs ``hull`` as a
            ``ConvexHull`` and ``face_ids`` (the dilation works on the triangles). Closer to
            ``"raycast"`` but slower, see :func:`plan`. ``False`` (default): the visible sets.

    Returns:
        ``(V, n)`` bool: ``sets[v, i]`` is True when view ``v`` captures sample ``i``.
    """
    if method == "analytic":
        on_triangles = isinstance(hull, ConvexHull) and face_ids is not None
        if dilate and not on_triangles:
            raise ValueError(
                "dilate=True needs the hull as a ConvexHull and the samples' face_ids "
                "(sample_on_hull returns them)"
            )
        if not on_triangles:
            return analytic_visibility(samples, normals, poses, intrinsics)
        seen = analytic_visibility_faces(hull, samples, face_ids, poses, intrinsics)
        if dilate:
            near = near_triangles(hull, samples, face_ids, eps)
            seen = dilate_view_sets(seen, samples, face_ids, hull, near, poses, intrinsics)
        return seen
    if method == "raycast":
        if not eps > 0:
            raise ValueError(f"eps must be positive, got {eps}")
        return raycast_view_sets(samples, poses, intrinsics, hull, eps)
    raise ValueError(f"method must be one of {METHODS}, got {method!r}")


# --------------------------------------------------------------------------------------------
# Greedy maximum coverage (Algorithm 3)
# --------------------------------------------------------------------------------------------


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


def popcount_rows(rows: np.ndarray) -> np.ndarray:
    """Number of set bits of each row of a ``(V, W)`` uint64 array: ``(V,)`` int64.

    Branch-free SWAR popcount of every word (numpy 1.26 has no ``bitwise_count``).
    """
    a = np.right_shift(rows, _U1)
    a &= _M1
    np.subtract(rows, a, out=a)  # 2-bit counts
    b = np.right_shift(a, _U2)
    b &= _M2
    a &= _M2
    a += b  # 4-bit counts
    np.right_shift(a, _U4, out=b)
    a += b
    a &= _M4  # byte counts
    a *= _H01
    a >>= _U56  # the sum of the bytes lands in the top byte
    return a.sum(axis=1, dtype=np.int64)


def _as_sets(sets: np.ndarray) -> np.ndarray:
    arr = np.asarray(sets)
    if arr.ndim != 2:
        raise ValueError(f"sets must be a (V, n) boolean matrix, got shape {arr.shape}")
    if arr.dtype != np.bool_:
        if not (np.issubdtype(arr.dtype, np.integer) and np.isin(arr, (0, 1)).all()):
            raise ValueError(f"sets must hold booleans (or 0/1 integers), got dtype {arr.dtype}")
        arr = arr.astype(bool)
    return arr


def _as_exclude(exclude: Iterable[int], n_views: int) -> np.ndarray:
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


def _spread_fill(directions: np.ndarray, closed: np.ndarray, count: int) -> list[int]:
    """``count`` views, not ``closed``, each as far in angle as possible from those before.

    Each pick maximises its smallest angle (at the origin) to the closed views and the earlier
    picks; ties (cosines equal to 12 decimals, so that symmetric viewspaces tie exactly) go to
    the lowest index. With nothing closed, the first pick is the lowest index.

    Args:
        directions: ``(V, 3)`` unit vectors from the origin to the views.
        closed: ``(V,)`` bool, the views already visited or chosen; not modified.
        count: number of picks, at most the open views.
    """
    open_views = ~closed
    nearest = np.full(len(directions), -np.inf)  # cosine of the smallest angle to a closed view
    if closed.any():
        nearest = (directions @ directions[closed].T).max(axis=1)
    picks: list[int] = []
    for _ in range(count):
        candidates = np.flatnonzero(open_views)
        best = int(candidates[np.argmin(np.round(nearest[candidates], 12))])
        picks.append(best)
        open_views[best] = False
        np.maximum(nearest, directions @ directions[best], out=nearest)
    return picks


def greedy_packed(
    rows: np.ndarray,
    n_iter: int,
    exclude: Iterable[int] = (),
    positions: np.ndarray | None = None,
) -> tuple[list[int], list[int], int]:
    """Greedy maximum coverage on bit rows, see :func:`greedy_max_coverage`.

    Args:
        rows: ``(V, W)`` uint64 bit rows (:func:`pack_sets`); not modified.
        n_iter: number of views to pick.
        exclude: indices of views already visited.
        positions: ``(V, 3)`` view positions, world units, or None (see
            :func:`greedy_max_coverage`).

    Returns:
        ``(views, gains, n_covered)``: as :func:`greedy_max_coverage`, plus the number of
        elements covered by the excluded and chosen views together.
    """
    rows = np.asarray(rows)
    if rows.ndim != 2 or rows.dtype != np.uint64:
        raise ValueError(f"rows must be a (V, W) uint64 array, got {rows.dtype} {rows.shape}")
    n_views = rows.shape[0]
    excluded = _as_exclude(exclude, n_views)
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
                rest = _spread_fill(directions, closed, count)
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
    look at) to the excluded and already chosen views is largest (ties: the lowest index).

    Args:
        sets: ``(V, n)`` bool (or 0/1): ``sets[v, i]`` is True when view ``v`` covers element
            ``i``.
        n_iter: number of views to choose, ``<= V - len(exclude)``.
        exclude: indices of views that are already visited: never chosen, their elements count
            as covered.
        positions: ``(V, 3)`` view positions, world units (any non-zero distance from the
            origin), for the spread-out zero-gain picks; None picks them by index.

    Returns:
        ``(views, gains)``: the ``n_iter`` chosen view indices in order, and the number of
        elements each newly covered (its marginal gain; non-increasing).
    """
    views, gains, _ = greedy_packed(pack_sets(sets), n_iter, exclude, positions)
    return views, gains


# --------------------------------------------------------------------------------------------
# Plans
# --------------------------------------------------------------------------------------------


def _as_viewspace(viewspace: np.ndarray) -> np.ndarray:
    arr = np.asarray(viewspace, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
        raise ValueError(f"viewspace must have shape (V, 3) with V >= 1, got {arr.shape}")
    return arr


def _plan_on_cloud(
    points: np.ndarray,
    viewspace: np.ndarray,
    n_iter: int,
    exclude: Iterable[int],
    n_samp: int,
    rng: np.random.Generator | int,
    method: str,
    intrinsics: Intrinsics,
    eps: float,
    poses: np.ndarray | None,
    timings: dict[str, float],
    dilate: bool = False,
) -> Plan:
    """Algorithms 2 and 3 on the hull of ``points``; adds its stage times to ``timings``."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    viewspace = _as_viewspace(viewspace)
    excluded = _as_exclude(exclude, len(viewspace))
    clock = time.perf_counter
    t0 = clock()
    hull = convex_hull(points)
    t1 = clock()
    samples, normals, face_ids = sample_on_hull(hull, n_samp, rng)
    t2 = clock()
    poses = viewspace_poses(viewspace) if poses is None else _as_poses(poses)
    if len(poses) != len(viewspace):
        raise ValueError(f"poses has {len(poses)} cameras, the viewspace {len(viewspace)}")
    sets = view_sets(samples, normals, poses, intrinsics, method, eps, hull, face_ids, dilate)
    t3 = clock()
    rows = pack_sets(sets)
    t4 = clock()
    views, gains, n_covered = greedy_packed(rows, n_iter, excluded, viewspace)
    t5 = clock()
    for key, seconds in (
        ("hull", t1 - t0),
        ("sampling", t2 - t1),
        ("simulation", t3 - t2),
        ("sets", t4 - t3),
        ("greedy", t5 - t4),
    ):
        timings[key] = timings.get(key, 0.0) + seconds
    timings["total"] = sum(
        timings[k]
        for k in ("signature", "hull", "sampling", "simulation", "sets", "greedy")
        if k in timings
    )
    return Plan(views, gains, n_covered / len(samples), timings)


def plan(
    points: np.ndarray,
    viewspace: np.ndarray,
    n_iter: int = DEFAULT_N_ITER,
    exclude: Iterable[int] = (),
    n_samp: int = DEFAULT_N_SAMP,
    rng: np.random.Generator | int = 0,
    method: str = "analytic",
    intrinsics: Intrinsics = Intrinsics(),  # noqa: B008 - frozen dataclass, immutable default
    eps: float = DEFAULT_EPS,
    poses: np.ndarray | None = None,
    dilate: bool = False,
) -> Plan:
    """Convex-hull set-cover plan from a partial cloud (the paper's Algorithms 2 and 3).

    Args:
        points: ``(N, 3)`` partial cloud (what the visited views saw), world units.
        viewspace: ``(V, 3)`` camera positions; every camera looks at the origin.
        n_iter: number of views to plan, ``<= V - len(exclude)``. Once the hull is covered,
            the remaining picks spread out over the viewspace (see
            :func:`greedy_max_coverage` with ``positions=viewspace``).
        exclude: indices of the views already visited (the start view): never chosen, and the
            hull samples they capture count as covered before the first pick.
        n_samp: number of hull samples.
        rng: numpy Generator or integer seed (only the sampling is random).
        method: view simulation, ``"analytic"`` or ``"raycast"`` (see :func:`view_sets`).
        intrinsics: the camera.
        eps: capture distance, world units: of ``"raycast"``, and of ``"analytic"`` with
            ``dilate`` (see :func:`view_sets`).
        poses: ``(V, 4, 4)`` :func:`nbv.camera.viewspace_poses` of ``viewspace``, when the
            caller has them already (they are the same for every plan on one viewspace).
        dilate: with ``"analytic"``, dilate the visible sets by ``eps`` (:mod:`nbv.dilation`):
            the samples within ``eps`` of a pixel's point just behind the silhouette or just
            outside the image count too, as they do for ``"raycast"``. Closer to ``"raycast"``
            but about 4x slower, far more on hulls of many small triangles (measured in the
            module docstring). Off by default. ``"raycast"`` ignores it.

    Returns:
        :class:`Plan`.

    Raises:
        ValueError: for a cloud whose hull has no volume (flat, colinear, fewer than 4 points)
            and for bad arguments.
    """
    return _plan_on_cloud(
        points, viewspace, n_iter, exclude, n_samp, rng, method, intrinsics, eps, poses, {}, dilate
    )


def sph_hull_points(points: np.ndarray, lmax: int = 3) -> np.ndarray:
    """The spherical signature of a cloud in world coordinates (at the cloud's centroid).

    Args:
        points: ``(N, 3)`` cloud, world units.
        lmax: maximum harmonic degree (the paper's 3).

    Returns:
        ``(4 (lmax + 1)^2, 3)`` float64 points: :func:`nbv.sph.signature_with_centroid` shifted
        by the centroid.
    """
    signature, centroid = signature_with_centroid(as_cloud(points, "points"), lmax)
    return signature.astype(np.float64) + centroid


def plan_sph(
    points: np.ndarray,
    viewspace: np.ndarray,
    lmax: int = 3,
    n_iter: int = DEFAULT_N_ITER,
    exclude: Iterable[int] = (),
    n_samp: int = DEFAULT_N_SAMP,
    rng: np.random.Generator | int = 0,
    method: str = "analytic",
    intrinsics: Intrinsics = Intrinsics(),  # noqa: B008 - frozen dataclass, immutable default
    eps: float = DEFAULT_EPS,
    poses: np.ndarray | None = None,
    dilate: bool = False,
) -> Plan:
    """Convex-hull set cover on the hull of the cloud's spherical signature.

    Same as :func:`plan` (``dilate`` included: off by default, see there for its cost), but the
    hull is that of :func:`sph_hull_points` (the signature of degree ``lmax`` placed at the
    cloud's centroid) instead of the cloud's own. ``timings`` gets a ``signature`` entry too.
    """
    t0 = time.perf_counter()
    signature = sph_hull_points(points, lmax)
    timings = {"signature": time.perf_counter() - t0}
    return _plan_on_cloud(
        signature,
        viewspace,
        n_iter,
        exclude,
        n_samp,
        rng,
        method,
        intrinsics,
        eps,
        poses,
        timings,
        dilate,
    )
