"""What a plan writes into its run folder: ``plan.json``, ``cloud.ply``, ``plan.png`` and
``plan.html``, each whole or not at all.

``plan.json`` (world frame and units of the input):

* ``chosen``: the planned view indices in order (``next_view`` is the first); ``visited``: the
  captured ones (indices ``>= n_candidates`` are captures off the viewspace);
* ``views``: for every chosen view its index, camera centre, and camera-to-world pose in OpenCV
  axes (x right, y down, z forward) and in Blender / OpenGL axes (x right, y up, -z forward);
  ``candidates``: the same for every candidate;
* ``predicted_gains`` (and ``gain_unit``) of the chosen views, when the planner predicts any;
  ``coverage`` by view against the mesh (mesh input);
* ``object`` (centre, radius, up, whether estimated; captures input: ``source``, and the
  object ``estimate`` with its inputs and counts when one ran), ``candidate_limits`` (captures
  input, when candidates were limited: how many were dropped and why, and the viewspace index of
  each kept candidate), ``camera`` (the planner's), ``timings`` (seconds of each decision and of
  the policy's stages), ``notes`` and ``settings``;
* ``reconstruction``: the depth views fused into ``reconstruction.ply`` (the file, the views,
  the voxel, the vertex and triangle counts; mesh input: ``scores`` against the mesh:
  accuracy, completeness, Chamfer distance, precision, recall and F-score at ``eps`` and 2
  ``eps``, world units), or null when no view is a depth image.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from pathlib import Path

import numpy as np

from nbv.geometry.camera import opencv_to_blender
from nbv.geometry.viewspace_generators import ViewspaceSpec
from nbv.plan.config import PlanSettings
from nbv.policies.episode import auc
from nbv.scan.result import PlanResult
from nbv.utils.atomic import fsync_replace, write_text

log = logging.getLogger(__name__)


def _pose_entry(index: int, pose: np.ndarray) -> dict:
    return {
        "view": int(index),
        "position": pose[:3, 3].tolist(),
        "opencv": pose.tolist(),
        "blender": opencv_to_blender(pose).tolist(),
    }


def _jsonable(value):
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if dataclasses.is_dataclass(value):
        return {f.name: _jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    return value


#: The order of ``plan.json``'s ``settings``, the one it has always had: the settings' keys, but
#: the viewspace without its radius and, after it, the cameras' ``distance`` and the object's
#: ``center`` and ``radius`` as keys of their own. A setting added later follows these.
RECORD_ORDER = (
    "out_dir", "method", "mesh", "captures", "viewspace", "distance", "center", "radius",
    "start_view", "n_views", "camera", "match_degrees", "points_per_view", "eps", "n_gt",
    "save_captures", "captures_out", "setcover", "infogain", "checkpoint", "seed", "picture",
    "page",
)  # fmt: skip


def settings_record(settings: PlanSettings) -> dict:
    """``plan.json``'s ``settings``: every setting as JSON, in :data:`RECORD_ORDER`."""
    flat = {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
    vs, obj = flat.pop("viewspace"), flat.pop("object")
    flat |= {
        "viewspace": {f.name: getattr(vs, f.name) for f in dataclasses.fields(ViewspaceSpec)},
        "distance": vs.radius,
        "center": obj.center,
        "radius": obj.radius,
        "box_min": obj.box_min,
        "box_max": obj.box_max,
        "estimate": obj.estimate,
    }
    order = [*RECORD_ORDER, *(key for key in flat if key not in RECORD_ORDER)]
    return {key: _jsonable(flat[key]) for key in order}


def plan_record(settings: PlanSettings, result: PlanResult) -> dict:
    """The content of ``plan.json`` (see the module docstring)."""
    world = result.frame.poses_to_world(result.views.poses)
    record = {
        "input": {"mesh": str(settings.mesh)} if settings.mesh else {
            "captures": str(settings.captures), "views": result.captured_files},
        "method": settings.method,
        "next_view": result.chosen[0],
        "chosen": result.chosen,
        "visited": result.visited,
        "n_candidates": result.n_candidates,
        "views": [_pose_entry(v, world[v]) for v in result.chosen],
        "predicted_gains": result.gains,
        "gain_unit": result.gain_unit or None,
        "coverage": result.coverage,
        "auc": auc(np.array(result.coverage)) if result.coverage else None,
        "object": {
            "center": result.frame.center.tolist(),
            "radius": result.frame.radius,
            "up": result.frame.up,
            "estimated": result.frame_estimated,
        },
        "candidate_limits": result.candidate_limits,
        "camera_distance": float(np.linalg.norm(world[0, :3, 3] - result.frame.center)),
        "camera": _jsonable(result.camera),
        "timings": {"decisions": result.decisions, "stages": result.stages},
        "notes": result.notes,
        "reconstruction": None if result.reconstruction is None else result.reconstruction.record(),
        "candidates": [_pose_entry(v, world[v]) for v in range(result.n_candidates)],
        "settings": settings_record(settings),
    }  # fmt: skip
    if settings.captures is not None:
        record["object"]["source"] = result.object_source
        record["object"]["estimate"] = result.estimate
    return record


def _write_ply(path: Path, write, what: str) -> None:
    """Write a PLY with Open3D's ``write(file) -> ok``, whole or not at all. Open3D picks the
    format by the suffix, so the temporary file ends in .ply too."""
    tmp = path.with_name(f".{path.stem}.tmp.ply")
    try:
        if not write(str(tmp)):
            raise OSError(f"{path}: Open3D could not write the {what}")
        fsync_replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


#: A valid PLY file of a cloud without points (Open3D refuses to write one).
EMPTY_CLOUD_PLY = (
    b"ply\nformat binary_little_endian 1.0\nelement vertex 0\n"
    b"property double x\nproperty double y\nproperty double z\nend_header\n"
)


def write_cloud(path: Path, points: np.ndarray) -> None:
    """The accumulated cloud as a binary PLY (Open3D), world frame; a cloud without points is
    written as a PLY with 0 vertices."""
    import open3d as o3d

    if not len(points):
        _write_ply(path, lambda file: Path(file).write_bytes(EMPTY_CLOUD_PLY) > 0, "cloud")
        return
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, np.float64)))
    _write_ply(path, lambda file: o3d.io.write_point_cloud(file, cloud), "cloud")


def write_mesh(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> None:
    """A triangle mesh as a binary PLY (Open3D), world frame; whole or not at all. (Open3D
    refuses to write a mesh without vertices: skip an empty reconstruction before calling.)"""
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.asarray(vertices, np.float64)),
        o3d.utility.Vector3iVector(np.asarray(triangles, np.int32)),
    )
    _write_ply(path, lambda file: o3d.io.write_triangle_mesh(file, mesh), "mesh")


def hull_mesh(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) vertices and (F, 3) triangles of the cloud's convex hull (empty for a flat or
    tiny cloud, which has none)."""
    from nbv.setcover.hull_sampling import convex_hull

    try:
        hull = convex_hull(np.asarray(points, dtype=np.float64))
    except ValueError:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    used, faces = np.unique(hull.simplices, return_inverse=True)
    return hull.points[used], faces.reshape(-1, 3).astype(np.int64)


#: A point this much beyond the object's sphere (in its radii) is its surroundings in the
#: pictures: the sphere holds the object, and noise sits on its surface.
SPHERE_MARGIN = 1.05


def in_region(settings: PlanSettings, result: PlanResult, cloud: np.ndarray) -> np.ndarray:
    """(N,) bool: the cloud's world points inside the object's region (``object.box_*`` when
    given, else its sphere): the object, drawn in colour; the rest is its surroundings."""
    obj = settings.object
    if obj.box_min is not None and obj.box_max is not None:
        return np.all((cloud >= obj.box_min) & (cloud <= obj.box_max), axis=1)
    distance = np.linalg.norm(cloud - result.frame.center, axis=1)
    return distance <= SPHERE_MARGIN * result.frame.radius


def name_of(settings: PlanSettings) -> str:
    """The input's file or folder name, as the plan's title says it."""
    return Path(settings.mesh or settings.captures or "views").name


def write_outputs(settings: PlanSettings, result: PlanResult) -> list[Path]:
    """Write the plan's files into ``settings.out_dir``; returns their paths."""
    out = Path(settings.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    record = plan_record(settings, result)
    frame = result.frame
    cloud = frame.points_to_world(result.cloud)
    world = frame.poses_to_world(result.views.poses)
    written = []
    if not len(cloud):
        # A flat object seen edge-on, or one too small for a pixel: the plan still stands.
        empty = "the visited views saw nothing of the object: cloud.ply holds no points"
        log.warning("%s: %s", name_of(settings), empty)
        record["notes"] = [*record["notes"], empty]
    write_cloud(out / "cloud.ply", cloud)
    written.append(out / "cloud.ply")
    fused = result.reconstruction
    if fused is not None and len(fused.triangles):
        write_mesh(out / "reconstruction.ply", fused.vertices, fused.triangles)
        written.append(out / "reconstruction.ply")
    inside = in_region(settings, result, cloud)
    region, surroundings = cloud[inside], cloud[~inside]
    vertices, faces = hull_mesh(region)
    focus = (frame.center, frame.radius) if len(surroundings) else None
    name = name_of(settings)
    title = f"{settings.method} on {name}: next view {result.chosen[0]}, plan {result.chosen}"
    if settings.picture:
        from nbv.plan.picture import draw_plan

        draw_plan(out / "plan.png", region, vertices, faces, world, result.visited,
                  result.chosen, title, frame.up, surroundings, focus)  # fmt: skip
        written.append(out / "plan.png")
    if settings.page:
        from nbv.plan.page import write_plan_page

        write_plan_page(
            out / "plan.html", points=region.astype(np.float32), hull_vertices=vertices,
            hull_faces=faces, candidates=world, chosen=result.chosen, visited=result.visited,
            title=title, up=frame.up.lstrip("-"), surroundings=surroundings.astype(np.float32),
        )  # fmt: skip
        written.append(out / "plan.html")
    # plan.json last: its presence says the run finished.
    write_text(out / "plan.json", json.dumps(record, indent=1))
    written.append(out / "plan.json")
    return written
