"""A table-top scene as a depth camera on a robot sees it, rendered with the project's ray caster.

One object stands on a table with a wall behind it (world units are metres, +z up; the table's
top is the plane z = 0, the wall the plane y = ``wall_distance`` behind the object). Cameras sit
on a circle about the object at ``distance`` from its centre and ``elevation`` degrees up, in front
of the wall, looking at the centre. Every view is ray cast
(:func:`nbv.geometry.raycast.raycast_depth`) and made into a sensor's image:

* the depth-noise model (:func:`nbv.render.noise.noisy_depth`): axial noise rising with depth
  and incidence angle, dropout at grazing angles and on the silhouette;
* ``missing`` of the remaining pixels lost at random;
* nothing beyond ``max_range``;
* a pixel without a measurement is 0, as a sensor writes it.

The object is passed in (a project mesh: the synthetic shapes of :mod:`nbv.assets.synthetic`,
a test's shape), so this module needs only the renderer. Everything random comes from ``seed``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv.geometry.camera import Intrinsics, look_at
from nbv.geometry.raycast import raycast_depth
from nbv.render.noise import DepthNoise, noisy_depth
from nbv.utils.seeding import named_rng


@dataclass(frozen=True)
class SceneSettings:
    """A table-top scene (lengths in metres, angles in degrees).

    Attributes:
        radius: the object's bounding sphere (about its bounding-box centre).
        views: cameras, on a circle of ``spread`` degrees of azimuth in front of the wall.
        spread: azimuth span of the cameras (0 for one view); the middle one faces the wall.
        distance: the cameras' distance from the object's centre.
        elevation: the cameras' elevation above the horizontal, seen from the object's centre.
        table: half the table's edge; its top is z = 0 and it is ``table_thickness`` thick.
        table_thickness: the table's thickness.
        wall_distance: the wall's plane y = this, behind the object's centre.
        wall_height: the wall's height above the table.
        noise: the depth-noise model; None renders clean depth.
        missing: share of the pixels lost at random (after the noise model's dropout).
        max_range: the sensor's range (planar depth); None: unlimited.
    """

    radius: float = 0.10
    views: int = 3
    spread: float = 100.0
    distance: float = 0.45
    elevation: float = 35.0
    table: float = 0.6
    table_thickness: float = 0.04
    wall_distance: float = 0.3
    wall_height: float = 0.6
    noise: DepthNoise | None = DepthNoise(a=0.001, b=0.0, c=0.0001)
    missing: float = 0.15
    max_range: float | None = 1.2

    def __post_init__(self) -> None:
        if not (self.radius > 0 and self.distance > self.radius and self.views >= 1):
            raise ValueError(
                f"scene: radius={self.radius}, distance={self.distance}, views={self.views}: "
                "need radius > 0, distance > radius and views >= 1"
            )
        if not 0 <= self.missing < 1:
            raise ValueError(f"scene: missing={self.missing}: must be in [0, 1)")


@dataclass(frozen=True)
class Scene:
    """A rendered scene.

    Attributes:
        depth: (V, H, W) float32 planar depth, metres, 0 where nothing was measured.
        clean: (V, H, W) float32 the same views without noise, dropout or range limit (inf for
            nothing hit).
        labels: (V, H, W) int8 what each pixel of ``clean`` shows: :data:`NOTHING`,
            :data:`OBJECT`, :data:`TABLE` or :data:`WALL`.
        poses: (V, 4, 4) camera-to-world, OpenCV axes.
        intrinsics: the camera.
        center: (3,) the object's bounding-box centre; radius: its bounding sphere's radius.
        vertices, faces: the object's mesh as placed.
        settings: what it was built from.
    """

    depth: np.ndarray
    clean: np.ndarray
    labels: np.ndarray
    poses: np.ndarray
    intrinsics: Intrinsics
    center: np.ndarray
    radius: float
    vertices: np.ndarray
    faces: np.ndarray
    settings: SceneSettings


#: Pixel labels of :attr:`Scene.labels`.
NOTHING, OBJECT, TABLE, WALL = 0, 1, 2, 3


def _box(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    box = trimesh.creation.box(bounds=np.stack([lo, hi]))
    return np.asarray(box.vertices, np.float64), np.asarray(box.faces, np.int64)


def place_object(
    vertices: np.ndarray, faces: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """The mesh scaled to a bounding sphere of ``radius`` about its bounding-box centre and set
    on the table: its lowest point at z = 0, its centre above the origin. (N, 3) and (F, 3)."""
    v = np.asarray(vertices, dtype=np.float64)
    center = 0.5 * (v.min(axis=0) + v.max(axis=0))
    v = (v - center) * (radius / np.linalg.norm(v - center, axis=1).max())
    v[:, 2] -= v[:, 2].min()
    return v, np.asarray(faces, dtype=np.int64)


def camera_poses(center: np.ndarray, settings: SceneSettings) -> np.ndarray:
    """(V, 4, 4) poses on the cameras' circle (module docstring), looking at ``center``."""
    s = settings
    azimuths = np.radians(np.linspace(-s.spread / 2, s.spread / 2, s.views) if s.views > 1
                          else np.zeros(1))  # fmt: skip
    el = np.radians(s.elevation)
    # The wall is at +y: the middle camera looks along +y from -y.
    eyes = center + s.distance * np.stack(
        [np.sin(azimuths) * np.cos(el), -np.cos(azimuths) * np.cos(el),
         np.full_like(azimuths, np.sin(el))], axis=1,
    )  # fmt: skip
    return np.stack([look_at(e, center, np.array([0.0, 0.0, 1.0])) for e in eyes])


def table_scene(
    vertices: np.ndarray,
    faces: np.ndarray,
    intrinsics: Intrinsics,
    settings: SceneSettings,
    seed: int,
    poses: np.ndarray | None = None,
) -> Scene:
    """Render an object (any mesh: it is placed by :func:`place_object`) on the table.

    Args:
        vertices, faces: the object's mesh, any units and placement.
        intrinsics: the camera.
        settings: the scene.
        seed: the noise's, the dropout's and the missing pixels' seed.
        poses: (V, 4, 4) camera-to-world to render instead of the settings' circle.

    Returns:
        The :class:`Scene`.
    """
    s = settings
    obj_v, obj_f = place_object(vertices, faces, s.radius)
    center = 0.5 * (obj_v.min(axis=0) + obj_v.max(axis=0))
    table_v, table_f = _box(np.array([-s.table, -s.table, -s.table_thickness]),
                            np.array([s.table, s.table, 0.0]))  # fmt: skip
    wall_v, wall_f = _box(np.array([-s.table, s.wall_distance, 0.0]),
                          np.array([s.table, s.wall_distance + 0.02, s.wall_height]))  # fmt: skip
    poses = camera_poses(center, s) if poses is None else np.asarray(poses, dtype=np.float64)
    parts = [(obj_v, obj_f), (table_v, table_f), (wall_v, wall_f)]
    clean = np.stack([
        raycast_depth(v, f, poses, intrinsics, threads=1) for v, f in parts
    ])  # fmt: skip
    # The nearest surface of each pixel, and whose it is.
    nearest = clean.min(axis=0)
    which = np.argmin(clean, axis=0).astype(np.int8) + 1
    labels = np.where(np.isfinite(nearest), which, NOTHING).astype(np.int8)
    depth = nearest.astype(np.float32)
    if s.noise is not None:
        depth = noisy_depth(depth, intrinsics, s.noise, named_rng(seed, "scene", "noise"))
    rng = named_rng(seed, "scene", "missing")
    depth[rng.random(depth.shape) < s.missing] = np.inf
    if s.max_range is not None:
        depth[depth > s.max_range] = np.inf
    depth[~np.isfinite(depth)] = 0.0
    return Scene(depth, nearest.astype(np.float32), labels, poses, intrinsics, center,
                 float(s.radius), obj_v, obj_f, s)  # fmt: skip
