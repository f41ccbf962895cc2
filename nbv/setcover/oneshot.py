from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from nbv.geometry.camera import Intrinsics, viewspace_poses
from nbv.geometry.clouds import as_cloud
from nbv.geometry.scores import DEFAULT_EPS
from nbv.geometry.sph import equiangular_directions, signature_with_centroid, unit_vectors
from nbv.setcover.greedy import DEFAULT_N_ITER, as_exclude, greedy_packed, pack_sets
from nbv.setcover.hull_sampling import convex_hull, sample_on_hull
from nbv.setcover.settings import SetCoverSettings
from nbv.setcover.view_sets import view_sets
from nbv.setcover.visibility import as_poses


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


def _as_viewspace(viewspace: np.ndarray) -> np.ndarray:
    arr = np.asarray(viewspace, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
        raise ValueError(f"viewspace must have shape (V, 3) with V >= 1, got {arr.shape}")
    return arr


def plan(
    points: np.ndarray,
    viewspace: np.ndarray,
    n_iter: int = DEFAULT_N_ITER,
    exclude: Iterable[int] = (),
    rng: np.random.Generator | int = 0,
    settings: SetCoverSettings = SetCoverSettings(),  # noqa: B008 - frozen dataclass
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
            :func:`greedy_max_coverage` with ``positions=viewspace``), views tied for a pick
            chosen among at random by a child of ``rng`` (``Generator.spawn``).
        exclude: indices of the views already visited (the start view): never chosen, and the
            hull samples they capture count as covered before the first pick.
        rng: numpy Generator or integer seed: of the hull sampling, and of the fill's
            tie-break through a spawned child generator (which draws nothing from ``rng``: the
            samples and the covering picks are those of the same seed before the fill's
            tie-break was random; only the fill's picks among tied views changed).
        settings: the planner's settings: ``n_samp`` hull samples, the view ``simulation``
            (``"analytic"`` or ``"raycast"``, see :func:`nbv.setcover.view_sets.view_sets`) and
            ``dilate``: with ``"analytic"``, dilate the visible sets by ``eps``
            (:mod:`nbv.setcover.dilation`), so that the samples within ``eps`` of a pixel's point
            just behind the silhouette or just outside the image count too, as they do for
            ``"raycast"``. Closer to ``"raycast"`` but about 4x slower, far more on hulls of
            many small triangles (measured in the module docstring). Off by default.
        intrinsics: the camera.
        eps: capture distance, world units: of ``"raycast"``, and of ``"analytic"`` with
            ``dilate`` (see :func:`view_sets`).
        poses: ``(V, 4, 4)`` :func:`nbv.geometry.camera.viewspace_poses` of ``viewspace``, when the
            caller has them already (they are the same for every plan on one viewspace).

    Returns:
        :class:`Plan`.

    Raises:
        ValueError: for a cloud whose hull has no volume (flat, colinear, fewer than 4 points)
            and for bad arguments.
    """
    viewspace = _as_viewspace(viewspace)
    excluded = as_exclude(exclude, len(viewspace))
    clock = time.perf_counter
    t0 = clock()
    hull = convex_hull(points)
    t1 = clock()
    if isinstance(rng, int | np.integer) and not isinstance(rng, bool):
        rng = np.random.default_rng(int(rng))  # as sample_on_hull makes it: the same draws
    samples, normals, face_ids = sample_on_hull(hull, settings.n_samp, rng)
    # The fill's tie-break gets a child generator: spawning draws nothing from ``rng`` (it
    # advances the spawn counter of its seed sequence only), so the hull samples, and with them
    # the covering picks, are what they were before the fill was randomised; each plan from
    # one generator gets a fresh child.
    fill_rng = rng.spawn(1)[0]
    t2 = clock()
    poses = viewspace_poses(viewspace) if poses is None else as_poses(poses)
    if len(poses) != len(viewspace):
        raise ValueError(f"poses has {len(poses)} cameras, the viewspace {len(viewspace)}")
    sets = view_sets(samples, normals, poses, intrinsics, settings.simulation, eps, hull,
                     face_ids, settings.dilate)  # fmt: skip
    t3 = clock()
    rows = pack_sets(sets)
    t4 = clock()
    views, gains, n_covered = greedy_packed(rows, n_iter, excluded, viewspace, fill_rng)
    t5 = clock()
    timings = {"hull": t1 - t0, "sampling": t2 - t1, "simulation": t3 - t2, "sets": t4 - t3,
               "greedy": t5 - t4}  # fmt: skip
    timings["total"] = sum(timings.values())
    return Plan(views, gains, n_covered / len(samples), timings)


def sph_hull_points(points: np.ndarray, lmax: int = 3) -> np.ndarray:
    """The spherical signature of a cloud in world coordinates (at the cloud's centroid), its
    radii bounded by the cloud.

    A signature fitted to one view extrapolates far past what the view saw: radii up to 7 for
    an object of radius 0.5, and many negative (a point on the far side of the centroid). Most
    cameras would then sit inside its hull. Each radius is therefore clamped to ``[0, R]``, ``R``
    the largest distance of a cloud point from the centroid: the hull stays within the sphere
    about the centroid that holds the cloud.

    Args:
        points: ``(N, 3)`` cloud, world units.
        lmax: maximum harmonic degree (the paper's 3).

    Returns:
        ``(4 (lmax + 1)^2, 3)`` float64 points, in the order of
        :func:`nbv.geometry.sph.equiangular_directions`.
    """
    cloud = as_cloud(points, "points")
    signature, centroid = signature_with_centroid(cloud, lmax)
    directions = unit_vectors(*equiangular_directions(lmax))
    radius = np.einsum("ij,ij->i", signature.astype(np.float64), directions)  # signed
    extent = float(np.linalg.norm(cloud - centroid, axis=1).max())
    return np.clip(radius, 0.0, extent)[:, None] * directions + centroid
