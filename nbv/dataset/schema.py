"""The HDF5 layout of a dataset shard and the functions that write it (the contract between
stages: docs/dataset.md, "The shard file").

A shard file holds::

    / (attrs)                   schema_version, eps, n_gt, width, height, fx, fy, cx, cy, seed,
                                licence (of the source's meshes), config (JSON of the settings
                                that shape the data)
    /viewspaces/<name>          (V, 3) float64 camera positions
    /splits/<split>             keys of the models in that split (variable-length strings)
    /failures                   (K, 2) strings: key, reason of each model that could not be made
    /models/<key> (attrs)       category, split, source, source_path, center (3,), scale, seed,
                                gt_hull_volume (volume of the ground truth's convex hull; 0 if
                                flat, NaN if Qhull failed), gt_hull_error (Qhull's message or "")
    /models/<key>/gt_points     (n_gt, 3) float32 on the normalised mesh
    /models/<key>/views/<vs>/poses     (V, 4, 4) float64 camera-to-world (OpenCV camera axes)
    /models/<key>/views/<vs>/points    (sum N_v, 3) float32 world points (attr points_per_view)
    /models/<key>/views/<vs>/offsets   (V + 1,) int64
    /models/<key>/views/<vs>/coverage  (V, ceil(n_gt / 8)) uint8 packed bits (full-resolution views)
    /models/<key>/views/<vs>/hull_points   (sum K_v, 3) float32 hull vertices of each full view
    /models/<key>/views/<vs>/hull_offsets  (V + 1,) int64, as offsets for hull_points
    /models/<key>/views/<vs>/depth     (V, H, W) float16, only with keep_depth (inf = background)

Per-model data first goes to a *part* file of its own (same layout, one model), written to a
temporary name and renamed when complete; the shard file is assembled from the parts the same way.
A model is therefore complete or absent whatever moment the process is killed."""

from __future__ import annotations

import io
import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np

from nbv.dataset.records import ModelData, ViewData
from nbv.utils.atomic import atomic_path

SCHEMA_VERSION = 1


#: Root attributes every shard carries (docs/dataset.md, "The shard file").
ROOT_ATTRS = ("schema_version", "eps", "n_gt", "width", "height", "fx", "fy", "cx", "cy")


_COMPRESSION = {"compression": "gzip", "compression_opts": 4, "shuffle": True}


_STR = h5py.string_dtype()


def write_root(handle: h5py.File, root_attrs: dict, viewspaces: dict[str, np.ndarray]) -> None:
    """Write the root attributes and the viewspaces of a shard or part file."""
    for name, value in root_attrs.items():
        handle.attrs[name] = value
    group = handle.require_group("viewspaces")
    for name, positions in viewspaces.items():
        group.create_dataset(name, data=np.asarray(positions, dtype=np.float64))


def write_model(group: h5py.Group, model: ModelData) -> None:
    """Write one model into ``group`` (an empty ``/models/<key>`` group)."""
    group.attrs.update(
        category=model.category,
        split=model.split,
        source=model.source,
        source_path=model.source_path,
        center=np.asarray(model.center, dtype=np.float64),
        scale=float(model.scale),
        seed=int(model.seed),
        gt_hull_volume=float(model.gt_hull_volume),
        gt_hull_error=str(model.gt_hull_error),
    )
    group.create_dataset("gt_points", data=model.gt_points.astype(np.float32), **_COMPRESSION)
    for name, view in model.views.items():
        g = group.create_group(f"views/{name}")
        g.create_dataset("poses", data=view.poses.astype(np.float64))
        points = g.create_dataset("points", data=view.points.astype(np.float32), **_COMPRESSION)
        points.attrs["points_per_view"] = int(view.points_per_view)
        g.create_dataset("offsets", data=view.offsets.astype(np.int64))
        g.create_dataset("coverage", data=view.coverage.astype(np.uint8), **_COMPRESSION)
        g.create_dataset("hull_points", data=view.hull_points.astype(np.float32))
        g.create_dataset("hull_offsets", data=view.hull_offsets.astype(np.int64))
        if view.depth is not None:
            depth = view.depth.astype(np.float16)
            g.create_dataset("depth", data=depth, chunks=(1, *depth.shape[1:]), **_COMPRESSION)


def read_model(
    group: h5py.Group, viewspaces: tuple[str, ...] | None = None, depth: bool = True
) -> ModelData:
    """Read ``/models/<key>`` back into a :class:`ModelData` (all views unless named; the
    full-resolution depth images too, when stored, unless ``depth`` is False)."""
    attrs = group.attrs
    views = {}
    for name, g in group["views"].items():
        if viewspaces is not None and name not in viewspaces:
            continue
        views[name] = ViewData(
            poses=g["poses"][()],
            points=g["points"][()],
            offsets=g["offsets"][()],
            coverage=g["coverage"][()],
            hull_points=g["hull_points"][()],
            hull_offsets=g["hull_offsets"][()],
            points_per_view=int(g["points"].attrs.get("points_per_view", 0)),
            depth=g["depth"][()] if depth and "depth" in g else None,
        )
    return ModelData(
        key=group.name.rsplit("/", 1)[-1],
        category=str(attrs["category"]),
        split=str(attrs["split"]),
        source=str(attrs["source"]),
        source_path=str(attrs["source_path"]),
        center=np.asarray(attrs["center"]),
        scale=float(attrs["scale"]),
        seed=int(attrs["seed"]),
        gt_points=group["gt_points"][()],
        gt_hull_volume=float(attrs["gt_hull_volume"]),
        views=views,
        gt_hull_error=str(attrs.get("gt_hull_error", "")),
    )


@contextmanager
def hdf5_written(path: Path) -> Iterator[h5py.File]:
    """An HDF5 file to fill in the body, built in memory and written to ``path`` whole once the
    body ends (:func:`~nbv.utils.atomic.atomic_path`: nothing under ``path`` if it fails).

    In memory first: when the disk fills (or a file-size limit is reached) under HDF5's own
    writes, the library's later clean-up fails too and can end the process with a crash; a plain
    write of the finished bytes fails with the system's error, which the commands report in one
    line. Memory: the file's size.
    """
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as handle:
        yield handle
    with atomic_path(path) as tmp, open(tmp, "wb") as out:
        out.write(buffer.getbuffer())


def write_part(
    path: Path, root_attrs: dict, viewspaces: dict[str, np.ndarray], model: ModelData
) -> None:
    """Write a one-model part file atomically (temporary name, fsync, rename)."""
    with hdf5_written(path) as handle:
        write_root(handle, root_attrs, viewspaces)
        write_model(handle.create_group(f"models/{model.key}"), model)


def write_strings(handle: h5py.Group, name: str, values: list, columns: int | None = None) -> None:
    """Store strings (or rows of ``columns`` strings; an empty list gives (0, columns))."""
    data = np.array(values, dtype=object)
    if columns is not None:
        data = data.reshape(-1, columns)
    handle.create_dataset(name, data=data, dtype=_STR)


def assemble_shard(
    path: Path,
    root_attrs: dict,
    viewspaces: dict[str, np.ndarray],
    sources: list[tuple[Path, str]],
    failures: list[tuple[str, str]],
) -> None:
    """Write a shard file atomically from models held in other files.

    Args:
        path: the shard file to (re)write.
        root_attrs: root attributes (``ROOT_ATTRS`` and more).
        viewspaces: name -> (V, 3) positions.
        sources: (file, key) of every model to copy, in the order to store them; a file may be the
            previous version of ``path`` itself.
        failures: (key, reason) of the models that could not be made.
    """
    splits: dict[str, list[str]] = {}
    with hdf5_written(path) as out:
        write_root(out, root_attrs, viewspaces)
        models = out.create_group("models")
        for file, key in sources:
            with h5py.File(file, "r") as src:
                src.copy(src[f"models/{key}"], models, name=key)
            splits.setdefault(str(models[key].attrs["split"]), []).append(key)
        for split, keys in splits.items():
            write_strings(out, f"splits/{split}", keys)
        write_strings(out, "failures", [[key, reason] for key, reason in failures], columns=2)


def config_json(settings: dict) -> str:
    """Canonical JSON of the settings that determine a dataset's arrays."""
    return json.dumps(settings, sort_keys=True, separators=(",", ":"))
