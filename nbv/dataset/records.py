"""In-memory records of a dataset's models: plain arrays, no HDF5, so that algorithms can take them."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
        """Every view's (K_v, 3) hull vertices, float64 (for :func:`nbv.geometry.scores.vig_of_state`)."""
        h, o = self.hull_points.astype(np.float64), self.hull_offsets
        return [h[o[v] : o[v + 1]] for v in range(len(o) - 1)]


@dataclass
class ModelData:
    """Everything the dataset stores for one model."""

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
