"""Convex-hull set cover: next-best-view planning on the hull of a partial cloud.

The paper's Algorithms 2 and 3:

1. Take the convex hull of the partial cloud (Qhull) and draw ``n_samp`` points on it, uniformly
   by area (:func:`sample_hull`).
2. Simulate every view of the viewspace on the hull: view ``v``'s set is the hull samples it would
   capture (:func:`view_sets`).
3. Greedy maximum coverage (:func:`greedy_max_coverage`): pick the view with the most uncovered
   samples, remove its samples from every other set (Algorithm 3), repeat ``n_iter`` times. The
   chosen views, in order, are the plan.

:func:`plan` runs all of it on the partial cloud, :func:`plan_sph` on the spherical signature of
the cloud (:mod:`nbv.sph`) placed back at the cloud's centroid.

View simulation has two paths:

* ``"analytic"`` (the fast one). A convex surface cannot occlude itself, so a hull sample ``p``
  with outward normal ``n`` is seen from a camera centred at ``c`` exactly when its face looks at
  the camera, ``n . (c - p) > 0``, and it projects inside the image, ``0 <= u <= W - 1`` and
  ``0 <= v <= H - 1`` (pixel-centre coordinates of :mod:`nbv.camera`) in front of the camera.
  The image bounds are four planes through the camera centre, so everything is a sign test of
  a dot product, done for all views and samples at once.
* ``"raycast"`` renders the hull mesh like the dataset does (:func:`nbv.render.render_raycast`,
  one ray per pixel centre), back-projects every view to a cloud and takes the hull samples
  closer than ``eps`` to that cloud (:func:`nbv.scores.covered_mask`), the coverage test of the
  scores. The paths differ only at borders: a sample on a face seen almost edge-on may be
  farther than ``eps`` from every pixel's point (the pixels spread out along the face), and a
  sample just behind the silhouette or just outside the image may lie within ``eps`` of a
  point that is seen. On object-sized hulls at 640 x 480 and ``eps = 0.00707`` they agree on
  about 97.5 to 99 % of (view, sample) pairs: the longer the silhouette for the hull's area
  (boxes, hulls of a single view), the lower.

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
from nbv.scores import DEFAULT_EPS, as_cloud, covered_mask
from nbv.sph import signature_with_centroid

#: Number of hull samples of the paper.
DEFAULT_N_SAMP = 16384
#: Number of views a plan picks (the paper's 9 after the start view).
DEFAULT_N_ITER = 9
METHODS = ("analytic", "raycast")

#: A face counts as turned towards the camera when ``n . (c - p)`` exceeds this (cloud units):
#: faces whose plane passes through the camera centre are seen edge-on and capture nothing.
_FACING_TOL = 1e-9
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


def _as_poses(poses: np.ndarray) -> np.ndarray:
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ValueError(f"poses must have shape (V, 4, 4), got {arr.shape}")
    return arr


def _frustum_planes(poses: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """Half-spaces of each camera's image, ``(V, 5, 4)``: ``a . p + b >= 0`` inside.

    Rows: in front (``z > 0``), ``u >= 0``, ``u <= W - 1``, ``v >= 0``, ``v <= H - 1``; with
    ``(x, y, z)`` the camera-frame point, ``u >= 0`` is ``fx x + cx z >= 0`` (for ``z > 0``), and
    so on: planes through the camera centre, rotated to the world.
    """
    k = intrinsics
    right, down, forward = poses[:, :3, 0], poses[:, :3, 1], poses[:, :3, 2]
    normal = np.stack(
        [
            forward,
            k.fx * right + k.cx * forward,
            (k.width - 1 - k.cx) * forward - k.fx * right,
            k.fy * down + k.cy * forward,
            (k.height - 1 - k.cy) * forward - k.fy * down,
        ],
        axis=1,
    )  # (V, 5, 3)
    offset = -np.einsum("vkj,vj->vk", normal, poses[:, :3, 3])
    return np.concatenate([normal, offset[..., None]], axis=2)


def analytic_visibility(
    samples: np.ndarray, normals: np.ndarray, poses: np.ndarray, intrinsics: Intrinsics
) -> np.ndarray:
    """Which points of a convex surface each camera sees, without rendering.

    A point ``p`` with outward normal ``n`` is seen from a camera at ``c`` iff ``n . (c - p) > 0``
    (tolerance ``1e-9``) and it projects to ``0 <= u <= W - 1``, ``0 <= v <= H - 1`` with depth
    ``z > 0``. Exact for points on a convex surface, which cannot hide each other.

    Args:
        samples: ``(n, 3)`` points on the surface, world units.
        normals: ``(n, 3)`` their outward unit normals.
        poses: ``(V, 4, 4)`` camera-to-world, OpenCV convention.
        intrinsics: the camera.

    Returns:
        ``(V, n)`` bool.
    """
    samples = as_cloud(samples, "samples")
    normals = as_cloud(normals, "normals")
    if normals.shape != samples.shape:
        raise ValueError(f"normals {normals.shape} must match samples {samples.shape}")
    poses = _as_poses(poses)
    n_views, n = len(poses), len(samples)
    homog = np.empty((4, n))
    homog[:3] = samples.T
    homog[3] = 1.0
    signed = (_frustum_planes(poses, intrinsics).reshape(-1, 4) @ homog).reshape(n_views, 5, n)
    seen = signed[:, 0] > 0.0
    for k in range(1, 5):
        seen &= signed[:, k] >= 0.0
    # n . (c - p) = [c, 1] . [n, -n . p]: one product for all views.
    facing = np.empty((4, n))
    facing[:3] = normals.T
    facing[3] = -np.einsum("ij,ij->i", normals, samples)
    seen &= (poses[:, :3, 3] @ facing[:3] + facing[3]) > _FACING_TOL
    return seen


def _inside(signed: np.ndarray) -> np.ndarray:
    """Inside all five half-spaces of :func:`_frustum_planes`: ``(..., 5, m)`` -> ``(..., m)``."""
    inside = signed[..., 0, :] > 0.0
    for k in range(1, 5):
        inside &= signed[..., k, :] >= 0.0
    return inside


def analytic_visibility_faces(
    hull: ConvexHull,
    samples: np.ndarray,
    face_ids: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
) -> np.ndarray:
    """:func:`analytic_visibility` decided per triangle: the same answer, much less work.

    A triangle's samples share its normal, so "faces the camera" is one test per triangle. The
    image is convex, so a triangle whose three corners lie inside it lies wholly inside; only
    the samples of the other triangles that face the camera (those an image border cuts, or
    that lie outside the image) are tested one by one.

    Args:
        hull: the ``ConvexHull`` the samples were drawn on.
        samples: ``(n, 3)`` points on it, world units.
        face_ids: ``(n,)`` index into ``hull.simplices`` of the triangle of each sample.
        poses: ``(V, 4, 4)`` camera-to-world, OpenCV convention.
        intrinsics: the camera.

    Returns:
        ``(V, n)`` bool.
    """
    samples = as_cloud(samples, "samples")
    face_ids = np.asarray(face_ids)
    poses = _as_poses(poses)
    n_faces = len(hull.simplices)
    if face_ids.shape != (len(samples),) or not np.issubdtype(face_ids.dtype, np.integer):
        raise ValueError(
            f"face_ids must be ({len(samples)},) integers like samples, got "
            f"{face_ids.dtype} {face_ids.shape}"
        )
    if face_ids.size and (face_ids.min() < 0 or face_ids.max() >= n_faces):
        raise ValueError(f"face_ids must lie in [0, {n_faces}), the hull's triangles")
    n_views = len(poses)
    planes = _frustum_planes(poses, intrinsics)  # (V, 5, 4)
    # Corners are tested once each: Qhull's vertex list, renumbered.
    corner_ids = hull.vertices
    renumber = np.empty(len(hull.points), dtype=np.intp)
    renumber[corner_ids] = np.arange(len(corner_ids))
    tri = renumber[hull.simplices]
    signed = planes[..., :3].reshape(-1, 3) @ hull.points[corner_ids].T
    signed += planes[..., 3].reshape(-1, 1)
    corner_in = _inside(signed.reshape(n_views, 5, -1))  # (V, corners)
    all_in = corner_in[:, tri[:, 0]] & corner_in[:, tri[:, 1]] & corner_in[:, tri[:, 2]]
    normal, offset = hull.equations[:, :3], hull.equations[:, 3]
    facing = poses[:, :3, 3] @ normal.T + offset > _FACING_TOL  # n . c + d = n . (c - p)
    seen_face = np.ascontiguousarray(facing & all_in)
    counts = np.bincount(face_ids, minlength=n_faces)
    grouped = bool(np.all(face_ids[1:] >= face_ids[:-1]))
    if grouped:
        # Samples grouped by triangle (as sample_on_hull draws them): a row-major repeat, much
        # faster than a gather and C-ordered for the bit packing that follows.
        seen = np.repeat(seen_face, counts, axis=1)
    else:
        seen = np.take(seen_face, face_ids, axis=1)
    cut_view, cut_face = np.nonzero(facing & ~all_in)
    if cut_view.size:
        # Triangles the image border cuts (or that lie outside it): their samples one by one.
        starts = np.cumsum(counts) - counts
        lengths = counts[cut_face]
        first = np.repeat(starts[cut_face] - np.cumsum(lengths) + lengths, lengths)
        sample_idx = first + np.arange(lengths.sum())
        if not grouped:
            sample_idx = np.argsort(face_ids, kind="stable")[sample_idx]
        view_idx = np.repeat(cut_view, lengths)
        p = planes[view_idx]
        signed = np.einsum("mkj,mj->km", p[..., :3], samples[sample_idx]) + p[..., 3].T
        seen[view_idx, sample_idx] = _inside(signed)
    return seen


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
) -> np.ndarray:
    """Each view's set of hull samples (the paper's Algorithm 2).

    Args:
        samples: ``(n, 3)`` points on the hull (:func:`sample_hull`), world units.
        normals: ``(n, 3)`` their outward unit normals.
        poses: ``(V, 4, 4)`` camera-to-world, OpenCV convention.
        intrinsics: the camera.
        method: ``"analytic"`` (fast, exact for a convex surface) or ``"raycast"``
            (:func:`raycast_view_sets`, renders the hull; needs ``hull``).
        eps: capture distance of the ``"raycast"`` path, cloud units (unused by ``"analytic"``).
        hull: the hull (``ConvexHull``, or ``(vertices, faces)`` for ``"raycast"``).
        face_ids: ``(n,)`` triangle of each sample (:func:`sample_hull`). With a ``ConvexHull``
            ``hull``, the analytic path decides whole triangles at once
            (:func:`analytic_visibility_faces`); otherwise each sample on its own
            (:func:`analytic_visibility`). Both give the same sets.

    Returns:
        ``(V, n)`` bool: ``sets[v, i]`` is True when view ``v`` captures sample ``i``.
    """
    if method == "analytic":
        if isinstance(hull, ConvexHull) and face_ids is not None:
            return analytic_visibility_faces(hull, samples, face_ids, poses, intrinsics)
        return analytic_visibility(samples, normals, poses, intrinsics)
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


def greedy_packed(
    rows: np.ndarray, n_iter: int, exclude: Iterable[int] = ()
) -> tuple[list[int], list[int], int]:
    """Greedy maximum coverage on bit rows, see :func:`greedy_max_coverage`.

    Args:
        rows: ``(V, W)`` uint64 bit rows (:func:`pack_sets`); not modified.
        n_iter: number of views to pick.
        exclude: indices of views already visited.

    Returns:
        ``(views, gains, n_covered)``: as :func:`greedy_max_coverage`, plus the number of
        elements covered by the excluded and chosen views together.
    """
    rows = np.asarray(rows)
    if rows.ndim != 2 or rows.dtype != np.uint64:
        raise ValueError(f"rows must be a (V, W) uint64 array, got {rows.dtype} {rows.shape}")
    n_views = rows.shape[0]
    excluded = _as_exclude(exclude, n_views)
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
            # Nothing left to cover: every remaining pick gains 0, lowest indices first.
            rest = np.flatnonzero(~closed)[: n_iter - len(views)].tolist()
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
    sets: np.ndarray, n_iter: int = DEFAULT_N_ITER, exclude: Iterable[int] = ()
) -> tuple[list[int], list[int]]:
    """Greedy maximum coverage (the paper's Algorithm 3).

    Before the first pick, the elements of the excluded views (the views already visited, such
    as the start view) are removed from every set: the plan continues from what those views saw,
    as the paper plans from the start view's cloud. Then, ``n_iter`` times: pick the not yet
    chosen, not excluded view whose set holds the most elements (ties: the lowest index) and
    remove its elements from every set. Views with nothing new are still picked (gain 0) until
    ``n_iter`` views are chosen. The result is within ``1 - 1/e`` of the best ``n_iter`` views.

    Args:
        sets: ``(V, n)`` bool (or 0/1): ``sets[v, i]`` is True when view ``v`` covers element
            ``i``.
        n_iter: number of views to choose, ``<= V - len(exclude)``.
        exclude: indices of views that are already visited: never chosen, their elements count
            as covered.

    Returns:
        ``(views, gains)``: the ``n_iter`` chosen view indices in order, and the number of
        elements each newly covered (its marginal gain; non-increasing).
    """
    views, gains, _ = greedy_packed(pack_sets(sets), n_iter, exclude)
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
    sets = view_sets(samples, normals, poses, intrinsics, method, eps, hull, face_ids)
    t3 = clock()
    rows = pack_sets(sets)
    t4 = clock()
    views, gains, n_covered = greedy_packed(rows, n_iter, excluded)
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
) -> Plan:
    """Convex-hull set-cover plan from a partial cloud (the paper's Algorithms 2 and 3).

    Args:
        points: ``(N, 3)`` partial cloud (what the visited views saw), world units.
        viewspace: ``(V, 3)`` camera positions; every camera looks at the origin.
        n_iter: number of views to plan, ``<= V - len(exclude)``.
        exclude: indices of the views already visited (the start view): never chosen, and the
            hull samples they capture count as covered before the first pick.
        n_samp: number of hull samples.
        rng: numpy Generator or integer seed (only the sampling is random).
        method: view simulation, ``"analytic"`` or ``"raycast"`` (see :func:`view_sets`).
        intrinsics: the camera.
        eps: capture distance of the ``"raycast"`` path.
        poses: ``(V, 4, 4)`` :func:`nbv.camera.viewspace_poses` of ``viewspace``, when the
            caller has them already (they are the same for every plan on one viewspace).

    Returns:
        :class:`Plan`.

    Raises:
        ValueError: for a cloud whose hull has no volume (flat, colinear, fewer than 4 points)
            and for bad arguments.
    """
    return _plan_on_cloud(
        points, viewspace, n_iter, exclude, n_samp, rng, method, intrinsics, eps, poses, {}
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
) -> Plan:
    """Convex-hull set cover on the hull of the cloud's spherical signature.

    Same as :func:`plan`, but the hull is that of :func:`sph_hull_points` (the signature of
    degree ``lmax`` placed at the cloud's centroid) instead of the cloud's own. ``timings`` gets
    a ``signature`` entry too.
    """
    t0 = time.perf_counter()
    signature = sph_hull_points(points, lmax)
    timings = {"signature": time.perf_counter() - t0}
    return _plan_on_cloud(
        signature, viewspace, n_iter, exclude, n_samp, rng, method, intrinsics, eps, poses, timings
    )
