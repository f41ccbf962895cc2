"""Means with bootstrap confidence intervals, for paired differences over episodes.

Episodes of one model are not independent (its start views share the shape), so the default
resampling unit is a *cluster* (a model): each bootstrap draw takes as many clusters as there are,
with replacement, and averages all their episodes. With one episode per cluster this is the
ordinary bootstrap. Percentile intervals, seeded: the same numbers and seed give the same interval.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Bootstrap draws and confidence level used when a caller does not say.
N_BOOT = 10_000
LEVEL = 0.95


@dataclass(frozen=True)
class Interval:
    """A mean and its bootstrap confidence interval.

    Attributes:
        mean: the sample mean.
        low, high: the interval's ends (NaN with fewer than two clusters).
        n: the number of values; clusters: the number of resampled units.
    """

    mean: float
    low: float
    high: float
    n: int
    clusters: int

    @property
    def above_zero(self) -> bool:
        """The whole interval lies above 0."""
        return bool(self.low > 0)

    @property
    def below_zero(self) -> bool:
        """The whole interval lies below 0."""
        return bool(self.high < 0)

    def within(self, bound: float) -> bool:
        """The whole interval lies inside ``[-bound, bound]``."""
        return bool(-bound <= self.low and self.high <= bound)

    def text(self, digits: int = 3, signed: bool = True) -> str:
        """``+0.012 [+0.004, +0.020]``."""
        f = f"{{:{'+' if signed else ''}.{digits}f}}"
        if not np.isfinite(self.low):
            return f.format(self.mean) + " [n/a]"
        return f"{f.format(self.mean)} [{f.format(self.low)}, {f.format(self.high)}]"

    def to_json(self) -> dict:
        return {"mean": self.mean, "low": self.low, "high": self.high, "n": self.n,
                "clusters": self.clusters}  # fmt: skip


def bootstrap_mean(
    values,
    clusters=None,
    seed: int = 0,
    n_boot: int = N_BOOT,
    level: float = LEVEL,
) -> Interval:
    """The mean of ``values`` with a percentile bootstrap interval.

    Args:
        values: ``(E,)`` numbers (for a paired comparison, the per-episode differences).
        clusters: ``(E,)`` labels of the resampling units (e.g. model keys); None = every value
            its own unit.
        seed: the generator's seed.
        n_boot: bootstrap draws.
        level: the interval's coverage (0.95 for a 95 % interval).

    Returns:
        :class:`Interval`; NaN ends with fewer than two clusters.

    Raises:
        ValueError: no values, non-finite values, or labels of another length.
    """
    x = np.asarray(values, dtype=float).ravel()
    if x.size == 0:
        raise ValueError("bootstrap_mean: no values")
    if not np.isfinite(x).all():
        raise ValueError("bootstrap_mean: the values hold NaN or infinity")
    if clusters is None:
        label = np.arange(x.size)
    else:
        labels = np.asarray(clusters)
        if labels.shape != x.shape:
            raise ValueError(f"bootstrap_mean: {labels.size} cluster labels for {x.size} values")
        _, label = np.unique(labels, return_inverse=True)
    sums = np.bincount(label, weights=x)
    counts = np.bincount(label).astype(float)
    k = sums.size
    mean = float(x.mean())
    if k < 2:
        return Interval(mean, float("nan"), float("nan"), int(x.size), int(k))
    rng = np.random.default_rng(seed)
    draws = np.empty(n_boot)
    # In blocks, so that memory stays at a few MB for any number of clusters.
    block = max(1, 2_000_000 // k)
    for i in range(0, n_boot, block):
        pick = rng.integers(0, k, size=(min(block, n_boot - i), k))
        draws[i : i + len(pick)] = sums[pick].sum(axis=1) / counts[pick].sum(axis=1)
    tail = (1.0 - level) / 2.0
    low, high = np.quantile(draws, [tail, 1.0 - tail])
    return Interval(mean, float(low), float(high), int(x.size), int(k))
