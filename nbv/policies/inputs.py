"""What a policy computes from the captured views: the cloud and its signature, with the
seconds each stage took."""

from __future__ import annotations

import numpy as np

from nbv.geometry.sph import n_coeffs, signature


def record_time(timings: dict[str, list[float]], key: str, seconds: float) -> None:
    """Add one decision's ``seconds`` of stage ``key`` to a policy's ``timings``."""
    timings.setdefault(key, []).append(seconds)


def cloud_or_origin(cloud: np.ndarray) -> np.ndarray:
    """The cloud, or the origin as its only point when the views saw nothing (an empty view of
    a flat object seen edge-on): every downstream step needs at least one point."""
    return cloud if len(cloud) else np.zeros((1, 3), dtype=np.float32)


NO_SPREAD = "every point at one place (the views saw nothing): no signature"


def has_spread(cloud: np.ndarray) -> bool:
    """A radius function needs a point away from the centroid: two points that differ."""
    # One contiguous pass; np.ptp along the point axis reads it strided, 30x slower (0.75 ms
    # on a 16k-point cloud, a third of PCNBV-sph's signature step).
    return bool(len(cloud)) and bool((cloud != cloud[0]).any())


def safe_signature(cloud: np.ndarray, lmax: int, notes: list[str]) -> np.ndarray:
    """The spherical signature, or all zeros (every radius 0) for a cloud without spread."""
    if has_spread(cloud):
        return signature(cloud, lmax)
    notes.append(NO_SPREAD + "; zeros used")
    return np.zeros((4 * n_coeffs(lmax), 3), dtype=np.float32)
