"""In-memory records of a dataset's models: plain arrays, no HDF5.

Algorithms (episodes, policies, scores) take these, never the storage code."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from nbv.geometry.scores import coverage_from_bits, coverage_gains, vig_gains, vig_of_state
from nbv.geometry.union import UnionHulls


def offsets_of(arrays: list[np.ndarray]) -> np.ndarray:
    """(len + 1,) int64 start offsets of arrays stored one after the other (``ViewData``'s
    ``offsets`` and ``hull_offsets``)."""
    return np.concatenate([[0], np.cumsum([len(a) for a in arrays])]).astype(np.int64)


@dataclass
class ViewData:
    """One model seen from one viewspace.

    Attributes:
        poses: (V, 4, 4) float64 camera-to-world.
        points: (sum N_v, 3) float32 world points of all views, view after view.
        offsets: (V + 1,) int64; view v is ``points[offsets[v]:offsets[v + 1]]``.
        coverage: (V, ceil(n_gt / 8)) uint8 packed coverage bits.
        hull_points: (sum K_v, 3) float32 convex-hull vertices of each full-resolution view.
        hull_offsets: (V + 1,) int64; view v's hull vertices are
            ``hull_points[hull_offsets[v]:hull_offsets[v + 1]]``.
        points_per_view: the subsampling setting the points were kept with (0 = all).
        depth: optional (V, H, W) float16 planar depth, inf for background.
    """

    poses: np.ndarray
    points: np.ndarray
    offsets: np.ndarray
    coverage: np.ndarray
    hull_points: np.ndarray
    hull_offsets: np.ndarray
    points_per_view: int = 0
    depth: np.ndarray | None = None

    def view_points(self, v: int) -> np.ndarray:
        """(N_v, 3) float32 points of view ``v``."""
        return self.points[self.offsets[v] : self.offsets[v + 1]]

    def view_hulls(self) -> list[np.ndarray]:
        """Every view's (K_v, 3) hull vertices, float64 (for
        :func:`nbv.geometry.scores.vig_of_state`)."""
        h, o = self.hull_points.astype(np.float64), self.hull_offsets
        return [h[o[v] : o[v + 1]] for v in range(len(o) - 1)]

    @cached_property
    def unions(self) -> UnionHulls:
        """Hull volumes of unions of these views, memoised for as long as this record lives
        (the episodes of one model share many view sets)."""
        return UnionHulls(self.view_hulls())


@dataclass
class ModelData:
    """Everything the dataset stores for one model.

    ``gt_hull_volume`` is 0 for a flat ground truth and NaN when Qhull failed on it; then
    ``gt_hull_error`` holds Qhull's message (empty otherwise). VIG is undefined for both.
    """

    key: str
    category: str
    split: str
    source: str
    source_path: str
    center: np.ndarray
    scale: float
    seed: int
    gt_points: np.ndarray
    gt_hull_volume: float
    views: dict[str, ViewData] = field(default_factory=dict)
    gt_hull_error: str = ""


#: The scores a view can be chosen by: coverage of the ground truth (PC-NBV) and VIG.
SCORES = ("coverage", "vig")


def score_functions(
    model: ModelData, score: str, viewspace: str
) -> tuple[Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], float]]:
    """``(gains, value)`` of ``score`` on a model's views of ``viewspace``.

    ``gains(view_state)`` is the ``(V,)`` gain of every view (0 for visited ones) and
    ``value(view_state)`` the score of the state, both from the stored ground truth: coverage
    from the packed coverage bits, VIG from the views' hull vertices and the ground truth's
    hull volume.

    Raises:
        ValueError: an unknown score (the message lists :data:`SCORES`).
    """
    view = model.views[viewspace]
    if score == "coverage":
        n_gt = len(model.gt_points)
        return (
            lambda s: coverage_gains(view.coverage, s, n_gt),
            lambda s: coverage_from_bits(view.coverage, s, n_gt),
        )
    if score == "vig":
        hulls = view.view_hulls()
        volume = model.gt_hull_volume
        return (lambda s: vig_gains(hulls, s, volume), lambda s: vig_of_state(hulls, s, volume))
    raise ValueError(f"score={score!r}: must be one of {', '.join(SCORES)}")
