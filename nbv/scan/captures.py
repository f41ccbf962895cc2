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
from pathlib import Path

import numpy as np
import OpenEXR

from nbv.geometry.camera import (
    Intrinsics,
    opencv_to_blender,
)
from nbv.scan.capture import (
    AXES,
    NO_RETURN,
    Capture,
    CaptureError,
    check_rigid,
    cloud_capture,
    depth_capture,
)

#: The index file of a capture folder.
INDEX = "views.json"
#: Depth image suffixes and point cloud suffixes a view may have.
DEPTH_SUFFIXES = (".npy", ".png", ".exr")
CLOUD_SUFFIXES = (".ply", ".pcd")
#: The keys of ``views.json`` and of one of its views.
FOLDER_KEYS = ("axes", "intrinsics", "depth_scale", "object", "no_return", "max_range", "views")
VIEW_KEYS = ("file", "pose", "intrinsics", "depth_scale", "no_return", "max_range")


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
