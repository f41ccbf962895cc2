"""Depth images of a triangle mesh by ray casting: Open3D's Embree scene, one ray per pixel centre.

The pure ray casting, with no render job or renderer process around it: the dataset's ``raycast``
backend (:mod:`nbv.render.raycast`) and the planner's ray-cast view simulation
(:func:`nbv.setcover.view_sets.raycast_view_sets`) both call :func:`raycast_depth`, so that they
see the same pixels. Open3D is imported on the first call only (it is heavy).
"""

from __future__ import annotations

import numpy as np

from nbv.geometry.camera import Intrinsics, pixel_rays

__all__ = ["check_mesh", "raycast_depth", "reachable_pixels"]


def check_mesh(vertices: np.ndarray, faces: np.ndarray, poses: np.ndarray) -> None:
    """Refuse arrays that are not a triangle mesh and camera poses.

    Raises:
        ValueError: ``vertices`` not (N, 3), ``faces`` not integer (F, 3) indices into them, or
            ``poses`` not (V, 4, 4); the message gives the shape found.
    """
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"vertices must be (N, 3), got shape {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise ValueError(f"faces must be integer (F, 3), got {faces.dtype} {faces.shape}")
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise ValueError(
            f"face indices must lie in [0, {len(vertices)}), got [{faces.min()}, {faces.max()}]"
        )
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise ValueError(f"poses must be (V, 4, 4), got shape {poses.shape}")


def raycast_depth(
    vertices: np.ndarray,
    faces: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    *,
    threads: int = 0,
) -> np.ndarray:
    """Planar depth images of a triangle mesh by ray casting (Open3D / Embree).

    Rays go through the pixel centres of :func:`nbv.geometry.camera.pixel_rays` with unit camera-z,
    so the hit distance along the unnormalised ray is the planar depth.

    Args:
        vertices: (N, 3) vertex positions, world units.
        faces: (F, 3) integer triangle indices.
        poses: (V, 4, 4) camera-to-world, OpenCV convention.
        intrinsics: the camera.
        threads: threads for Embree; 0 = all cores.

    Returns:
        (V, H, W) float32 planar depth, world units; ``inf`` where no triangle is hit.
    """
    import open3d as o3d  # imported here: heavy, and only this backend needs it

    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    poses = np.asarray(poses, dtype=np.float64)
    check_mesh(vertices, faces, poses)
    depth = np.full((len(poses), intrinsics.height, intrinsics.width), np.inf, dtype=np.float32)
    if faces.size == 0:
        return depth
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.ascontiguousarray(vertices, dtype=np.float32)),
        o3d.core.Tensor(np.ascontiguousarray(faces, dtype=np.uint32)),
    )
    # One float32 product per view gives every ray: [x, y, 1, 1] @ [[0, R^T], [c, 0]] puts the
    # camera centre c in the first three columns and R @ [x, y, 1] in the last three.
    pixels = np.ones((intrinsics.height * intrinsics.width, 4), dtype=np.float32)
    pixels[:, :2] = pixel_rays(intrinsics).reshape(-1, 3)[:, :2]
    transform = np.zeros((4, 6), dtype=np.float32)
    for i, pose in enumerate(poses):
        transform[:3, 3:] = pose[:3, :3].T
        transform[3, :3] = pose[:3, 3]
        reach = np.flatnonzero(reachable_pixels(vertices, faces, pose, intrinsics).ravel())
        rays = o3d.core.Tensor.from_numpy(pixels[reach] @ transform)
        depth[i].ravel()[reach] = scene.cast_rays(rays, nthreads=threads)["t_hit"].numpy()
    return depth


def reachable_pixels(
    vertices: np.ndarray, faces: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, tile: int = 8
) -> np.ndarray:
    """A conservative mask of the pixels whose rays can hit the mesh: (H, W) bool.

    A triangle in front of the camera projects inside the pixel bounding box of its projected
    corners, so the union of those boxes (rounded out to ``tile`` x ``tile`` blocks, which keeps
    the count cheap) holds every pixel that can see it. Ray casting only those pixels gives the
    same depth image for a fraction of the rays. A mesh reaching behind the camera plane, or one
    with more than a triangle per 16 pixels, gets every pixel.
    """
    rotation, centre = pose[:3, :3], pose[:3, 3]
    cam = (np.asarray(vertices, dtype=np.float64) - centre) @ rotation
    full = np.ones((intrinsics.height, intrinsics.width), dtype=bool)
    # The mask costs O(F): past about one triangle per 16 pixels it costs more than it saves.
    if not np.all(cam[:, 2] > 1e-9) or 16 * len(faces) > full.size:
        return full
    u = intrinsics.fx * cam[:, 0] / cam[:, 2] + intrinsics.cx
    v = intrinsics.fy * cam[:, 1] / cam[:, 2] + intrinsics.cy
    tu, tv = -(-intrinsics.width // tile), -(-intrinsics.height // tile)
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    # Pixel centres are integers: a box [lo, hi] holds the pixels ceil(lo)..floor(hi). (Column
    # minima by np.minimum are several times faster than .min(axis=1) on (F, 3) arrays.)
    u0 = np.clip(np.ceil(np.minimum(np.minimum(u[a], u[b]), u[c])) // tile, 0, tu).astype(np.int64)
    u1 = np.clip(np.floor(np.maximum(np.maximum(u[a], u[b]), u[c])) // tile + 1, 0, tu)
    v0 = np.clip(np.ceil(np.minimum(np.minimum(v[a], v[b]), v[c])) // tile, 0, tv).astype(np.int64)
    v1 = np.clip(np.floor(np.maximum(np.maximum(v[a], v[b]), v[c])) // tile + 1, 0, tv)
    u1, v1 = u1.astype(np.int64), v1.astype(np.int64)
    keep = (u1 > u0) & (v1 > v0)
    u0, u1, v0, v1 = u0[keep], u1[keep], v0[keep], v1[keep]
    # Two-dimensional difference array of the boxes, summed up: tiles covered by some box.
    stride = tu + 1
    corners = np.concatenate(
        [v0 * stride + u0, v0 * stride + u1, v1 * stride + u0, v1 * stride + u1]
    )
    weights = np.concatenate(
        [np.ones_like(u0), -np.ones_like(u0), -np.ones_like(u0), np.ones_like(u0)]
    )
    counts = np.bincount(corners, weights, minlength=(tv + 1) * stride).reshape(tv + 1, stride)
    tiles = counts.cumsum(axis=0).cumsum(axis=1)[:tv, :tu] > 0.5
    mask = np.repeat(np.repeat(tiles, tile, axis=0), tile, axis=1)
    return mask[: intrinsics.height, : intrinsics.width]
