"""In-memory records of a dataset's models: plain arrays, no HDF5.

Algorithms (episodes, policies, scores) take these, never the storage code."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from nbv.geometry.hull import QhullFailure
from nbv.geometry.scores import coverage_from_bits, coverage_gains, vig_gains, vig_of_state
from nbv.geometry.union import UnionHulls
from nbv.geometry.views import CapturedViews, offsets_of

__all__ = ["SCORES", "ModelData", "ViewData", "offsets_of", "score_functions"]


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

    def captured(self) -> CapturedViews:
        """What a camera gives a policy of these views: poses and points (the same arrays), no
        ground truth."""
        return CapturedViews(self.poses, self.points, self.offsets, self.points_per_view)

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

    def captured(self, viewspace: str) -> CapturedViews:
        """What a policy sees of the views of ``viewspace`` (:meth:`ViewData.captured`)."""
        return self.views[viewspace].captured()

    def view_gains(self, viewspace: str, score: str, view_state: np.ndarray) -> np.ndarray:
        """(V,) the true gain of every view of ``viewspace`` after ``view_state`` (0 for visited
        ones): what the oracle ranks by (:func:`score_functions`)."""
        return score_functions(self, score, viewspace)[0](view_state)

    def curves(
        self, viewspace: str, views: list[int], notes: list[str] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Coverage and VIG after each view of ``views`` (in order): two (len(views),) arrays.

        VIG is NaN where it is undefined (a flat ground truth, or one Qhull failed on) and where
        Qhull fails on the union of the visited views; each such failure is added to ``notes``.
        The hull volumes come from the view record's memo
        (:class:`nbv.geometry.union.UnionHulls`).
        """
        view = self.views[viewspace]
        n_gt = len(self.gt_points)
        defined = self.gt_hull_volume > 0
        state = np.zeros(len(view.poses), dtype=bool)
        cov, vig = [], []
        for i, v in enumerate(views):
            state[v] = True
            cov.append(coverage_from_bits(view.coverage, state, n_gt))
            try:
                vig.append(
                    view.unions.volume(views[: i + 1]) / self.gt_hull_volume if defined else np.nan
                )
            except QhullFailure as err:
                vig.append(np.nan)
                if notes is not None:
                    notes.append(f"VIG after {len(vig)} views unknown: {err}")
        return np.array(cov), np.array(vig)


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
