"""Picking the best unvisited view: argmax over the views a mask leaves free."""

from __future__ import annotations

import numpy as np


def masked_argmax(values: np.ndarray, visited: np.ndarray) -> np.ndarray | int:
    """Index of the largest value among the unvisited entries, ties to the lowest index.

    Args:
        values: ``(V,)`` or ``(B, V)`` scores of every view.
        visited: bool of the same shape; True entries are never chosen.

    Returns:
        An int for ``(V,)`` input, else ``(B,)`` int64. A row with every view visited gives 0
        (the argmax of all ``-inf``); callers that may see one check it themselves.
    """
    values = np.asarray(values)
    picked = np.argmax(np.where(visited, -np.inf, values), axis=-1)
    return int(picked) if values.ndim == 1 else picked
