"""Analytic visibility: which points of a convex surface each camera sees, without rendering.

A convex surface cannot occlude itself, so a point ``p`` with outward normal ``n`` is seen from a
camera centred at ``c`` exactly when its face looks at the camera, ``n . (c - p) > 0``, and it
projects inside the image, ``0 <= u <= W - 1`` and ``0 <= v <= H - 1`` (pixel-centre coordinates
of :mod:`nbv.geometry.camera`) in front of the camera. Both are sign tests of dot products: with the
camera centre, and with the five half-spaces of each camera's image (:func:`frustum_planes`,
planes through the camera centre), for all views and points at once
(:func:`analytic_visibility`). On the samples of a convex hull, :func:`analytic_visibility_faces`
gives the same answer with much less work by deciding whole triangles at once, from
:func:`facing_triangles` and :func:`corners_in_image`. A ``margin``
widens the image by a distance: :mod:`nbv.setcover.dilation` uses it to find the samples just
outside the image.

These visible sets are the ``"analytic"`` view simulation of
:func:`nbv.setcover.view_sets.view_sets` without dilation. Measured against its ray-cast sets at 640
x 480, ``eps = 0.00707``, 33 views at distance 1, 4096 samples, on (view, sample) pairs, they agree
on 99.07 % for a sphere and 98.57 % for a box, on 96.9 to 98.9 % for hulls of single full-resolution
views of common test meshes, and on 61 % for a flat one, whose back lies within ``eps`` of its front
(the dilated sets: see :mod:`nbv.setcover.dilation`).

Distances are in world units; poses are camera-to-world, OpenCV convention. The underscored
helpers (argument checks, frustum planes, index ranges) also serve :mod:`nbv.setcover.dilation` and
:mod:`nbv.setcover.oneshot`; they are not a public interface.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from nbv.geometry.camera import Intrinsics
from nbv.geometry.clouds import as_cloud

#: A face counts as turned towards the camera when ``n . (c - p)`` exceeds this (cloud units):
#: faces whose plane passes through the camera centre are seen edge-on and capture nothing.
_FACING_TOL = 1e-9


def as_poses(poses: np.ndarray) -> np.ndarray:
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ValueError(f"poses must have shape (V, 4, 4), got {arr.shape}")
    return arr


def frustum_planes(poses: np.ndarray, intrinsics: Intrinsics, margin: float = 0.0) -> np.ndarray:
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


def as_margin(margin: float, name: str = "margin") -> float:
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
            planes through the camera centre and the image borders
            (:func:`nbv.setcover.dilation.dilate_view_sets` finds the samples just outside the image
            with ``margin = eps``). ``0`` is the exact test above.

    Returns:
        ``(V, n)`` bool.
    """
    samples = as_cloud(samples, "samples")
    normals = as_cloud(normals, "normals")
    if normals.shape != samples.shape:
        raise ValueError(f"normals {normals.shape} must match samples {samples.shape}")
    poses = as_poses(poses)
    planes = frustum_planes(poses, intrinsics, as_margin(margin))
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
    """Inside all five half-spaces of :func:`frustum_planes`: ``(..., 5, m)`` -> ``(..., m)``."""
    inside = signed[..., 0, :] > 0.0
    for k in range(1, 5):
        inside &= signed[..., k, :] >= 0.0
    return inside


def affine_at(function: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``function[:3] . point + function[3]`` elementwise: ``(4, ...)`` and ``(3, ...)``.

    Coefficients and coordinates in rows, because numpy is slow at reducing axes of length 3.
    """
    out = function[0] * points[0]
    out += function[1] * points[1]
    out += function[2] * points[2]
    out += function[3]
    return out


def _inside_pairs(
    planes: np.ndarray, view_idx: np.ndarray, samples: np.ndarray, sample_idx: np.ndarray
) -> np.ndarray:
    """:func:`_inside` for (view, sample) pairs: ``(m,)`` bool.

    Args:
        planes: ``(V, 5, 4)`` :func:`frustum_planes`.
        view_idx: ``(m,)`` view of each pair.
        samples: ``(n, 3)`` points, world units.
        sample_idx: ``(m,)`` sample of each pair.
    """
    # Coordinates in rows and one gathered row per coefficient: faster than a (m, 5, 4) gather.
    xyz = np.take(samples.T, sample_idx, axis=1)
    columns = np.ascontiguousarray(planes.transpose(1, 2, 0))  # (5, 4, V)
    inside = affine_at(np.take(columns[0], view_idx, axis=1), xyz) > 0.0
    for k in range(1, 5):
        inside &= affine_at(np.take(columns[k], view_idx, axis=1), xyz) >= 0.0
    return inside


def as_face_ids(face_ids: np.ndarray, hull: ConvexHull, n: int) -> np.ndarray:
    face_ids = np.asarray(face_ids)
    n_faces = len(hull.simplices)
    if face_ids.shape != (n,) or not np.issubdtype(face_ids.dtype, np.integer):
        raise ValueError(
            f"face_ids must be ({n},) integers like samples, got {face_ids.dtype} {face_ids.shape}"
        )
    if face_ids.size and (face_ids.min() < 0 or face_ids.max() >= n_faces):
        raise ValueError(f"face_ids must lie in [0, {n_faces}), the hull's triangles")
    return face_ids


def index_ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """``concatenate([arange(a, a + k) for a, k in zip(starts, lengths)])``, vectorised."""
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, dtype=np.intp)
    shift = np.repeat(starts - np.cumsum(lengths) + lengths, lengths)
    return shift + np.arange(total)


def facing_triangles(hull: ConvexHull, poses: np.ndarray) -> np.ndarray:
    """Which hull triangles each camera faces: ``(V, F)`` bool, ``n . (c - p) > 1e-9``."""
    normal, offset = hull.equations[:, :3], hull.equations[:, 3]
    return poses[:, :3, 3] @ normal.T + offset > _FACING_TOL  # n . c + d = n . (c - p)


def corners_in_image(hull: ConvexHull, planes: np.ndarray) -> np.ndarray:
    """Which of the hull's corners (``hull.vertices``, in that order) each camera's image holds:
    ``(V, corners)`` bool, for the ``(V, 5, 4)`` half-spaces of :func:`frustum_planes`."""
    signed = planes[..., :3].reshape(-1, 3) @ hull.points[hull.vertices].T
    signed += planes[..., 3].reshape(-1, 1)
    return _inside(signed.reshape(len(planes), 5, -1))


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
    face_ids = as_face_ids(face_ids, hull, len(samples))
    poses = as_poses(poses)
    n_faces = len(hull.simplices)
    planes = frustum_planes(poses, intrinsics, as_margin(margin))  # (V, 5, 4)
    # Corners are tested once each: Qhull's vertex list, renumbered.
    renumber = np.empty(len(hull.points), dtype=np.intp)
    renumber[hull.vertices] = np.arange(len(hull.vertices))
    tri = renumber[hull.simplices]
    corner_in = corners_in_image(hull, planes)  # (V, corners)
    all_in = corner_in[:, tri[:, 0]] & corner_in[:, tri[:, 1]] & corner_in[:, tri[:, 2]]
    facing = facing_triangles(hull, poses)
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
        sample_idx = index_ranges(starts[cut_face], lengths)
        if not grouped:
            sample_idx = np.argsort(face_ids, kind="stable")[sample_idx]
        view_idx = np.repeat(cut_view, lengths)
        seen[view_idx, sample_idx] = _inside_pairs(planes, view_idx, samples, sample_idx)
    return seen
