"""Simple shapes and scenes with known answers: point sets for the hull planner's tests, and a
cup whose pocket only one view sees, for the information-gain planners'."""

import numpy as np
import trimesh

from nbv.geometry.camera import Intrinsics, backproject, viewspace_poses
from nbv.infogain.gain import candidate_voxels
from nbv.infogain.occupancy import OccupancyMap, background_directions
from nbv.infogain.settings import InfoGainSettings
from nbv.render.raycast import render_raycast


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit vectors (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5.0**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def cube_corners(half: float) -> np.ndarray:
    """The 8 corners of the cube ``[-half, half]^3``, (8, 3)."""
    return np.array(
        [[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    )


def cup() -> trimesh.Trimesh:
    """A 0.7 x 0.5 x 0.5 box with a 0.3 x 0.3 pocket 0.6 deep, open towards +x."""
    walls = [
        ((-0.35, -0.25), (-0.25, 0.25), (-0.25, 0.25)),  # the pocket's bottom
        ((-0.25, 0.35), (-0.25, -0.15), (-0.25, 0.25)),
        ((-0.25, 0.35), (0.15, 0.25), (-0.25, 0.25)),
        ((-0.25, 0.35), (-0.15, 0.15), (-0.25, -0.15)),
        ((-0.25, 0.35), (-0.15, 0.15), (0.15, 0.25)),
    ]
    boxes = []
    for bounds in walls:
        lo, hi = np.array(bounds).T
        boxes.append(trimesh.creation.box(bounds=np.stack([lo, hi])))
    return trimesh.util.concatenate(boxes)


#: The view of :func:`pocket_scene` that looks into the pocket.
INTO_POCKET = 9


def pocket_scene():
    """The cup seen from 9 views all around but never into its pocket (view ``INTO_POCKET``
    does): ``(directions (V, 3), poses, camera, captured (V,) bool, candidate voxels, map)``
    at the default ig settings."""
    mesh = cup()
    camera = Intrinsics.centred(96, 72, 72.0)
    oblique = [(np.cos(a), np.sin(a) * np.cos(b), np.sin(a) * np.sin(b))
               for a in [np.radians(40)] for b in np.radians([0, 90, 180, 270])]  # fmt: skip
    diagonal = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    directions = np.array([(-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1), *oblique,
                           (1, 0, 0), *diagonal], dtype=float)  # fmt: skip
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    poses = viewspace_poses(directions)
    depth = render_raycast(mesh.vertices, mesh.faces, poses, camera)
    captured = np.arange(len(directions)) < INTO_POCKET
    occupancy = OccupancyMap(InfoGainSettings().occupancy())
    for v in np.flatnonzero(captured):
        points = backproject(depth[v], camera, poses[v])
        misses = background_directions(points, poses[v], camera, block=4)
        occupancy.insert_view(poses[v][:3, 3], points, misses)
    voxels = candidate_voxels(poses, camera, 16, occupancy.settings)
    return directions, poses, camera, captured, voxels, occupancy
