"""Depth by ray casting in this process: the ``raycast`` render backend.

The ray casting itself is :func:`nbv.geometry.raycast.raycast_depth` (named here
:func:`render_raycast`, as the backend calls it); this module streams render jobs through it.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.geometry.raycast import raycast_depth as render_raycast
from nbv.geometry.raycast import reachable_pixels
from nbv.render.job import RenderError, RenderJob

__all__ = ["reachable_pixels", "render_raycast", "render_raycast_stream"]


def render_raycast_stream(
    jobs: Iterable[RenderJob], intrinsics: Intrinsics, threads: int
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    """Ray cast each job in turn: ``(key, (V, H, W) float32 depth)``, or ``(key, RenderError)``
    for a job that failed (the stream goes on)."""
    for job in jobs:
        try:
            depth = render_raycast(job.vertices, job.faces, job.poses, intrinsics, threads=threads)
        except Exception as exc:  # one bad mesh must not stop the stream
            yield job.key, RenderError(f"{job.key!r}: {type(exc).__name__}: {exc}")
        else:
            yield job.key, depth
