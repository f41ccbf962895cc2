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
  scores. This is the definition; it is slow.
* ``"analytic"`` (the fast one) needs no rendering. A convex surface cannot occlude itself, so
  a hull sample ``p`` with outward normal ``n`` is seen from a camera centred at ``c`` exactly
  when its face looks at the camera, ``n . (c - p) > 0``, and it projects inside the image,
  ``0 <= u <= W - 1`` and ``0 <= v <= H - 1`` (pixel-centre coordinates of :mod:`nbv.camera`)
  in front of the camera: sign tests of dot products, for all views and samples at once
  (:func:`analytic_visibility_faces`). Then the dilation by ``eps``
  (:func:`dilate_view_sets`): samples the view does not see but that lie within ``eps`` of a
  point it captures, just behind the silhouette or just outside the image. Those lie within
  ``eps`` of a triangle facing the camera (found once per hull, :func:`near_triangles`), and
  whether a pixel's ray hits that triangle within ``eps`` of the sample is solved exactly (the
  pixels that do fill an ellipse in the image): a purely geometric "within ``eps`` of the
  facing surface" would overshoot, as near a silhouette that surface is seen edge-on and its
  pixels' points lie far apart.

  The two paths then differ in one way only: a sample on a face seen so obliquely that the
  pixels' points on it lie farther apart than ``eps`` is kept by ``"analytic"`` though no point
  may come within ``eps``. Measured at 640 x 480, ``eps = 0.00707``, 33 views at distance 1,
  4096 samples, on (view, sample) pairs: the two agree on 99.35 % for a sphere and 99.45 % for
  a box (the visible sets alone: 99.07 and 98.57 %), and on 98.5 to 99.5 % for hulls of single
  full-resolution views of common test meshes (97.1 to 97.9 % for a flat one; visible sets
  alone: 96.9 to 98.9 %, and 61 % for the flat one, whose back lies within ``eps`` of its
  front). Everything ``"raycast"`` captures ``"analytic"`` captures too, but for rays that slip
  between the triangles of the float32 render (under 0.1 % of pairs).

Cameras sit at the viewspace positions and look at the origin (:func:`nbv.camera.viewspace_poses`).
Distances are in the cloud's units (the normalised object frame, where the object fits in a
sphere of radius 0.5 and the cameras are at distance 1). Times in :class:`Plan` are seconds.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

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
#: A triangle whose bounding ball, grown by eps, holds at most this many samples (expected)
#: is "small" for :func:`near_triangles`: its nearby samples are found with a k-d tree, not
#: through pairs of triangles ...
_BALL_SAMPLES = 64.0
#: ... provided there is at least one small triangle for this many samples.
_SAMPLES_PER_TREE_QUERY = 64
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


def _frustum_planes(poses: np.ndarray, intrinsics: Intrinsics, margin: float = 0.0) -> np.ndarray:
    """Half-spaces of each camera's image, ``(V, 5, 4)``: ``a . p + b >= 0`` inside.

    Rows: in front (``z > 0``), ``u >= 0``, ``u <= W - 1``, ``v >= 0``, ``v <= H - 1``; with
    ``(x, y, z)`` the camera-frame point, ``u >= 0`` is ``fx x + cx z >= 0`` (for ``z > 0``), and
    so on: planes through the camera centre, rotated to the world. With ``margin > 0`` (cloud
    units) the four side planes move out by ``margin``: a point passes them when its Euclidean
    distance to their half-space is at most ``margin``. ``margin = 0`` leaves them untouched.
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
    if margin:
        # a . p + b >= -margin |a| is "signed distance >= -margin"; shifting b keeps every
        # later test a plain sign test.
        offset[:, 1:] += margin * np.linalg.norm(normal[:, 1:], axis=2)
    return np.concatenate([normal, offset[..., None]], axis=2)


def _as_margin(margin: float, name: str = "margin") -> float:
    value = float(margin)
    if not (np.isfinite(value) and value >= 0.0):
        raise ValueError(f"{name} must be a finite distance >= 0, got {margin!r}")
    return value


def analytic_visibility(
    samples: np.ndarray,
    normals: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    margin: float = 0.0,
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
        margin: widen the image by this distance (world units, ``>= 0``): a facing point also
            counts when it lies outside the image but within ``margin`` of each of the four
            planes through the camera centre and the image borders (:func:`dilate_view_sets`
            finds the samples just outside the image with ``margin = eps``). ``0`` is the exact
            test above.

    Returns:
        ``(V, n)`` bool.
    """
    samples = as_cloud(samples, "samples")
    normals = as_cloud(normals, "normals")
    if normals.shape != samples.shape:
        raise ValueError(f"normals {normals.shape} must match samples {samples.shape}")
    poses = _as_poses(poses)
    planes = _frustum_planes(poses, intrinsics, _as_margin(margin))
    n_views, n = len(poses), len(samples)
    homog = np.empty((4, n))
    homog[:3] = samples.T
    homog[3] = 1.0
    signed = (planes.reshape(-1, 4) @ homog).reshape(n_views, 5, n)
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


def _inside_pairs(
    planes: np.ndarray, view_idx: np.ndarray, samples: np.ndarray, sample_idx: np.ndarray
) -> np.ndarray:
    """:func:`_inside` for (view, sample) pairs: ``(m,)`` bool.

    Args:
        planes: ``(V, 5, 4)`` :func:`_frustum_planes`.
        view_idx: ``(m,)`` view of each pair.
        samples: ``(n, 3)`` points, world units.
        sample_idx: ``(m,)`` sample of each pair.
    """
    # Coordinates in rows and one gathered row per coefficient: faster than a (m, 5, 4) gather.
    xyz = np.take(samples.T, sample_idx, axis=1)
    columns = np.ascontiguousarray(planes.transpose(1, 2, 0))  # (5, 4, V)
    inside = _affine_at(np.take(columns[0], view_idx, axis=1), xyz) > 0.0
    for k in range(1, 5):
        inside &= _affine_at(np.take(columns[k], view_idx, axis=1), xyz) >= 0.0
    return inside


def _as_face_ids(face_ids: np.ndarray, hull: ConvexHull, n: int) -> np.ndarray:
    face_ids = np.asarray(face_ids)
    n_faces = len(hull.simplices)
    if face_ids.shape != (n,) or not np.issubdtype(face_ids.dtype, np.integer):
        raise ValueError(
            f"face_ids must be ({n},) integers like samples, got {face_ids.dtype} {face_ids.shape}"
        )
    if face_ids.size and (face_ids.min() < 0 or face_ids.max() >= n_faces):
        raise ValueError(f"face_ids must lie in [0, {n_faces}), the hull's triangles")
    return face_ids


def _ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """``concatenate([arange(a, a + k) for a, k in zip(starts, lengths)])``, vectorised."""
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, dtype=np.intp)
    shift = np.repeat(starts - np.cumsum(lengths) + lengths, lengths)
    return shift + np.arange(total)


def analytic_visibility_faces(
    hull: ConvexHull,
    samples: np.ndarray,
    face_ids: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    margin: float = 0.0,
) -> np.ndarray:
    """:func:`analytic_visibility` decided per triangle: the same answer, much less work.

    A triangle's samples share its normal, so "faces the camera" is one test per triangle. The
    image is convex, so a triangle whose three corners lie inside it lies wholly inside; only
    the samples of the other triangles that face the camera (those an image border cuts, or
    that lie outside the image) are tested one by one. The image widened by ``margin`` is
    convex too, so the same holds with a margin.

    Args:
        hull: the ``ConvexHull`` the samples were drawn on.
        samples: ``(n, 3)`` points on it, world units.
        face_ids: ``(n,)`` index into ``hull.simplices`` of the triangle of each sample.
        poses: ``(V, 4, 4)`` camera-to-world, OpenCV convention.
        intrinsics: the camera.
        margin: widen the image by this distance, world units (see :func:`analytic_visibility`).

    Returns:
        ``(V, n)`` bool.
    """
    samples = as_cloud(samples, "samples")
    face_ids = _as_face_ids(face_ids, hull, len(samples))
    poses = _as_poses(poses)
    n_faces = len(hull.simplices)
    n_views = len(poses)
    planes = _frustum_planes(poses, intrinsics, _as_margin(margin))  # (V, 5, 4)
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
        sample_idx = _ranges(starts[cut_face], lengths)
        if not grouped:
            sample_idx = np.argsort(face_ids, kind="stable")[sample_idx]
        view_idx = np.repeat(cut_view, lengths)
        seen[view_idx, sample_idx] = _inside_pairs(planes, view_idx, samples, sample_idx)
    return seen


# --------------------------------------------------------------------------------------------
# Dilation by eps: the samples a view's points come within eps of
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class NearTriangles:
    """Hull samples within ``eps`` of a hull triangle other than their own.

    View-independent (:func:`near_triangles`). The pairs come in groups, one group per
    ``(own, other)`` pair of triangles: group ``g`` holds the samples
    ``sample[starts[g]:starts[g + 1]]``, all on triangle ``own[g]`` and within ``eps`` of triangle
    ``other[g]``. Groups are sorted by ``own``, then ``other``.

    Attributes:
        own: ``(G,)`` int64 triangle (index into ``hull.simplices``) the group's samples lie on.
        other: ``(G,)`` int64 the nearby triangle.
        starts: ``(G + 1,)`` int64 offsets of the groups into ``sample``.
        sample: ``(m,)`` int64 sample indices, grouped, ascending within a group.
        eps: the distance the pairs were found with, world units.
    """

    own: np.ndarray
    other: np.ndarray
    starts: np.ndarray
    sample: np.ndarray
    eps: float


def _beyond_planes(corners: np.ndarray, equations: np.ndarray) -> np.ndarray:
    """Four affine functions per hull triangle that bound the distance to it from below.

    Returns ``(4, 4, F)``: function ``k`` of triangle ``f`` is
    ``p -> out[k, :3, f] . p + out[k, 3, f]``. Function 0 is the distance below the triangle's
    plane (every hull point lies on the inner side of every facet plane, where it is ``>= 0``);
    functions 1 to 3 are how far, measured in the plane, ``p`` lies beyond the line of the
    edge from corner ``k - 1`` to corner ``k`` (negative on the triangle's side). A point's
    squared distance to the triangle is its squared height plus its squared in-plane
    distance, so at least ``f0^2 + max(f1, f2, f3, 0)^2``, with equality unless its nearest
    point is a corner. A zero-length edge gets the zero function.

    Args:
        corners: ``(F, 3, 3)`` the triangles.
        equations: ``(F, 4)`` their outward unit planes, ``ConvexHull.equations``.
    """
    edges = corners[:, [1, 2, 0]] - corners
    normal = np.cross(equations[:, None, :3], edges)
    length = np.linalg.norm(normal, axis=2, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0.0)
    # Qhull does not orient its triangles: point every normal away from the opposite corner.
    towards = np.einsum("fkj,fkj->fk", normal, corners[:, [2, 0, 1]] - corners)
    normal *= np.where(towards > 0.0, -1.0, 1.0)[..., None]
    offset = -np.einsum("fkj,fkj->fk", normal, corners)
    out = np.empty((4, 4, len(corners)))
    out[0] = -equations.T
    out[1:, :3] = normal.transpose(1, 2, 0)
    out[1:, 3] = offset.T
    return out


def _ball_pairs(
    centre_a: np.ndarray,
    radius_a: np.ndarray,
    centre_b: np.ndarray,
    radius_b: np.ndarray,
    eps: float,
) -> tuple[np.ndarray, np.ndarray]:
    """All ``(i, j)`` whose balls come within ``eps``: ``|a_i - b_j| <= r_i + r_j + eps``.

    k-d trees over the centres, one per class of radii (powers of two times ``eps``), so that
    a few large balls among many small ones do not widen every query.

    Args:
        centre_a, centre_b: ``(A, 3)`` and ``(B, 3)`` ball centres, world units.
        radius_a, radius_b: ``(A,)`` and ``(B,)`` their radii, ``>= 0``.
        eps: the distance, world units.

    Returns:
        ``(i, j)``: ``(P,)`` intp indices into ``a`` and ``b``.
    """

    def classes(centre: np.ndarray, radius: np.ndarray) -> list[tuple[np.ndarray, cKDTree, float]]:
        level = np.ceil(np.log2(np.maximum(radius / max(eps, 1e-12), 1.0))).astype(np.intp)
        members = [np.flatnonzero(level == k) for k in np.unique(level)]
        return [(m, cKDTree(centre[m]), float(radius[m].max())) for m in members]

    found_i, found_j = [np.zeros(0, dtype=np.intp)], [np.zeros(0, dtype=np.intp)]
    if len(centre_a) and len(centre_b):
        classes_b = classes(centre_b, radius_b)
        for ia, tree_a, max_a in classes(centre_a, radius_a):
            for jb, tree_b, max_b in classes_b:
                near = tree_a.sparse_distance_matrix(
                    tree_b, max_a + max_b + eps, output_type="ndarray"
                )
                i, j = ia[near["i"]], jb[near["j"]]
                keep = near["v"] <= radius_a[i] + radius_b[j] + eps
                found_i.append(i[keep])
                found_j.append(j[keep])
    return np.concatenate(found_i), np.concatenate(found_j)


def _barycentric_duals(corners: np.ndarray) -> np.ndarray:
    """Affine functions giving the barycentric coordinates of a point in its triangle.

    Returns ``(3, 4, F)``: coordinate ``j`` (the weight of corner ``j``) of a point ``p`` of
    triangle ``f`` is ``out[j, :3, f] . p + out[j, 3, f]``. Degenerate triangles get zeros.
    """
    origin = corners[:, 0]
    e1, e2 = corners[:, 1] - origin, corners[:, 2] - origin
    g11 = np.einsum("ij,ij->i", e1, e1)
    g12 = np.einsum("ij,ij->i", e1, e2)
    g22 = np.einsum("ij,ij->i", e2, e2)
    det = g11 * g22 - g12 * g12
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=det > 0.0)
    out = np.zeros((3, 4, len(corners)))
    out[1, :3] = ((g22 * inv)[:, None] * e1 - (g12 * inv)[:, None] * e2).T
    out[2, :3] = ((g11 * inv)[:, None] * e2 - (g12 * inv)[:, None] * e1).T
    out[1:, 3] = -np.einsum("kjf,fj->kf", out[1:, :3], origin)
    out[0, :3] = -out[1, :3] - out[2, :3]
    out[0, 3] = 1.0 - out[1, 3] - out[2, 3]
    return out


def _affine_at(function: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``function[:3] . point + function[3]`` elementwise: ``(4, ...)`` and ``(3, ...)``.

    Coefficients and coordinates in rows, because numpy is slow at reducing axes of length 3.
    """
    out = function[0] * points[0]
    out += function[1] * points[1]
    out += function[2] * points[2]
    out += function[3]
    return out


def _edge_sq_distance(corners: np.ndarray, tri: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Squared distance of each point to the nearest of the three edges of its triangle.

    Args:
        corners: ``(F, 3, 3)`` triangles.
        tri: ``(m,)`` triangle of each point.
        xyz: ``(3, m)`` the points, coordinates in rows.

    Returns:
        ``(m,)``: the squared distance to the triangle for points whose foot on its plane lies
        outside it.
    """
    start = np.ascontiguousarray(corners.transpose(1, 2, 0))  # (corner, xyz, F)
    edge = start[[1, 2, 0]] - start
    inv_sq = 1.0 / np.maximum((edge * edge).sum(axis=1), 1e-300)  # (3, F)
    best = np.full(len(tri), np.inf)
    for k in range(3):
        e = np.take(edge[k], tri, axis=1)
        rel = xyz - np.take(start[k], tri, axis=1)
        t = rel[0] * e[0] + rel[1] * e[1] + rel[2] * e[2]
        t *= np.take(inv_sq[k], tri)
        np.clip(t, 0.0, 1.0, out=t)
        rel -= t * e
        np.minimum(best, rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2], out=best)
    return best


def _coordinate_ranges(values: np.ndarray, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on each barycentric coordinate of the points where affine functions are ``<= eps``.

    Args:
        values: ``(K, 3, P)`` values of ``K`` affine functions at the three corners of each of
            ``P`` triangles.
        eps: the threshold.

    Returns:
        ``(lo, hi)``, ``(3, P)`` each: a point of triangle ``p`` where all ``K`` functions are
        ``<= eps`` has barycentric coordinate ``j`` in ``[lo[j, p], hi[j, p]]``. With ``m`` the
        smaller value at the two other corners, a function's value is at least
        ``m + lambda_j (c_j - m)`` on the triangle.
    """
    lo = np.zeros(values.shape[1:])
    hi = np.ones(values.shape[1:])
    for j in range(3):
        c = values[:, j]
        m = np.minimum(values[:, (j + 1) % 3], values[:, (j + 2) % 3])
        slope = c - m
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = (eps - m) / slope
        for k in range(len(values)):
            np.minimum(hi[j], np.where(slope[k] > 0.0, bound[k], 1.0), out=hi[j])
            np.maximum(lo[j], np.where(slope[k] < 0.0, bound[k], 0.0), out=lo[j])
    return lo, hi


def _candidates_by_pairs(
    samples: np.ndarray,
    face_ids: np.ndarray,
    corners: np.ndarray,
    bounds: np.ndarray,
    centre: np.ndarray,
    radius: np.ndarray,
    large: np.ndarray,
    eps: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Candidate ``(sample, triangle)`` pairs for the large triangles, through triangle pairs.

    Pairs ``(own, other)``, ``other`` large, whose bounding balls come within ``eps``; the four
    lower bounds of :func:`_beyond_planes` of ``other`` must come within ``eps`` on ``own``
    (first at its ball, then exactly at its corners), which bounds the barycentric
    coordinates of the samples of ``own`` that can qualify: with the samples of each triangle
    sorted by one coordinate, they form one contiguous range.

    Args:
        samples: ``(n, 3)``, face_ids: ``(n,)``: the hull samples and their triangles.
        corners: ``(F, 3, 3)`` the triangles; bounds: ``(4, 4, F)`` their
            :func:`_beyond_planes`; centre, radius: ``(F, 3)``, ``(F,)`` their bounding balls.
        large: ``(L,)`` indices of the triangles to find samples near.
        eps: the distance, world units.

    Returns:
        ``(sample, triangle)``: ``(m,)`` intp each, a superset of the pairs within ``eps``.
    """
    own, other = _ball_pairs(centre, radius, centre[large], radius[large], eps)
    other = large[other]
    # A large ball holds many triangles far from its (flat) triangle. The bounds change by at
    # most the distance moved (unit gradients): at the own centroid each must be within the
    # own radius of eps.
    keep = own != other
    centre_xyz = np.ascontiguousarray(centre.T)
    for k in range(4):
        value = _affine_at(np.take(bounds[k], other, axis=1), np.take(centre_xyz, own, axis=1))
        keep &= value <= radius[own] + eps
    own, other = own[keep], other[keep]
    own_corners = corners[own].transpose(2, 1, 0)  # (xyz, corner, P)
    values = np.stack([_affine_at(bounds[k][:, other], own_corners) for k in range(4)])
    lo, hi = _coordinate_ranges(values, eps)  # (3, P) each
    # Each bound must reach eps somewhere on the own triangle, at a corner if anywhere.
    lowest = np.minimum(np.minimum(values[:, 0], values[:, 1]), values[:, 2])
    feasible = np.all(lowest <= eps, axis=0) & np.all(lo <= hi, axis=0)
    own, other, lo, hi = own[feasible], other[feasible], lo[:, feasible], hi[:, feasible]
    # The coordinate whose range holds the fewest samples of a uniform triangle: the fraction
    # with lambda_j in [a, b] is (1 - a)^2 - (1 - b)^2. Widened by 1e-9 against rounding.
    lo, hi = np.clip(lo - 1e-9, 0.0, 1.0), np.clip(hi + 1e-9, 0.0, 1.0)
    axis = np.argmin((1.0 - lo) ** 2 - (1.0 - hi) ** 2, axis=0)
    pick = np.arange(len(own))
    lo, hi = lo[axis, pick], hi[axis, pick]
    duals = _barycentric_duals(corners)
    xyz = np.ascontiguousarray(samples.T)
    sorted_by = np.zeros((3, len(samples)), dtype=np.intp)
    first, stop = np.zeros(len(own), dtype=np.intp), np.zeros(len(own), dtype=np.intp)
    for j in np.unique(axis):
        # Keys face + lambda_j / 2 sort by triangle, then by the coordinate within it.
        weight = _affine_at(np.take(duals[j], face_ids, axis=1), xyz)
        key = face_ids + 0.5 * np.clip(weight, 0.0, 1.0)
        sorted_by[j] = np.argsort(key)
        key = key[sorted_by[j]]
        chosen = axis == j
        first[chosen] = np.searchsorted(key, own[chosen] + 0.5 * lo[chosen], side="left")
        stop[chosen] = np.searchsorted(key, own[chosen] + 0.5 * hi[chosen], side="right")
    lengths = stop - first
    pair = np.repeat(np.arange(len(own)), lengths)
    return sorted_by[axis[pair], _ranges(first, lengths)], other[pair]


def near_triangles(
    hull: ConvexHull, samples: np.ndarray, face_ids: np.ndarray, eps: float = DEFAULT_EPS
) -> NearTriangles:
    """Pair every hull sample with the other hull triangles within ``eps`` of it, exactly.

    These are the triangles whose pixels can capture the sample in a view (see
    :func:`dilate_view_sets`), even when the sample's own triangle is turned away. Candidates
    first, by triangle size next to ``eps``: for small triangles, the samples in their
    bounding ball grown by ``eps`` (k-d trees); for large ones, through pairs of triangles and
    ranges of barycentric coordinates (:func:`_candidates_by_pairs`). Then per candidate the
    four lower bounds of :func:`_beyond_planes`, which are exact unless the nearest point is
    beyond an edge, where the distance to the three edges decides.

    Args:
        hull: the ``ConvexHull`` the samples were drawn on.
        samples: ``(n, 3)`` points on it, world units.
        face_ids: ``(n,)`` index into ``hull.simplices`` of each sample's triangle.
        eps: the distance, world units, ``>= 0``; a pair is kept when the distance is ``<= eps``.

    Returns:
        :class:`NearTriangles`.
    """
    samples = as_cloud(samples, "samples")
    face_ids = _as_face_ids(face_ids, hull, len(samples))
    eps = _as_margin(eps, "eps")
    n_faces = len(hull.simplices)
    corners = hull.points[hull.simplices]  # (F, 3, 3)
    bounds = _beyond_planes(corners, hull.equations)  # (4, 4, F)
    centre = corners.mean(axis=1)
    radius = np.linalg.norm(corners - centre[:, None], axis=2).max(axis=1)
    density = len(samples) / max(float(hull.area), 1e-300)
    small = density * np.pi * (radius + eps) ** 2 <= _BALL_SAMPLES
    if small.sum() * _SAMPLES_PER_TREE_QUERY < len(samples):
        small[:] = False  # a tree over the samples would cost more than it saves
    near_sample, near_tri = _ball_pairs(
        samples, np.zeros(len(samples)), centre[small], radius[small], eps
    )
    by_pairs = _candidates_by_pairs(
        samples, face_ids, corners, bounds, centre, radius, np.flatnonzero(~small), eps
    )
    sample_idx = np.concatenate([near_sample, by_pairs[0]])
    tri = np.concatenate([np.flatnonzero(small)[near_tri], by_pairs[1]])
    keep = tri != face_ids[sample_idx]
    sample_idx, tri = sample_idx[keep], tri[keep]

    xyz = np.take(samples.T, sample_idx, axis=1)
    height = _affine_at(np.take(bounds[0], tri, axis=1), xyz)
    over = np.zeros(len(tri))
    for k in (1, 2, 3):
        np.maximum(over, _affine_at(np.take(bounds[k], tri, axis=1), xyz), out=over)
    eps_sq = eps * eps
    close = (height <= eps) & (height * height + over * over <= eps_sq)
    outside = np.flatnonzero(close & (over > 0.0))
    if outside.size:
        close[outside] = _edge_sq_distance(corners, tri[outside], xyz[:, outside]) <= eps_sq

    sample_idx, tri = sample_idx[close].astype(np.int64), tri[close].astype(np.int64)
    key = face_ids[sample_idx].astype(np.int64) * n_faces + tri
    order = np.lexsort((sample_idx, key))
    key, sample_idx = key[order], sample_idx[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if key.size else key
    own, other = np.divmod(key[first], n_faces)
    starts = np.append(first, len(key)).astype(np.int64)
    return NearTriangles(own, other, starts, sample_idx, eps)


def _pixel_capture(
    samples: np.ndarray,
    sample_idx: np.ndarray,
    view_idx: np.ndarray,
    tri_idx: np.ndarray,
    hull: ConvexHull,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    eps: float,
) -> np.ndarray:
    """Whether a pixel of the view hits the triangle within ``eps`` of the sample: ``(m,)`` bool.

    For triples (view, sample, hull triangle facing the view). A pixel centre ``x = (u, v)``,
    integers in ``[0, W - 1] x [0, H - 1]``, casts the ray ``s m(x)`` (camera frame,
    ``m(x) = ((u - cx) / fx, (v - cy) / fy, 1)``, as :func:`nbv.render.render_raycast` does).
    On a convex hull it first hits the facing triangle whose projection holds ``x`` (three
    linear inequalities in ``x``), where it meets that triangle's plane ``n . y + h = 0``. That
    point lies within ``eps`` of the sample ``y`` (camera frame) iff
    ``|h m(x) + (n . m(x)) y| <= eps |n . m(x)|``: both sides are affine in ``x``, so the
    pixels that pass lie inside a conic, an ellipse for any triangle not seen almost exactly
    edge-on. The rows (or columns, whichever are fewer) that cross the ellipse are tried from
    its centre outwards: one passes when an integer lies inside the ellipse, the image and
    the triangle's projection on it. Exact up to rounding; a triangle whose conic is not an
    ellipse (the camera within about ``eps`` of its plane) is taken to show no pixel.

    Args:
        samples: ``(n, 3)`` hull samples, world units.
        sample_idx: ``(m,)`` sample of each triple.
        view_idx: ``(m,)`` view of each triple.
        tri_idx: ``(m,)`` hull triangle of each triple; it must face the view.
        hull: the ``ConvexHull``.
        poses: ``(V, 4, 4)`` camera-to-world, OpenCV convention.
        intrinsics: the camera.
        eps: capture distance, world units.
    """
    k = intrinsics
    out = np.zeros(len(sample_idx), dtype=bool)
    if out.size == 0:
        return out
    n_faces = len(hull.simplices)
    combo, inverse = np.unique(view_idx * n_faces + tri_idx, return_inverse=True)
    c_view, c_tri = np.divmod(combo, n_faces)
    rot, centre = poses[c_view, :3, :3], poses[c_view, :3, 3]
    plane = hull.equations[c_tri]
    normal = np.einsum("cji,cj->ic", rot, plane[:, :3])  # (3, C), camera frame
    height = np.einsum("cj,cj->c", plane[:, :3], centre) + plane[:, 3]
    corner = np.einsum("cji,ckj->kic", rot, hull.points[hull.simplices[c_tri]] - centre[:, None])
    # The triangle's projection: per edge, the plane through the camera centre and the edge
    # in pixel coordinates, ">= 0" inside; and its pixel bounding box (when all corners lie
    # in front of the camera), to skip rows that cannot cross it.
    edges = np.empty((3, 3, len(combo)))  # (edge, coefficient of u, v, 1, combo)
    for e in range(3):
        side = np.cross(corner[e], corner[(e + 1) % 3], axis=0)
        side *= np.where((side * corner[(e + 2) % 3]).sum(axis=0) < 0.0, -1.0, 1.0)
        edges[e, 0] = side[0] / k.fx
        edges[e, 1] = side[1] / k.fy
        edges[e, 2] = side[2] - side[0] * k.cx / k.fx - side[1] * k.cy / k.fy
    front = np.all(corner[:, 2] > 0.0, axis=0)
    depth = np.where(front, corner[:, 2], 1.0)
    box = np.empty((2, 2, len(combo)))  # (u or v, min or max, combo)
    for axis, (f, c) in enumerate(((k.fx, k.cx), (k.fy, k.cy))):
        pix = f * corner[:, axis] / depth + c
        box[axis, 0] = np.where(front, pix.min(axis=0), -np.inf)
        box[axis, 1] = np.where(front, pix.max(axis=0), np.inf)

    # The samples in each view's camera frame, one product per view (faster than a gather of
    # a rotation per triple).
    y = np.empty((3, len(sample_idx)))
    by_view = np.argsort(view_idx, kind="stable")
    bounds_v = np.searchsorted(view_idx[by_view], np.arange(len(poses) + 1))
    for v in np.flatnonzero(np.diff(bounds_v)):
        sel = by_view[bounds_v[v] : bounds_v[v + 1]]
        y[:, sel] = poses[v, :3, :3].T @ (samples[sample_idx[sel]] - poses[v, :3, 3]).T
    n = normal[:, inverse]
    h = height[inverse]
    ahead = y[2] > 0.0
    z = np.where(ahead, y[2], 1.0)
    ray = y / z  # m(x) at the sample's own projection
    gu, gv = n[0] / k.fx, n[1] / k.fy  # gradient of n . m(x)
    g0 = n[0] * ray[0] + n[1] * ray[1] + n[2]
    # With x = the sample's projection + d: h m + (n . m) y = w0 + A d and n . m = g0 + g . d.
    w0 = (n[0] * y[0] + n[1] * y[1] + n[2] * y[2] + h) * ray
    a_u = z * gu * ray
    a_u[0] += h / k.fx
    a_v = z * gv * ray
    a_v[1] += h / k.fy

    def dot(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]

    eps_sq = eps * eps
    p_uu = dot(a_u, a_u) - eps_sq * gu * gu
    p_uv = dot(a_u, a_v) - eps_sq * gu * gv
    p_vv = dot(a_v, a_v) - eps_sq * gv * gv
    q_u = dot(a_u, w0) - eps_sq * g0 * gu
    q_v = dot(a_v, w0) - eps_sq * g0 * gv
    det = p_uu * p_vv - p_uv * p_uv
    ellipse = ahead & (p_uu > 0.0) & (det > 0.0)
    det = np.where(ellipse, det, 1.0)
    # (x - c)^T P (x - c) <= kappa, in pixels.
    kappa = (p_vv * q_u * q_u - 2.0 * p_uv * q_u * q_v + p_uu * q_v * q_v) / det
    kappa -= dot(w0, w0) - eps_sq * g0 * g0
    ellipse &= kappa >= 0.0
    c_u = k.fx * ray[0] + k.cx - (p_vv * q_u - p_uv * q_v) / det
    c_v = k.fy * ray[1] + k.cy - (p_uu * q_v - p_uv * q_u) / det
    half_u = np.sqrt(np.maximum(kappa * p_vv / det, 0.0))
    half_v = np.sqrt(np.maximum(kappa * p_uu / det, 0.0))
    # Walk along the shorter axis "a" (rows when it is v) and solve along the other, "b".
    rows = half_v <= half_u
    centre_a, centre_b = np.where(rows, c_v, c_u), np.where(rows, c_u, c_v)
    half = np.where(rows, half_v, half_u)
    p_aa, p_bb = np.where(rows, p_vv, p_uu), np.where(rows, p_uu, p_vv)
    axis_a = rows.astype(np.intp)  # 1: v, 0: u
    first = np.maximum(np.ceil(centre_a - half), 0.0)
    first = np.maximum(first, np.ceil(box[axis_a, 0, inverse]))
    last = np.minimum(np.floor(centre_a + half), np.where(rows, k.height - 1, k.width - 1))
    last = np.minimum(last, np.floor(box[axis_a, 1, inverse]))
    lim_b = np.where(rows, k.width - 1, k.height - 1)
    start = np.clip(np.round(centre_a), first, last)
    coef_a = edges[:, np.where(rows, 1, 0), inverse]  # (3, m): the edges' coefficients of a
    coef_b = edges[:, np.where(rows, 0, 1), inverse]
    coef_1 = edges[:, 2, inverse]
    todo = np.flatnonzero(ellipse & (first <= last))
    step = 0
    while todo.size:
        # Offsets 0, 1, -1, 2, -2, ... from the row nearest the centre: most samples that
        # are captured are captured on the first.
        offset = (step + 1) // 2 * (1 if step % 2 else -1)
        step += 1
        line = start[todo] + offset
        valid = (line >= first[todo]) & (line <= last[todo])
        idx, line = todo[valid], line[valid]
        da = line - centre_a[idx]
        pab, pbb = p_uv[idx], p_bb[idx]
        disc = pab * pab * da * da - pbb * (p_aa[idx] * da * da - kappa[idx])
        root = np.sqrt(np.maximum(disc, 0.0))
        lo = np.maximum(centre_b[idx] + (-pab * da - root) / pbb, 0.0)
        hi = np.minimum(centre_b[idx] + (-pab * da + root) / pbb, lim_b[idx])
        hit = disc >= 0.0
        for e in range(3):
            cb = coef_b[e, idx]
            rest = coef_a[e, idx] * line + coef_1[e, idx]  # inside: cb * x_b + rest >= 0
            with np.errstate(divide="ignore", invalid="ignore"):
                bound = -rest / cb
            lo = np.where(cb > 0.0, np.maximum(lo, bound), lo)
            hi = np.where(cb < 0.0, np.minimum(hi, bound), hi)
            hit &= (cb != 0.0) | (rest >= 0.0)
        hit &= np.ceil(lo) <= np.floor(hi)
        out[idx[hit]] = True
        # Go on with the triples not yet captured whose rows are not all tried.
        reach = (step + 1) // 2
        todo = todo[
            ~out[todo]
            & ((start[todo] - reach >= first[todo]) | (start[todo] + reach <= last[todo]))
        ]
    return out


def _near_by_sample(near: NearTriangles, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The nearby triangles of each sample: CSR ``(starts (n + 1,), triangles (m,))``."""
    other = np.repeat(near.other, np.diff(near.starts))
    order = np.argsort(near.sample, kind="stable")
    starts = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(near.sample, minlength=n), out=starts[1:])
    return starts, other[order]


def dilate_view_sets(
    seen: np.ndarray,
    samples: np.ndarray,
    face_ids: np.ndarray,
    hull: ConvexHull,
    near: NearTriangles,
    poses: np.ndarray,
    intrinsics: Intrinsics,
) -> np.ndarray:
    """Add to each view's visible set the samples its pixels' points come within ``eps`` of.

    Two kinds of samples a view does not see lie within ``eps = near.eps`` of the points a
    ray-cast view of the hull captures (:func:`raycast_view_sets`): samples just behind its
    silhouette, on a triangle turned away but within ``eps`` of one facing the camera
    (:func:`near_triangles`), and samples on facing triangles just outside the image, within
    ``eps`` of its border planes (:func:`analytic_visibility_faces` with ``margin=eps``). Being
    within ``eps`` of the facing surface is not enough: near a silhouette that surface is seen
    nearly edge-on and the pixels' points on it lie far apart. So each such sample is tested
    against the pixels themselves: it is added when the ray of some pixel centre hits a nearby
    facing triangle (its own included) within ``eps`` of it, solved exactly per triangle
    without rendering (the pixels whose hit lies within ``eps`` fill an ellipse in the image).

    Args:
        seen: ``(V, n)`` bool visible sets (:func:`analytic_visibility_faces`, no margin);
            not modified.
        samples: ``(n, 3)`` hull samples, world units.
        face_ids: ``(n,)`` index into ``hull.simplices`` of each sample's triangle.
        hull: the ``ConvexHull`` they lie on.
        near: :func:`near_triangles` of ``hull`` and ``samples``.
        poses: ``(V, 4, 4)`` camera-to-world, OpenCV convention.
        intrinsics: the camera.

    Returns:
        ``(V, n)`` bool: ``seen`` with the added samples.
    """
    samples = as_cloud(samples, "samples")
    face_ids = _as_face_ids(face_ids, hull, len(samples))
    poses = _as_poses(poses)
    seen = np.asarray(seen, dtype=bool)
    if seen.shape != (len(poses), len(samples)):
        raise ValueError(f"seen must have shape {(len(poses), len(samples))}, got {seen.shape}")
    seen = seen.copy()
    normal, offset = hull.equations[:, :3], hull.equations[:, 3]
    facing = poses[:, :3, 3] @ normal.T + offset > _FACING_TOL  # (V, F)
    # Behind the silhouette: own triangle turned away, the nearby one facing.
    hit_view, hit_group = np.nonzero(facing[:, near.other] & ~facing[:, near.own])
    lengths = np.diff(near.starts)[hit_group]
    views = [np.repeat(hit_view, lengths)]
    picks = [near.sample[_ranges(near.starts[hit_group], lengths)]]
    triangles = [np.repeat(near.other[hit_group], lengths)]
    # Outside the image: only views the hull's corners do not all project into.
    corners = hull.points[hull.vertices]
    planes = _frustum_planes(poses, intrinsics)
    signed = planes[..., :3].reshape(-1, 3) @ corners.T + planes[..., 3].reshape(-1, 1)
    cut = np.flatnonzero(~_inside(signed.reshape(len(poses), 5, -1)).all(axis=1))
    if cut.size:
        wide = analytic_visibility_faces(
            hull, samples, face_ids, poses[cut], intrinsics, margin=near.eps
        )
        border_view, border_sample = np.nonzero(wide & ~seen[cut])
        border_view = cut[border_view]
        starts, others = _near_by_sample(near, len(samples))
        count = starts[border_sample + 1] - starts[border_sample]
        nearby = others[_ranges(starts[border_sample], count)]
        near_view = np.repeat(border_view, count)
        keep = facing[near_view, nearby]
        views += [border_view, near_view[keep]]
        picks += [border_sample, np.repeat(border_sample, count)[keep]]
        triangles += [face_ids[border_sample], nearby[keep]]
    view_idx, sample_idx = np.concatenate(views), np.concatenate(picks)
    captured = _pixel_capture(
        samples, sample_idx, view_idx, np.concatenate(triangles), hull, poses, intrinsics, near.eps
    )
    seen[view_idx[captured], sample_idx[captured]] = True
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
    dilate: bool | None = None,
) -> np.ndarray:
    """Each view's set of hull samples (the paper's Algorithm 2).

    A view's set is the hull samples within ``eps`` of the points the view would capture.
    ``"raycast"`` renders the hull and takes exactly that; ``"analytic"`` works from the
    geometry:

    * ``dilate=False``: the samples the view sees, facing the camera and inside the image
      (:func:`analytic_visibility`): the exact visible part of the hull.
    * ``dilate=True``: those, plus the samples it does not see that lie within ``eps`` of a
      pixel's point: just behind the silhouette or just outside the image
      (:func:`near_triangles`, :func:`dilate_view_sets`, exact per pixel). The one remaining
      difference from ``"raycast"``: a sample on a face seen so obliquely that its pixels'
      points lie farther apart than ``eps`` is kept, though no point may come that close.
      See the module docstring for the measured agreement.

    Args:
        samples: ``(n, 3)`` points on the hull (:func:`sample_hull`), world units.
        normals: ``(n, 3)`` their outward unit normals.
        poses: ``(V, 4, 4)`` camera-to-world, OpenCV convention.
        intrinsics: the camera.
        method: ``"analytic"`` (fast) or ``"raycast"`` (:func:`raycast_view_sets`, renders the
            hull; needs ``hull``).
        eps: capture distance, world units: the ray-cast coverage distance (``> 0``) and the
            analytic dilation (``>= 0``).
        hull: the hull (``ConvexHull``, or ``(vertices, faces)`` for ``"raycast"``).
        face_ids: ``(n,)`` triangle of each sample (:func:`sample_hull`). With a ``ConvexHull``
            ``hull``, the analytic path decides whole triangles at once
            (:func:`analytic_visibility_faces`); otherwise each sample on its own
            (:func:`analytic_visibility`). Both give the same sets.
        dilate: analytic path only. ``None`` (default): dilate when ``hull`` is a
            ``ConvexHull`` and ``face_ids`` are given (the dilation needs the triangles;
            :func:`plan` gives them), else return the visible sets. ``True`` requires them;
            ``False`` gives the visible sets.

    Returns:
        ``(V, n)`` bool: ``sets[v, i]`` is True when view ``v`` captures sample ``i``.
    """
    if method == "analytic":
        on_triangles = isinstance(hull, ConvexHull) and face_ids is not None
        if dilate is None:
            dilate = on_triangles
        elif dilate and not on_triangles:
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
        eps: capture distance, world units, of both paths (see :func:`view_sets`).
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
