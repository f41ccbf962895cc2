"""A viewspace's depth images as its view record: back-projected, scored, subsampled.

:func:`view_data` is how a rendered (or captured) viewspace becomes a
:class:`~nbv.dataset.records.ViewData`: the dataset generator uses it for every model, and the
planner for a user's mesh does the same, so that both score views alike.
"""

from __future__ import annotations

import numpy as np

from nbv.dataset.records import ViewData, offsets_of
from nbv.geometry.camera import Intrinsics, backproject
from nbv.geometry.clouds import random_subset
from nbv.geometry.hull import hull_vertices
from nbv.geometry.scores import coverage_bits
from nbv.render.job import RenderError

__all__ = ["view_data"]


def view_data(
    depth: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    gt_points: np.ndarray,
    eps: float,
    points_per_view: int,
    rng: np.random.Generator,
    keep_depth: bool = False,
) -> ViewData:
    """Back-project, score and subsample the depth images of one viewspace.

    Args:
        depth: (V, H, W) planar depth, inf for background.
        poses: (V, 4, 4) camera-to-world.
        intrinsics: the camera.
        gt_points: (n_gt, 3) ground truth the coverage bits refer to.
        eps: coverage threshold, world units.
        points_per_view: points kept per view (random subset); 0 keeps all.
        rng: generator of the subsets.
        keep_depth: also return the depth images as float16.

    Returns:
        The viewspace's :class:`ViewData`; coverage bits come from the full-resolution clouds.

    Raises:
        RenderError: no view shows anything of the object. (A single empty view is kept: a flat
            object seen edge-on shows nothing.)
    """
    kept, bits, hulls = [], [], []
    for v in range(len(depth)):
        points = backproject(depth[v], intrinsics, poses[v])
        # The one coverage test of the project (the evaluator and the planner use it too).
        bits.append(coverage_bits([points], gt_points, eps)[0])
        hulls.append(hull_vertices(points).astype(np.float32))
        kept.append(random_subset(points, points_per_view, rng).astype(np.float32))
    if not any(len(p) for p in kept):
        raise RenderError("empty render: no view shows anything of the object")
    return ViewData(
        poses=poses,
        points=np.concatenate(kept),
        offsets=offsets_of(kept),
        coverage=np.stack(bits),
        hull_points=np.concatenate(hulls),
        hull_offsets=offsets_of(hulls),
        points_per_view=points_per_view,
        depth=depth.astype(np.float16) if keep_depth else None,
    )
