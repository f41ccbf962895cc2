"""Depth rendering of meshes: Blender Cycles (the default) or Open3D ray casting.

Both backends share the camera model of :mod:`nbv.geometry.camera` and return planar depth, ``inf``
for
background, as (V, H, W) float32 arrays, one per mesh:

* ``"blender"`` runs ``blender_scripts/render_depth.py`` in ONE subprocess (the bpy wheel, or a
  Blender binary given by path) for a whole stream of meshes and yields each mesh's depth as soon
  as it is done, so the caller overlaps its own work with rendering.
* ``"raycast"`` casts one ray per pixel centre with Open3D's Embree scene, in this process.

Per-mesh failures come back as :class:`RenderError` values in the stream instead of exceptions,
so one bad mesh never costs the rest of a shard."""

from __future__ import annotations

import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.render.blender import check_options, render_blender
from nbv.render.job import BACKENDS, RenderError, RenderJob
from nbv.render.raycast import render_raycast_stream

#: The options each backend takes (:func:`render`'s ``**kw``).
OPTIONS = {
    "blender": {"blender", "threads", "device", "processes", "chunk"},
    "raycast": {"threads"},
}


def render(
    jobs: Iterable[RenderJob],
    intrinsics: Intrinsics,
    backend: str = "blender",
    workdir: Path | None = None,
    **kw,
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    """Render a stream of meshes with either backend; failures come back as RenderError values.

    Args:
        jobs: meshes with unique keys and OpenCV camera-to-world poses.
        intrinsics: the camera.
        backend: "blender" (default, :func:`render_blender`) or "raycast" (:func:`render_raycast`).
        workdir: temporary folder for the Blender backend; None makes one under the system's
            temporary folder (removed afterwards unless a log had to be kept).
        **kw: backend options: ``blender``, ``threads``, ``device``, ``processes``, ``chunk``
            for "blender"; ``threads`` for "raycast".

    Yields:
        ``(key, depth or RenderError)``; depth is (V, H, W) float32 planar depth, inf background.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    allowed = OPTIONS[backend]
    if set(kw) - allowed:
        raise ValueError(
            f"backend {backend!r} takes options {sorted(allowed)}, got {sorted(set(kw) - allowed)}"
        )
    if backend == "raycast":
        check_options(kw.get("threads", 0))
        return render_raycast_stream(jobs, intrinsics, kw.get("threads", 0))
    if workdir is not None:
        return render_blender(jobs, intrinsics, Path(workdir), **kw)
    check_options(
        kw.get("threads", 0),
        kw.get("device", "CPU"),
        kw.get("blender"),
        kw.get("processes", 1),
        kw.get("chunk", 0),
    )
    return _in_temporary_dir(jobs, intrinsics, kw)


def _in_temporary_dir(
    jobs: Iterable[RenderJob], intrinsics: Intrinsics, kw: dict
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    workdir = Path(tempfile.mkdtemp(prefix="nbv-blender-"))
    try:
        yield from render_blender(jobs, intrinsics, workdir, **kw)
    finally:
        # Left in place when it still holds a log kept for a failure.
        if not any(workdir.iterdir()):
            workdir.rmdir()
