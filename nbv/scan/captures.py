"""Capture folders: a user's views of an object, read, checked, and written.

A capture folder holds ``views.json`` and one file a view (paths relative to the folder)::

    {
      "axes": "opencv",                     # or "blender": poses with camera -z forward, +y up
      "intrinsics": {"width": 640, "height": 480, "fx": 476, "fy": 476, "cx": 319.5, "cy": 239.5},
      "depth_scale": 0.001,                 # world units per stored unit (16-bit PNG, int NPY)
      "object": {"center": [0, 0, 0], "radius": 0.5},   # optional
      "no_return": "unknown",               # or "free"; optional, per view too
      "max_range": 1.2,                     # world units (planar depth); optional, per view too
      "views": [
        {"file": "view_00.npy", "pose": [[...], [...], [...], [0, 0, 0, 1]]},
        {"file": "view_01.ply", "pose": [[...], [...], [...], [0, 0, 0, 1]]}
      ]
    }

* A view is a planar depth image (``.npy`` float world units, or integer with ``depth_scale``;
  ``.png`` 16-bit with ``depth_scale``; ``.exr`` float, the first of its channels Z, Y, R, V or
  depth, through the OpenEXR package) taken with ``intrinsics``, or a point cloud (``.ply``,
  ``.pcd``) in the world frame.
  Depth 0, NaN or infinite is "no measurement".
* ``no_return`` says what a pixel without a measurement means: ``unknown`` (the default: a
  depth sensor's dark, shiny or grazing surface, often on the object itself; the planner's map
  leaves its ray unknown) or ``free`` (nothing is there: a rendered image's background, or a
  sensor that always returns within its range; the ray is free space up to ``max_range``, or
  through the whole region without it). A point cloud view declared ``free`` has its image
  blocks without a point free.
* ``max_range`` is the sensor's range (planar depth, world units): a measurement beyond it is
  dropped and its ray is free up to the range (OctoMap's ``maxrange``), whatever ``no_return``.
* ``pose`` is the camera-to-world 4x4 of the view (world units), OpenCV axes (x right, y down,
  z forward) unless ``axes`` says ``blender``. A view may give its own ``intrinsics`` and
  ``depth_scale``.
* ``object`` is optional; the planner's ``object.center`` / ``object.radius`` settings win over
  it, and without either the object is estimated from the captured points.

:func:`read_captures` refuses bad input with one :class:`CaptureError` naming the file and what
is wrong, before any output is written: NaN or infinite points, a pose that is not rigid, missing
intrinsics, integer depth without ``depth_scale``, an empty view; :func:`check_views_see` then
refuses a view whose camera does not look at the object. :func:`write_captures` writes a folder
whole or not at all.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenEXR

from nbv.geometry.camera import (
    Intrinsics,
    backproject,
    opencv_to_blender,
    project,
    valid_depth,
)
from nbv.infogain.occupancy import Misses

#: The index file of a capture folder.
INDEX = "views.json"
#: Depth image suffixes and point cloud suffixes a view may have.
DEPTH_SUFFIXES = (".npy", ".png", ".exr")
CLOUD_SUFFIXES = (".ply", ".pcd")
#: Pose axes conventions.
AXES = ("opencv", "blender")
#: Tolerance of the rigidity checks (|R^T R - I| and |det R - 1|): poses written as text with
#: six decimals still pass, a scaled or sheared matrix does not.
RIGID_TOL = 1e-4
#: A float depth image whose median is this many times the camera's distance to the object is
#: in other units than the poses (millimetres against metres is 1000).
UNIT_RATIO = 20.0
#: What a pixel without a measurement means (``no_return``); the first is the default.
NO_RETURN = ("unknown", "free")
#: The keys of ``views.json`` and of one of its views.
FOLDER_KEYS = ("axes", "intrinsics", "depth_scale", "object", "no_return", "max_range", "views")
VIEW_KEYS = ("file", "pose", "intrinsics", "depth_scale", "no_return", "max_range")


class CaptureError(ValueError):
    """A capture folder that cannot be used; the message names the file and what is wrong."""


@dataclass(frozen=True)
class Capture:
    """One captured view.

    Attributes:
        file: the view's file.
        points: (N, 3) float64 world points, N >= 1.
        pose: (4, 4) float64 camera-to-world, OpenCV axes.
        intrinsics: the depth camera (None for a point cloud view).
        median_depth: median planar depth of the view's points, world units.
        misses: what its rays that returned nothing mean, world units (None: unknown; see
            ``no_return`` and ``max_range`` in the module docstring).
        no_return: the view's ``no_return``; max_range: its ``max_range`` (world units, or None).
        depth: a depth image view's (H, W) float64 depth in world units as read (before the
            range cut: 0, NaN or inf where nothing was measured); None for a point cloud view.
    """

    file: Path
    points: np.ndarray
    pose: np.ndarray
    intrinsics: Intrinsics | None
    median_depth: float
    misses: Misses | None = None
    no_return: str = NO_RETURN[0]
    max_range: float | None = None
    depth: np.ndarray | None = None


def check_rigid(pose: object, where: str) -> np.ndarray:
    """A camera-to-world pose as a (4, 4) float64 array, refused unless rigid.

    Raises:
        CaptureError: not a 4x4 of finite numbers, a last row other than ``0 0 0 1``, a rotation
            part with ``R^T R != I`` or ``det R != 1`` (beyond :data:`RIGID_TOL`).
    """
    try:
        m = np.array(pose, dtype=np.float64)
    except (TypeError, ValueError):
        raise CaptureError(f"{where}: pose must be a 4x4 matrix of numbers") from None
    if m.shape != (4, 4):
        raise CaptureError(f"{where}: pose must be 4x4, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise CaptureError(f"{where}: pose has NaN or infinite entries")
    if not np.allclose(m[3], [0, 0, 0, 1], atol=RIGID_TOL):
        raise CaptureError(f"{where}: pose's last row is {m[3].tolist()}, must be [0, 0, 0, 1]")
    r = m[:3, :3]
    off = float(np.abs(r.T @ r - np.eye(3)).max())
    if off > RIGID_TOL:
        raise CaptureError(
            f"{where}: pose is not rigid: R^T R differs from I by {off:.3g} (scaled or sheared "
            "rotation part)"
        )
    det = float(np.linalg.det(r))
    if abs(det - 1.0) > RIGID_TOL:
        raise CaptureError(f"{where}: pose is not rigid: det R = {det:.6g}, must be 1 (a mirror)")
    return m


def _intrinsics(value: object, where: str) -> Intrinsics:
    keys = ("width", "height", "fx", "fy", "cx", "cy")
    if not isinstance(value, dict) or sorted(value) != sorted(keys):
        raise CaptureError(f"{where}: intrinsics must be an object with keys {', '.join(keys)}")
    try:
        return Intrinsics(int(value["width"]), int(value["height"]),
                          *(float(value[k]) for k in keys[2:]))  # fmt: skip
    except (TypeError, ValueError) as err:
        raise CaptureError(f"{where}: intrinsics {value}: {err}") from None


def _read_depth(path: Path, scale: float | None, where: str) -> np.ndarray:
    """A depth image in world units (float64, 0 / NaN / inf where nothing was measured)."""
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            raw = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as err:
            raise CaptureError(f"{where}: cannot read NPY ({err})") from None
    elif suffix == ".png":
        from PIL import Image

        try:
            with Image.open(path) as image:
                mode = image.mode
                raw = np.array(image)
        except OSError as err:
            raise CaptureError(f"{where}: cannot read PNG ({err})") from None
        if not mode.startswith("I"):
            raise CaptureError(f"{where}: a {mode} PNG; depth must be a 16-bit single-channel PNG")
    else:
        raw = _read_exr(path, where)
    if raw.ndim != 2:
        raise CaptureError(f"{where}: depth must be one channel (H, W), got shape {raw.shape}")
    if np.issubdtype(raw.dtype, np.integer):
        if scale is None:
            raise CaptureError(
                f"{where}: integer depth (e.g. millimetres) without depth_scale; give depth_scale "
                "= world units per stored unit (0.001 for millimetres in a metre world)"
            )
        depth = raw.astype(np.float64) * scale
        depth[raw == 0] = np.inf
        return depth
    if not np.issubdtype(raw.dtype, np.floating):
        raise CaptureError(f"{where}: depth of dtype {raw.dtype}; must be float or integer")
    return raw.astype(np.float64) * (1.0 if scale is None else scale)


def _read_exr(path: Path, where: str) -> np.ndarray:
    """The depth channel of an EXR file (OpenEXR >= 3.3's File API)."""
    try:
        with OpenEXR.File(str(path)) as exr:
            channels = exr.channels()
            name = next(c for c in ("Z", "Y", "R", "V", "depth") if c in channels)
            return np.asarray(channels[name].pixels)
    except StopIteration:
        raise CaptureError(f"{where}: no depth channel (Z, Y, R, V or depth) in the EXR") from None
    except Exception as err:  # any reader failure is a bad file
        raise CaptureError(f"{where}: cannot read EXR ({err})") from None


def _read_cloud(path: Path, where: str) -> np.ndarray:
    import open3d as o3d

    cloud = o3d.io.read_point_cloud(
        str(path), format=path.suffix.lower()[1:], remove_nan_points=False,
        remove_infinite_points=False,
    )  # fmt: skip
    points = np.asarray(cloud.points, dtype=np.float64)
    if len(points) == 0:
        raise CaptureError(f"{where}: no points (an empty view, or not a point cloud Open3D reads)")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        raise CaptureError(
            f"{where}: {int(bad.sum())} of {len(points)} points are NaN or infinite (first: point "
            f"{int(np.flatnonzero(bad)[0])})"
        )
    return points


def read_captures(folder: str | os.PathLike) -> tuple[list[Capture], dict | None]:
    """Read and check a capture folder (format in the module docstring).

    Returns:
        ``(captures, object)``: the views in file order, and ``views.json``'s ``object`` as
        ``{"center": (3,) array, "radius": float}`` (None when absent).

    Raises:
        CaptureError: the first problem found, naming the file.
    """
    folder = Path(folder)
    index = folder / INDEX
    if not index.is_file():
        raise CaptureError(f"{index}: no such file; a capture folder holds {INDEX} (see README)")
    try:
        spec = json.loads(index.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise CaptureError(f"{index}: cannot read JSON ({err})") from None
    if not isinstance(spec, dict) or not isinstance(spec.get("views"), list) or not spec["views"]:
        raise CaptureError(f"{index}: must be an object with a non-empty list 'views'")
    unknown = sorted(set(spec) - set(FOLDER_KEYS))
    if unknown:
        raise CaptureError(f"{index}: unknown keys {unknown}; allowed: {', '.join(FOLDER_KEYS)}")
    axes = spec.get("axes", "opencv")
    if axes not in AXES:
        raise CaptureError(f"{index}: axes={axes!r}; allowed: {', '.join(AXES)}")
    captures = [_read_view(folder, i, view, spec, axes) for i, view in enumerate(spec["views"])]
    return captures, _object(spec.get("object"), str(index))


def _object(value: object, where: str) -> dict | None:
    if value is None:
        return None
    try:
        center = np.array(value["center"], dtype=np.float64)
        radius = float(value["radius"])
    except (TypeError, KeyError, ValueError):
        raise CaptureError(
            f"{where}: object must be {{'center': [x, y, z], 'radius': r}}"
        ) from None
    if center.shape != (3,) or not np.all(np.isfinite(center)) or not radius > 0:
        raise CaptureError(f"{where}: object needs 3 finite centre numbers and a radius > 0")
    return {"center": center, "radius": radius}


def _read_view(folder: Path, i: int, view: object, spec: dict, axes: str) -> Capture:
    where = f"{folder / INDEX}: views[{i}]"
    if not isinstance(view, dict) or "file" not in view or "pose" not in view:
        raise CaptureError(f"{where}: each view needs 'file' and 'pose'")
    unknown = sorted(set(view) - set(VIEW_KEYS))
    if unknown:
        raise CaptureError(f"{where}: unknown keys {unknown}; allowed: {', '.join(VIEW_KEYS)}")
    path = folder / str(view["file"])
    where = f"{path}"
    no_return, max_range = _sensor(view, spec, where)
    pose = check_rigid(view["pose"], where)
    if axes == "blender":
        pose = opencv_to_blender(pose)  # the same axis flip turns a Blender pose into OpenCV's
    suffix = path.suffix.lower()
    if suffix not in DEPTH_SUFFIXES + CLOUD_SUFFIXES:
        raise CaptureError(
            f"{where}: unsupported view file; allowed: {', '.join(DEPTH_SUFFIXES + CLOUD_SUFFIXES)}"
        )
    if not path.is_file():
        raise CaptureError(f"{where}: no such file")
    if suffix in DEPTH_SUFFIXES:
        given = view.get("intrinsics", spec.get("intrinsics"))
        if given is None:
            raise CaptureError(
                f"{where}: a depth image needs intrinsics (in {INDEX}, for all views or this one)"
            )
        intrinsics = _intrinsics(given, where)
        scale = view.get("depth_scale", spec.get("depth_scale"))
        if scale is not None and not (isinstance(scale, int | float) and scale > 0):
            raise CaptureError(f"{where}: depth_scale={scale!r}; must be a positive number")
        depth = _read_depth(path, scale, where)
        return depth_capture(depth, intrinsics, pose, path, no_return, max_range)
    return cloud_capture(_read_cloud(path, where), pose, path, no_return, max_range)


def depth_capture(
    depth: np.ndarray,
    intrinsics: Intrinsics,
    pose: np.ndarray,
    file: Path,
    no_return: str = NO_RETURN[0],
    max_range: float | None = None,
) -> Capture:
    """A depth image view as the planner reads it (a file's, or one given to
    :class:`nbv.scan.planner.Planner`).

    Args:
        depth: (H, W) float64 planar depth, world units; 0, NaN or inf where nothing was
            measured.
        intrinsics: its camera ((H, W) must be its size).
        pose: (4, 4) rigid camera-to-world, OpenCV axes.
        file: the view's file (named in messages).
        no_return, max_range: what its missing pixels mean (module docstring).

    Raises:
        CaptureError: a size other than the camera's, or no pixel with a depth (within the range).
    """
    where = f"{file}"
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise CaptureError(
            f"{where}: depth is {depth.shape[1]} x {depth.shape[0]}, the intrinsics say "
            f"{intrinsics.width} x {intrinsics.height}"
        )
    measured = valid_depth(depth)
    beyond = measured & (depth > max_range) if max_range is not None else None
    kept = measured & ~beyond if beyond is not None else measured
    points = backproject(depth, intrinsics, pose, kept)
    if len(points) == 0:
        raise CaptureError(
            f"{where}: empty view: no pixel holds a depth"
            + (f" within max_range={max_range}" if max_range is not None else "")
        )
    mask = ~measured if no_return == "free" else np.zeros(depth.shape, dtype=bool)
    if beyond is not None:
        mask |= beyond
    declared = no_return == "free" or bool(mask.any())
    misses = Misses(mask, max_range, intrinsics) if declared else None
    # A pixel's planar depth is its point's: no projection needed.
    return Capture(file, points, pose, intrinsics, float(np.median(depth[kept])), misses,
                   no_return, max_range, depth)  # fmt: skip


def cloud_capture(
    points: np.ndarray,
    pose: np.ndarray,
    file: Path,
    no_return: str = NO_RETURN[0],
    max_range: float | None = None,
) -> Capture:
    """A point cloud view (N, 3) float64 world points (finite) with its (4, 4) camera-to-world
    pose, as the planner reads it; ``max_range`` drops the points beyond it (planar depth).

    Raises:
        CaptureError: no point is left (within the range).
    """
    if max_range is not None:
        _, z = project(points, Intrinsics(), pose)
        points = points[z <= max_range]
        if len(points) == 0:
            raise CaptureError(f"{file}: empty view: no point within max_range={max_range}")
    misses = Misses(None, max_range) if no_return == "free" else None
    _, z = project(points, Intrinsics(), pose)
    return Capture(file, points, pose, None, float(np.median(z)), misses, no_return, max_range)


def _sensor(view: dict, spec: dict, where: str) -> tuple[str, float | None]:
    """A view's ``no_return`` and ``max_range`` (its own, else the folder's), checked."""
    no_return = view.get("no_return", spec.get("no_return", NO_RETURN[0]))
    if no_return not in NO_RETURN:
        raise CaptureError(f"{where}: no_return={no_return!r}; allowed: {', '.join(NO_RETURN)}")
    max_range = view.get("max_range", spec.get("max_range"))
    if max_range is not None and not (
        isinstance(max_range, int | float) and not isinstance(max_range, bool) and max_range > 0
    ):
        raise CaptureError(
            f"{where}: max_range={max_range!r}; must be a positive distance (world units) or null"
        )
    return no_return, None if max_range is None else float(max_range)


def select_views(
    captures: list[Capture], views: tuple[int, ...], folder: str | os.PathLike
) -> list[Capture]:
    """The captures ``views`` (indices of ``views.json``'s list), in that order.

    Raises:
        CaptureError: an index the folder does not hold.
    """
    bad = [i for i in views if i >= len(captures)]
    if bad:
        raise CaptureError(
            f"views={list(views)}: {folder} holds {len(captures)} views (indices 0.."
            f"{len(captures) - 1})"
        )
    return [captures[i] for i in views]


def check_views_see(
    captures: list[Capture], center: np.ndarray, radius: float, camera: Intrinsics
) -> None:
    """Refuse a view whose camera does not look at the object, or whose depth is in other units.

    The object's centre must lie in front of the camera and inside its image (a depth view's
    own intrinsics; ``camera`` for a point cloud view); a float depth image whose median depth
    is :data:`UNIT_RATIO` times the camera's distance to the object is in other units.

    Raises:
        CaptureError: naming the file.
    """
    for c in captures:
        cam = c.intrinsics or camera
        (u, v), z = (x[0] for x in project(np.asarray(center)[None], cam, c.pose))
        distance = float(np.linalg.norm(c.pose[:3, 3] - center))
        if distance <= radius:
            raise CaptureError(
                f"{c.file}: the camera is inside the object's sphere (distance {distance:.4g} to "
                f"the centre, radius {radius:.4g})"
            )
        if not (z > 0 and -0.5 <= u <= cam.width - 0.5 and -0.5 <= v <= cam.height - 0.5):
            raise CaptureError(
                f"{c.file}: the camera does not look at the object: its centre "
                f"{np.round(center, 4).tolist()} is "
                + ("behind the camera" if z <= 0 else f"outside the image, at pixel ({u:.0f}, "
                   f"{v:.0f}) of {cam.width} x {cam.height}")
                + " (wrong pose, or axes: blender?)"
            )  # fmt: skip
        if c.intrinsics is not None and c.median_depth > UNIT_RATIO * distance:
            raise CaptureError(
                f"{c.file}: depth is {c.median_depth / distance:.0f}x the camera's distance to "
                f"the object ({c.median_depth:.4g} against {distance:.4g}): another unit than the "
                "poses (millimetres?); give depth_scale"
            )


def write_captures(
    folder: str | os.PathLike,
    depths: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    center: np.ndarray | None,
    radius: float | None,
    no_return: str | None = None,
    max_range: float | None = None,
) -> None:
    """Write depth views as a capture folder (``view_NN.npy`` float32 and ``views.json``).

    The folder appears whole or not at all: it is written beside its final name and renamed.

    Args:
        folder: the folder to make; must not exist, or be empty.
        depths: (V, H, W) planar depth, world units, inf (or 0) where nothing was measured.
        poses: (V, 4, 4) camera-to-world, OpenCV axes, world units.
        intrinsics: the camera.
        center, radius: the object's sphere, world units (``object`` of ``views.json``); None
            leaves it out (the planner estimates it).
        no_return: ``views.json``'s ``no_return`` (:data:`NO_RETURN`; ``free`` for rendered
            views, whose background is empty); None leaves it out (unknown).
        max_range: ``views.json``'s ``max_range``; None leaves it out.
    """
    if no_return is not None and no_return not in NO_RETURN:
        raise ValueError(f"no_return={no_return!r}; allowed: {', '.join(NO_RETURN)}")
    folder = Path(folder)
    if folder.exists() and any(folder.iterdir()):
        raise CaptureError(f"{folder}: exists and is not empty; captures go to a new folder")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        views = []
        for i, (depth, pose) in enumerate(zip(depths, poses, strict=True)):
            name = f"view_{i:02d}.npy"
            np.save(tmp / name, np.asarray(depth, dtype=np.float32))
            views.append({"file": name, "pose": np.asarray(pose).tolist()})
        spec: dict = {"axes": "opencv", "intrinsics": intrinsics.as_dict()}
        if center is not None and radius is not None:
            spec["object"] = {"center": np.asarray(center).tolist(), "radius": float(radius)}
        if no_return is not None:
            spec["no_return"] = no_return
        if max_range is not None:
            spec["max_range"] = float(max_range)
        spec["views"] = views
        (tmp / INDEX).write_text(json.dumps(spec, indent=1))
        if folder.exists():
            folder.rmdir()
        os.replace(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _exact_float32(depth: np.ndarray) -> np.ndarray:
    """The depth as float32 when that loses nothing (a float32 source), else float64: a folder
    read back gives the same points bit for bit."""
    single = depth.astype(np.float32)
    return single if np.array_equal(single.astype(np.float64), depth, equal_nan=True) else depth


def write_views(
    folder: str | os.PathLike,
    captures: list[Capture],
    center: np.ndarray | None = None,
    radius: float | None = None,
    extra: dict[str, str] | None = None,
    replace: bool = False,
) -> None:
    """Write views read or given before as a capture folder that reads back to the same views:
    depth images as ``view_NN.npy`` (world units, as read: before the range cut), point clouds
    as ``view_NN.ply``; each view with its own intrinsics, ``no_return`` and ``max_range``.

    Args:
        folder: the folder; with ``replace`` an existing one is swapped for the new one (never
            half of each), else it must be new or empty.
        captures: the views, in order.
        center, radius: ``views.json``'s ``object`` (world units), or None.
        extra: more text files to write into the folder, by name (read by their own readers;
            :func:`read_captures` reads only ``views.json`` and the views).
        replace: replace an existing folder.
    """
    import open3d as o3d

    folder = Path(folder)
    if not replace and folder.exists() and any(folder.iterdir()):
        raise CaptureError(f"{folder}: exists and is not empty; captures go to a new folder")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    old = None
    try:
        views = []
        for i, c in enumerate(captures):
            entry: dict = {}
            if c.depth is not None:
                entry["file"] = f"view_{i:02d}.npy"
                np.save(tmp / entry["file"], _exact_float32(np.asarray(c.depth, np.float64)))
                entry["intrinsics"] = c.intrinsics.as_dict()
            else:
                entry["file"] = f"view_{i:02d}.ply"
                cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(c.points))
                if not o3d.io.write_point_cloud(str(tmp / entry["file"]), cloud):
                    raise OSError(f"{tmp / entry['file']}: Open3D could not write the cloud")
            entry["pose"] = np.asarray(c.pose).tolist()
            entry["no_return"] = c.no_return
            if c.max_range is not None:
                entry["max_range"] = float(c.max_range)
            views.append(entry)
        spec: dict = {"axes": "opencv"}
        if center is not None and radius is not None:
            spec["object"] = {"center": np.asarray(center).tolist(), "radius": float(radius)}
        spec["views"] = views
        (tmp / INDEX).write_text(json.dumps(spec, indent=1))
        for name, text in (extra or {}).items():
            (tmp / name).write_text(text)
        if folder.exists() and any(folder.iterdir()):
            old = folder.with_name(f".{folder.name}.old")
            shutil.rmtree(old, ignore_errors=True)
            os.replace(folder, old)
        elif folder.exists():
            folder.rmdir()
        os.replace(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and not folder.exists():
            os.replace(old, folder)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
