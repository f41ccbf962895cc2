"""Exact symmetry augmentation of training batches (:mod:`nbv.geometry.symmetry`).

Each training sample in a batch is replaced by its image under one of the viewspace's
symmetries, drawn uniformly (the identity included) from the epoch's generator: the cloud is
mapped by the symmetry's matrix (a signature through :func:`nbv.geometry.symmetry.signature_map`,
exactly), and the view state and the per-view targets are permuted. The mapped sample is the one
the dataset would hold for the mapped object, so no label is made up.
"""

from __future__ import annotations

import numpy as np

from nbv.geometry.symmetry import (
    Symmetry,
    map_signature,
    permute_views,
    signature_map,
    viewspace_symmetries,
)


class Augmentation:
    """The symmetries of one viewspace, ready to map batches.

    Args:
        positions: (V, 3) camera positions of the samples' viewspace.
        lmax: degree of the samples' signatures.
    """

    def __init__(self, positions: np.ndarray, lmax: int) -> None:
        self.symmetries: list[Symmetry] = viewspace_symmetries(positions)
        self.lmax = lmax
        self._radii = [signature_map(s.matrix, lmax) for s in self.symmetries]

    def __len__(self) -> int:
        return len(self.symmetries)

    def apply(
        self,
        points: np.ndarray,
        view_state: np.ndarray,
        target: np.ndarray,
        rng: np.random.Generator,
        signature: bool = False,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Map each sample by a random symmetry.

        Args:
            points: (B, N, 3) clouds, or (B, G, 3) signatures when ``signature``.
            view_state: (B, V) visited views.
            target: (B, V) per-view gains.
            rng: draws one symmetry per sample.
            signature: ``points`` holds signatures.

        Returns:
            New ``(points, view_state, target)`` arrays of the same shapes and dtypes.
        """
        choice = rng.integers(len(self.symmetries), size=len(points))
        points, view_state, target = points.copy(), view_state.copy(), target.copy()
        for k in np.unique(choice):
            rows = np.flatnonzero(choice == k)
            sym = self.symmetries[k]
            if sym.is_identity:
                continue
            if signature:
                points[rows] = map_signature(points[rows], self._radii[k], self.lmax)
            else:
                points[rows] = points[rows] @ sym.matrix.T.astype(points.dtype)
            view_state[rows] = permute_views(view_state[rows], sym)
            target[rows] = permute_views(target[rows], sym)
        return points, view_state, target
