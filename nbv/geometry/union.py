"""Convex-hull volumes of unions of a model's views, grown one view at a time and memoised.

An episode's VIG curve asks for the hull volume of its first view, then of its first two, and so
on; the episodes of one model share many of those view sets (every method starts from the same
start views). Because ``hull(A | B) = hull(vertices(hull(A)) | B)``, the hull of a set grown by
one view is computed from its parent's hull vertices and the new view's own: a few hundred points
for Qhull instead of every visited view's vertices. Exact (up to Qhull's rounding, about 1e-15 of
the volume) and equal to :func:`nbv.geometry.scores.vig_of_state` times the ground truth's volume.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from nbv.geometry.clouds import as_cloud
from nbv.geometry.hull import QhullFailure, hull_volume_vertices


class UnionHulls:
    """Hull volumes of unions of views, memoised by the set of views.

    Args:
        view_vertices: ``V`` arrays ``(K_v, 3)``, each view's hull vertices
            (:func:`nbv.geometry.scores.view_hull_vertices`), any float dtype.

    The memo grows with every new set asked for (a volume and its ``(K, 3)`` vertices each); an
    object lives as long as one model's episodes.
    """

    def __init__(self, view_vertices: Sequence[np.ndarray]) -> None:
        self._views = [as_cloud(v, f"view_vertices[{i}]") for i, v in enumerate(view_vertices)]
        self._memo: dict[int, tuple[float, np.ndarray] | QhullFailure] = {
            0: (0.0, np.zeros((0, 3)))
        }

    def __len__(self) -> int:
        """Number of view sets memoised (the empty set included)."""
        return len(self._memo)

    def volume(self, views: Iterable[int]) -> float:
        """Hull volume of the union of ``views`` (indices, any order; repeats ignored), cubed
        cloud units; 0.0 for the empty set or a degenerate union.

        Raises:
            QhullFailure: Qhull failed on the union (every later ask for this set raises too).
            IndexError: a view outside ``0..V-1``.
        """
        members = sorted({int(v) for v in views})
        for v in members:
            if not 0 <= v < len(self._views):
                raise IndexError(f"view {v} is outside 0..{len(self._views) - 1}")
        entry = self._entry(members)
        if isinstance(entry, QhullFailure):
            raise entry
        return entry[0]

    def _entry(self, members: list[int]) -> tuple[float, np.ndarray] | QhullFailure:
        mask = sum(1 << v for v in members)
        entry = self._memo.get(mask)
        if entry is not None:
            return entry
        # A memoised parent (the set less one view) that Qhull did not fail on, else its own
        # parent, recursively: one Qhull run per new set on the path.
        parent = next(
            (v for v in reversed(members) if isinstance(self._memo.get(mask ^ (1 << v)), tuple)),
            members[-1],
        )
        base = self._entry([v for v in members if v != parent])
        if isinstance(base, QhullFailure):  # grow from the views themselves instead
            points = np.concatenate([self._views[v] for v in members])
        else:
            points = np.concatenate([base[1], self._views[parent]])
        try:
            entry = hull_volume_vertices(points)
        except QhullFailure as err:
            entry = err
        self._memo[mask] = entry
        return entry
