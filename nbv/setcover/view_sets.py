"""View simulation on a hull: which hull samples each view of the viewspace captures."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from nbv.geometry.camera import Intrinsics, backproject
from nbv.geometry.clouds import as_cloud
from nbv.geometry.raycast import raycast_depth
from nbv.geometry.scores import DEFAULT_EPS, covered_mask
from nbv.setcover.dilation import dilate_view_sets, near_triangles
from nbv.setcover.settings import SIMULATIONS
from nbv.setcover.visibility import analytic_visibility, analytic_visibility_faces, as_poses


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

    Each view's depth (:func:`nbv.geometry.raycast.raycast_depth`, one ray a pixel centre) is
    back-projected to a cloud; a sample is captured when a point of that cloud lies closer than
    ``eps`` (:func:`nbv.geometry.scores.covered_mask`). ``eps`` must exceed about half the distance
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
    samples = as_cloud(samples, "samples")
    poses = as_poses(poses)
    vertices, faces = _hull_mesh(hull)
    depth = raycast_depth(vertices, faces, poses, intrinsics)
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
      (:func:`nbv.setcover.visibility.analytic_visibility`): the exact visible part of the hull.
    * ``dilate=True``: those, plus the samples it does not see that lie within ``eps`` of a
      pixel's point: just behind the silhouette or just outside the image
      (:func:`nbv.setcover.dilation.near_triangles`, :func:`nbv.setcover.dilation.dilate_view_sets`,
      exact per pixel). The one remaining difference from ``"raycast"``: a sample on a face seen so
      obliquely that its pixels' points lie farther apart than ``eps`` is kept, though no point may
      come that close. See :mod:`nbv.setcover.dilation` for the measured agreement.

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
            (:func:`nbv.setcover.visibility.analytic_visibility_faces`); otherwise each sample on
            its own (:func:`nbv.setcover.visibility.analytic_visibility`). Both give the same sets.
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
    raise ValueError(f"method must be one of {SIMULATIONS}, got {method!r}")
