"""Wall-clock timing of a benchmark row."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np


def best_time(fn: Callable[[], object], repeat: int = 5, budget: float = 3.0) -> float:
    """Best wall time of ``fn`` in seconds over up to ``repeat`` runs (stops after ``budget`` s)."""
    best, spent = np.inf, 0.0
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        dt = time.perf_counter() - t0
        best, spent = min(best, dt), spent + dt
        if spent > budget:
            break
    return best
