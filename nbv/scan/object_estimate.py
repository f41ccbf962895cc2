"""The object found among its surroundings, when nobody measured it: one object on a support.

A depth camera sees the table the object stands on, the walls behind it and stray points. The
estimate (:func:`estimate_object`), all in world units:

1. **Aim**: where the cameras' optical axes meet (least squares); with one view, or axes too
   nearly parallel to meet, the points nearest the first camera's axis (their median along it).
2. **Planes**: Open3D's RANSAC (:meth:`open3d.geometry.PointCloud.segment_plane`, seeded) finds
   the largest planes in turn; a plane holding at least ``min_plane_share`` of all the points,
   with the aim and every camera on one side of it, is a support or a wall: its points and what
   lies behind it (the side away from the aim) go. (A face of the object is seen by some camera
   from outside: that camera and the aim lie on two sides of its plane.) The support is the
   first whose normal is within 45 degrees of the rig's up axis.
3. **Stray points**: Open3D's statistical outlier removal.
4. **The object**: Open3D's DBSCAN clusters; the cluster with the most points within the median
   distance of the points to the aim (stray fragments of a table's edge hold few; a sparse
   object split in parts gives its largest part).
5. **Sphere**: the cluster's bounding box, stretched down to the support when there is one (the
   object stands on it: its bottom rows were taken with the plane), gives the centre; the
   farthest point the radius.

:class:`ObjectEstimate` keeps every step's inputs and counts for ``plan.json``; ``trusted`` is
False, with ``warnings`` naming why and the settings to give, when the estimate looks wrong.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from nbv.utils.fields import at_least, between, check_ranges, positive, setting

log = logging.getLogger(__name__)

#: Axes whose normal matrix has a smallest eigenvalue below this (per view) are too nearly
#: parallel to meet: about 8 degrees of spread.
AXES_SPREAD = 0.02
#: A support's normal is within this many degrees of the rig's up axis.
SUPPORT_DEGREES = 45.0
#: Fewer points than this in the object's cluster is no estimate to trust.
MIN_POINTS = 50
_AUTO = "null (automatic) or a positive distance"


def _auto(v: float | None) -> bool:
    return v is None or v > 0


@dataclass(frozen=True)
class EstimateSettings:
    """``object.estimate:``, how the object is found when ``object.*`` is not given (lengths in
    world units; null ones scale with the median distance from the cameras to the aim, ``D``).

    Attributes:
        voxel: the merged cloud is thinned to one point per voxel of this edge (null: D / 250).
        plane_distance: RANSAC's inlier distance to a plane (null: D / 100).
        max_planes: supports and walls removed at most.
        min_plane_share: a plane is a support or a wall when it holds at least this share of
            all the (thinned) points (a face of the object holds less).
        outlier_neighbours: neighbours of the statistical outlier removal.
        outlier_std: a point farther than this many standard deviations above the mean
            neighbour distance is a stray one.
        cluster_distance: DBSCAN's neighbourhood (null: 3 voxels, or 4 times the median
            distance between neighbouring points when the cloud is sparser).
        cluster_points: DBSCAN's minimum points of a core point.
    """

    voxel: float | None = setting(None, check=_auto, allowed=_AUTO)
    plane_distance: float | None = setting(None, check=_auto, allowed=_AUTO)
    max_planes: int = setting(3, allows=at_least(0))
    min_plane_share: float = setting(0.05, allows=between(0, 1, "(]"))
    outlier_neighbours: int = setting(20, allows=at_least(2))
    outlier_std: float = setting(2.0, allows=positive())
    cluster_distance: float | None = setting(None, check=_auto, allowed=_AUTO)
    cluster_points: int = setting(10, allows=at_least(1))

    def __post_init__(self) -> None:
        check_ranges(self)


@dataclass(frozen=True)
class Plane:
    """A plane ``normal . x + offset = 0`` (world units), ``normal`` a unit vector toward the
    object's side; ``points`` the RANSAC inliers it held."""

    normal: np.ndarray
    offset: float
    points: int

    def distance(self, x: np.ndarray) -> np.ndarray:
        """(N,) signed distances of (N, 3) points: positive on the object's side."""
        return np.asarray(x, dtype=np.float64) @ self.normal + self.offset

    def record(self) -> dict:
        """As ``plan.json`` holds it."""
        return {"normal": self.normal.tolist(), "offset": self.offset, "points": self.points}


@dataclass
class ObjectEstimate:
    """The estimate and what it was made from (world units).

    Attributes:
        center: (3,) the object's centre; radius: its sphere's radius.
        aim: (3,) where the cameras look (step 1); ``aim_from`` says how it was found and
            ``aim_rms`` is the axes' RMS distance to it.
        planes: the supports and walls removed (step 2); ``support`` the index of the support
            among them, or None.
        counts: points at each step (``captured``, ``thinned``, ``off_planes``, ``inliers``,
            ``object``) and ``clusters`` found.
        settings: the settings the estimate ran with, the automatic lengths filled in.
        points: (K, 3) the object's cluster (not in the record).
        trusted: False when a check failed; ``warnings`` says which, naming what to give.
    """

    center: np.ndarray
    radius: float
    aim: np.ndarray
    aim_from: str
    aim_rms: float
    planes: list[Plane] = field(default_factory=list)
    support: int | None = None
    counts: dict[str, int] = field(default_factory=dict)
    settings: dict[str, float] = field(default_factory=dict)
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    trusted: bool = True
    warnings: list[str] = field(default_factory=list)

    @property
    def support_plane(self) -> Plane | None:
        """The support the object stands on, when one was found."""
        return None if self.support is None else self.planes[self.support]

    def record(self) -> dict:
        """As ``plan.json``'s ``object.estimate`` holds it."""
        return {
            "center": self.center.tolist(),
            "radius": self.radius,
            "aim": self.aim.tolist(),
            "aim_from": self.aim_from,
            "aim_rms": self.aim_rms,
            "planes": [p.record() for p in self.planes],
            "support": self.support,
            "counts": self.counts,
            "settings": self.settings,
            "trusted": self.trusted,
            "warnings": self.warnings,
        }


def axes_meeting(poses: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The point nearest every camera's optical axis (least squares), and the axes' RMS distance
    to it; None when the axes are too nearly parallel to meet (or there is one).

    Args:
        poses: (V, 4, 4) camera-to-world, OpenCV axes (+z forward).
    """
    poses = np.asarray(poses, dtype=np.float64)
    d = poses[:, :3, 2] / np.linalg.norm(poses[:, :3, 2], axis=1, keepdims=True)
    c = poses[:, :3, 3]
    # Sum of the projections onto each axis's normal plane: (sum P_i) p = sum P_i c_i.
    proj = np.eye(3) - d[:, :, None] * d[:, None, :]
    a, b = proj.sum(axis=0), np.einsum("vij,vj->i", proj, c)
    if len(poses) < 2 or np.linalg.eigvalsh(a)[0] < AXES_SPREAD * len(poses):
        return None
    p = np.linalg.solve(a, b)
    r = np.einsum("vij,vj->vi", proj, p - c)
    return p, float(np.sqrt(np.mean(np.sum(r**2, axis=1))))


def aim_point(poses: np.ndarray, clouds: list[np.ndarray]) -> tuple[np.ndarray, str, float]:
    """Where the cameras look: ``(point, how, rms)`` (see the module docstring, step 1).

    Args:
        poses: (V, 4, 4) camera-to-world, OpenCV axes.
        clouds: each view's (N_v, 3) world points.
    """
    met = axes_meeting(poses)
    if met is not None:
        return met[0], "axes", met[1]
    pose, points = np.asarray(poses[0], dtype=np.float64), np.asarray(clouds[0], np.float64)
    rel = points - pose[:3, 3]
    along = rel @ pose[:3, 2]
    off = np.linalg.norm(rel - along[:, None] * pose[:3, 2], axis=1)
    ahead = along > 0
    # The points within 5 degrees of the axis, else the nearest tenth of them.
    near = ahead & (off <= np.tan(np.radians(5.0)) * along)
    if near.sum() < 10:
        near = ahead & (off <= np.quantile(off[ahead], 0.1))
    depth = float(np.median(along[near]))
    return pose[:3, 3] + depth * pose[:3, 2], "points near the first camera's axis", 0.0


def _cloud(points: np.ndarray):
    import open3d as o3d

    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, np.float64)))


def thinned(points: np.ndarray, voxel: float) -> np.ndarray:
    """(M, 3) the points thinned to one a voxel of edge ``voxel`` (Open3D's voxel down-sampling:
    the mean of each voxel's points)."""
    return np.asarray(_cloud(points).voxel_down_sample(voxel).points)


def find_planes(
    points: np.ndarray,
    aim: np.ndarray,
    cameras: np.ndarray,
    up: np.ndarray,
    distance: float,
    settings: EstimateSettings,
    seed: int,
) -> tuple[np.ndarray, list[Plane], int | None]:
    """Remove supports and walls (module docstring, step 2).

    Args:
        points: (N, 3) world points.
        aim: (3,) where the cameras look (on the object's side of every plane).
        cameras: (V, 3) the camera centres (on that side too).
        up: (3,) the rig's up axis, world frame.
        distance: RANSAC's inlier distance.
        settings: ``max_planes`` and ``min_plane_share``.
        seed: RANSAC's seed (Open3D's global generator, set here).

    Returns:
        ``(kept, planes, support)``: the (M, 3) points in front of every plane, the planes in the
        order found, the index of the support among them (None without one).
    """
    import open3d as o3d

    o3d.utility.random.seed(int(seed))
    kept = np.asarray(points, dtype=np.float64)
    total = len(kept)
    planes: list[Plane] = []
    support = None
    for _ in range(settings.max_planes):
        if len(kept) < 3 * max(settings.outlier_neighbours, 10):
            break
        model, inliers = _cloud(kept).segment_plane(distance, 3, 1000)
        if len(inliers) < settings.min_plane_share * total:
            break
        normal, offset = np.asarray(model[:3], dtype=np.float64), float(model[3])
        scale = float(np.linalg.norm(normal))
        normal, offset = normal / scale, offset / scale
        side = float(aim @ normal + offset)
        if side < 0:
            normal, offset = -normal, -offset
        seen = np.asarray(cameras, dtype=np.float64) @ normal + offset
        if abs(side) <= 2 * distance or seen.min() <= distance:
            break  # a face of the object (a camera sees it from outside), not its surroundings
        plane = Plane(normal, offset, len(inliers))
        planes.append(plane)
        if support is None and normal @ up >= np.cos(np.radians(SUPPORT_DEGREES)):
            support = len(planes) - 1
        kept = kept[plane.distance(kept) > distance]
    return kept, planes, support


def estimate_object(
    poses: np.ndarray,
    clouds: list[np.ndarray],
    up: np.ndarray,
    settings: EstimateSettings,
    seed: int,
) -> ObjectEstimate:
    """The object's sphere from captures of it on a support (the module docstring's steps).

    Args:
        poses: (V, 4, 4) camera-to-world of the views, OpenCV axes, world units.
        clouds: each view's (N_v, 3) world points.
        up: (3,) the rig's up axis in the world frame.
        settings: the estimate's settings.
        seed: RANSAC's and the thinning's seed.

    Returns:
        The estimate; its ``trusted`` and ``warnings`` say whether to believe it.

    Raises:
        ValueError: nothing is left of the points to be the object (the message names the
            settings to give).
    """
    poses = np.asarray(poses, dtype=np.float64)
    points = np.concatenate([np.asarray(c, np.float64) for c in clouds])
    aim, aim_from, aim_rms = aim_point(poses, clouds)
    reach = float(np.median(np.linalg.norm(poses[:, :3, 3] - aim, axis=1)))
    voxel = settings.voxel or reach / 250
    plane_distance = settings.plane_distance or reach / 100
    counts = {"captured": len(points)}
    thin = thinned(points, voxel)
    counts["thinned"] = len(thin)
    kept, planes, support = find_planes(
        thin, aim, poses[:, :3, 3], up, plane_distance, settings, seed
    )
    counts["off_planes"] = len(kept)
    advice = "give object.center and object.radius, or a region object.box_min / object.box_max"
    if len(kept) < settings.outlier_neighbours + 1:
        raise ValueError(
            f"object estimate: {len(kept)} points are left off the supports and walls; {advice}"
        )
    cloud, _ = _cloud(kept).remove_statistical_outlier(
        settings.outlier_neighbours, settings.outlier_std
    )
    inliers = np.asarray(cloud.points)
    counts["inliers"] = len(inliers)
    spacing = float(np.median(np.asarray(cloud.compute_nearest_neighbor_distance())))
    cluster_distance = settings.cluster_distance or max(3 * voxel, 4 * spacing)
    labels = np.asarray(cloud.cluster_dbscan(cluster_distance, settings.cluster_points))
    counts["clusters"] = int(labels.max() + 1) if len(labels) else 0
    if len(labels) == 0 or labels.max() < 0:
        raise ValueError(f"object estimate: no cluster among {len(inliers)} points; {advice}")
    near = np.linalg.norm(inliers - aim, axis=1)
    near = (near <= np.median(near)) & (labels >= 0)
    if not near.any():
        near = labels >= 0
    obj = inliers[labels == np.bincount(labels[near]).argmax()]
    counts["object"] = len(obj)
    lo, hi = obj.min(axis=0), obj.max(axis=0)
    plane = None if support is None else planes[support]
    if plane is not None:
        # The object stands on the support: its bottom was taken with the plane's points.
        # Move the box's lower face along the support's normal, down to the plane.
        drop = float(plane.distance(obj).min())
        lo, hi = _stretch_down(lo, hi, plane.normal, drop)
    center = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(obj - center, axis=1).max())
    if plane is not None:
        radius = max(radius, float(plane.distance(center[None])[0]))
    estimate = ObjectEstimate(
        center=center, radius=radius, aim=aim, aim_from=aim_from, aim_rms=aim_rms, planes=planes,
        support=support, counts=counts,
        settings={"voxel": voxel, "plane_distance": plane_distance,
                  "cluster_distance": cluster_distance}, points=obj,
    )  # fmt: skip
    _check(estimate, poses, advice)
    return estimate


def _stretch_down(
    lo: np.ndarray, hi: np.ndarray, normal: np.ndarray, drop: float
) -> tuple[np.ndarray, np.ndarray]:
    """The box [lo, hi] grown along -normal by ``drop`` (its extent along each world axis grows
    by |normal_i| drop on the side the normal points away from)."""
    grow = drop * np.abs(normal)
    lo = np.where(normal > 0, lo - grow, lo)
    hi = np.where(normal < 0, hi + grow, hi)
    return lo, hi


def _check(estimate: ObjectEstimate, poses: np.ndarray, advice: str) -> None:
    """Mark an estimate that looks wrong, one warning a reason."""
    nearest = float(np.linalg.norm(poses[:, :3, 3] - estimate.center, axis=1).min())
    if estimate.counts["object"] < MIN_POINTS:
        estimate.warnings.append(f"the object's cluster holds {estimate.counts['object']} points")
    if estimate.radius >= 0.7 * nearest:
        estimate.warnings.append(
            f"the radius {estimate.radius:.4g} nearly reaches the nearest camera ({nearest:.4g} "
            "away): the cluster holds more than the object"
        )
    if estimate.aim_from == "axes" and estimate.aim_rms > 2 * estimate.radius:
        estimate.warnings.append(
            f"the cameras' axes pass {estimate.aim_rms:.3g} from their meeting point: they do not "
            "look at one object"
        )
    if np.linalg.norm(estimate.aim - estimate.center) > 2 * estimate.radius:
        estimate.warnings.append("the cameras look beside the object found")
    estimate.trusted = not estimate.warnings
    if estimate.warnings:
        estimate.warnings = [f"object estimate not to be trusted: {w}; {advice}"
                             for w in estimate.warnings]  # fmt: skip
