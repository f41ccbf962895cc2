"""What a camera gives a view-selection policy: :class:`CapturedViews`, the candidate views'
poses and the captured views' points, without any ground truth.

A dataset record makes one of its views (:meth:`nbv.dataset.records.ViewData.captured`); a
real scan makes one of its captures (:meth:`CapturedViews.of_parts`). Policies read only these;
the ground truth goes to the oracle and the evaluator alone (:mod:`nbv.policies.episode`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


def offsets_of(arrays: list[np.ndarray]) -> np.ndarray:
    """(len + 1,) int64 start offsets of arrays stored one after the other."""
    return np.concatenate([[0], np.cumsum([len(a) for a in arrays])]).astype(np.int64)


@dataclass(frozen=True)
class CapturedViews:
    """The views of one viewspace as a camera gives them.

    Attributes:
        poses: (V, 4, 4) float64 camera-to-world of every candidate view.
        points: (sum N_v, 3) float32 world points, view after view (a policy reads those of the
            captured views only).
        offsets: (V + 1,) int64; view v is ``points[offsets[v]:offsets[v + 1]]``.
        points_per_view: the subsampling the points were kept with (0 = all).
        misses: None for rendered views (a pixel without a return is free space, as the
            dataset renders); else per view what its rays that return nothing mean, a
            :class:`~nbv.infogain.occupancy.Misses` or None (unknown: a sensor's), the views
            not listed None.
    """

    poses: np.ndarray
    points: np.ndarray
    offsets: np.ndarray
    points_per_view: int = 0
    misses: tuple[Any, ...] | None = None

    @classmethod
    def of_parts(
        cls,
        poses: np.ndarray,
        parts: list[np.ndarray],
        points_per_view: int = 0,
        misses: list | None = None,
    ) -> CapturedViews:
        """Views from their poses (V, 4, 4) and each one's points (N_v, 3) (empty for the
        views not captured)."""
        return cls(
            np.asarray(poses, dtype=np.float64), np.concatenate(parts).astype(np.float32),
            offsets_of(parts), points_per_view, None if misses is None else tuple(misses),
        )  # fmt: skip

    def view_points(self, v: int) -> np.ndarray:
        """(N_v, 3) float32 points of view ``v``."""
        return self.points[self.offsets[v] : self.offsets[v + 1]]

    @property
    def sensed(self) -> bool:
        """Whether the views are a sensor's (``misses`` declared), not rendered ones."""
        return self.misses is not None

    def misses_of(self, v: int) -> Any:
        """What view ``v``'s missing pixels mean (None: unknown, or rendered views)."""
        if self.misses is None or v >= len(self.misses):
            return None
        return self.misses[v]
