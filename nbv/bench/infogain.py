"""Plain numpy references of the volumetric planners, and their benchmark rows.

:func:`numpy_traverse` is Amanatides and Woo's traversal vectorised over the segments with numpy
(one numpy step for all segments per voxel crossed), :func:`numpy_ray_gains` the gain metrics and
:func:`numpy_ray_features` ``ig_learned``'s per-ray features on whole ``(R, S)`` arrays, and
:func:`plain_decision` one information-gain decision built from them (``scorer``: an
``ig_learned`` decision), timed against the policies themselves (:func:`decision`): the fair
references of :mod:`nbv.infogain.raytrace`,
:func:`nbv.infogain.gain.ray_gains`, :func:`nbv.infogain.view_features.ray_features`,
:class:`nbv.policies.infogain.InfoGainPolicy` and
:class:`nbv.policies.learned_gain.LearnedGainPolicy`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nbv.bench.timing import best_time
from nbv.geometry.camera import Intrinsics
from nbv.infogain.gain import candidate_segments, frontier
from nbv.infogain.gain_scorer import GainScorer
from nbv.infogain.occupancy import OccupancyMap, background_directions, log_odds_of
from nbv.infogain.raytrace import clip_to_box, drop_end_voxels, flat_index
from nbv.infogain.settings import InfoGainSettings
from nbv.policies.episode import captured_state
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.learned_gain import LearnedGainPolicy


def numpy_traverse(
    origins: np.ndarray, ends: np.ndarray, n: int, bound: float, include_end: bool = True
) -> np.ndarray:
    """:func:`nbv.infogain.raytrace.traverse` in numpy: the same (R, S) voxels, -1 padded."""
    origins, ends = np.asarray(origins, float), np.asarray(ends, float)
    scale = n / (2.0 * bound)
    start, delta = (origins + bound) * scale, (ends - origins) * scale
    t_in, t_out = clip_to_box(start, delta, n)
    out = np.full((len(origins), 3 * n + 1), -1, dtype=np.int64)
    rays = np.flatnonzero(t_in < t_out)
    p = start[rays] + t_in[rays, None] * delta[rays]
    d = delta[rays]
    cell = np.clip(np.floor(p), 0, n - 1).astype(np.int64)
    step = np.where(d > 0, 1, -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_delta = np.where(d != 0, 1.0 / np.abs(d), np.inf)
        t_max = np.where(d != 0, t_in[rays, None] + (cell + (d > 0) - p) / d, np.inf)
    active = np.arange(len(rays))
    for k in range(3 * n + 1):
        out[rays[active], k] = flat_index(cell[active], n)
        tm = t_max[active]
        axis = np.argmin(tm, axis=1)
        keep = tm[np.arange(len(active)), axis] < t_out[rays[active]]
        active, axis = active[keep], axis[keep]
        if len(active) == 0:
            break
        cell[active, axis] += step[active, axis]
        t_max[active, axis] += t_delta[active, axis]
        active = active[((cell[active] >= 0) & (cell[active] < n)).all(axis=1)]
    counts = (out >= 0).sum(axis=1)
    if not include_end:
        drop_end_voxels(out, counts, start + delta, t_out, n)
    return out[:, : max(int(counts.max(initial=0)), 1)]


class _Rays(NamedTuple):
    """Rays read from the map, (R, S) per voxel position."""

    valid: np.ndarray  # a voxel, not padding
    index: np.ndarray  # the voxel (0 for padding)
    value: np.ndarray  # its log-odds (NaN: unknown)
    unknown: np.ndarray
    occupied: np.ndarray
    before: np.ndarray  # before the ray's first occupied voxel

    def rear(self) -> np.ndarray:
        """(R,) bool: the voxel before the ray's first occupied one is unknown."""
        first = np.argmax(self.occupied, axis=1)
        rear = self.occupied.any(axis=1) & (first > 0)
        return rear & self.unknown[np.arange(len(first)), np.maximum(first - 1, 0)]


def _read_rays(log_odds: np.ndarray, voxels: np.ndarray) -> _Rays:
    """The map's state along ``(R, S)`` voxel rows padded with -1."""
    valid = voxels >= 0
    index = np.where(valid, voxels, 0)
    value = log_odds[index]
    unknown = np.isnan(value) & valid
    occupied = (value >= 0) & valid
    before = valid & ~(np.cumsum(occupied, axis=1) > 0)
    return _Rays(valid, index, value, unknown, occupied, before)


def numpy_ray_gains(
    log_odds: np.ndarray,
    voxels: np.ndarray,
    metric: str,
    frontier_mask: np.ndarray | None = None,
    depth: int = 0,
) -> np.ndarray:
    """:func:`nbv.infogain.gain.ray_gains` on whole arrays: (R,) gains
    (``frontier_mask``: the (n^3,) bool frontier the ``frontier`` metric counts; ``depth``: the
    cap of a ray's count, 0 for none).

    Raises:
        ValueError: a metric the reference does not implement (``area_factor`` and
            ``proximity_count`` score a whole view, not rays alone).
    """
    implemented = ("unobserved", "frontier", "entropy", "rear_side_voxel", "rear_side_entropy")
    if metric not in implemented:
        raise ValueError(f"metric={metric!r}: the reference implements {', '.join(implemented)}")
    rays = _read_rays(log_odds, voxels)
    valid, index, value, unknown, _, before = rays
    if metric in ("unobserved", "frontier"):
        counted = unknown & before & (frontier_mask[index] if metric == "frontier" else True)
        count = counted.sum(axis=1).astype(float)
        return np.minimum(count, depth) if depth > 0 else count
    p = np.where(valid, 1 / (1 + np.exp(-np.nan_to_num(value, nan=0.0))), 0.0)
    q = np.clip(p, 1e-12, 1 - 1e-12)
    h = -(q * np.log2(q) + (1 - q) * np.log2(1 - q))
    visibility = np.concatenate([np.ones((len(p), 1)), np.cumprod(1 - p, axis=1)[:, :-1]], axis=1)
    weighted = np.where(valid, visibility * h, 0.0)
    if metric == "entropy":
        return weighted.sum(axis=1)
    rear = rays.rear()
    if metric == "rear_side_voxel":
        return rear.astype(float)
    return np.where(rear, np.where(unknown & before, weighted, 0.0).sum(axis=1), 0.0)


def numpy_ray_features(
    log_odds: np.ndarray, voxels: np.ndarray, frontier_mask: np.ndarray, n: int
) -> np.ndarray:
    """:func:`nbv.infogain.view_features.ray_features` on whole arrays: (R, 8)."""
    rays = _read_rays(log_odds, voxels)
    valid, index, _, unknown, occupied, before = rays
    rear = rays.rear()
    seen = unknown & before
    count = seen.sum(axis=1).astype(float)
    meets = occupied.any(axis=1)
    near = (seen & frontier_mask[index]).sum(axis=1)
    first_unknown = np.where(seen.any(axis=1), np.argmax(seen, axis=1), 0)
    free = valid & ~unknown & ~occupied & (np.arange(voxels.shape[1]) < first_unknown[:, None])
    run = np.where(count > 0, free.sum(axis=1) / n, 0.0)
    return np.stack([count, count > 0, meets, rear, near, np.minimum(count, 4),
                     (count > 0) & ~meets, run], axis=1).astype(float)  # fmt: skip


def _plain_insert(occupancy: OccupancyMap, origin, hits, misses) -> None:
    s = occupancy.settings
    far = occupancy.miss_ends(origin, misses)
    crossed = np.concatenate([
        numpy_traverse(np.broadcast_to(origin, hits.shape), hits, s.n, s.bound, False).ravel(),
        numpy_traverse(np.broadcast_to(origin, far.shape), far, s.n, s.bound).ravel(),
    ])  # fmt: skip
    occupied = np.unique(occupancy.voxel_of(hits))
    occupied = occupied[occupied >= 0]
    free = np.setdiff1d(crossed[crossed >= 0], occupied)
    for voxels, delta in ((free, log_odds_of(s.p_miss)), (occupied, log_odds_of(s.p_hit))):
        current = np.nan_to_num(occupancy.log_odds[voxels], nan=0.0)
        occupancy.log_odds[voxels] = np.clip(
            current + delta, log_odds_of(s.clamp_min), log_odds_of(s.clamp_max)
        )


def plain_decision(
    views, poses, intrinsics: Intrinsics, settings: InfoGainSettings,
    scorer: GainScorer | None = None,
) -> int:  # fmt: skip
    """One information-gain decision in plain numpy: map the captured ``views`` (a list of
    ``(view index, (N, 3) points)``), score every other view of ``poses``, return the best;
    with ``scorer``, ``ig_learned``'s decision."""
    occupancy = OccupancyMap(settings.occupancy())
    for v, points in views:
        misses = background_directions(points, poses[v], intrinsics, settings.block)
        _plain_insert(occupancy, poses[v][:3, 3], points, misses)
    captured = {v for v, _ in views}
    open_ = [v for v in range(len(poses)) if v not in captured]
    s = occupancy.settings
    origins, ends = candidate_segments(poses[open_], intrinsics, settings.columns, s)
    voxels = numpy_traverse(origins, ends, s.n, s.bound)
    if scorer is not None:
        rays = numpy_ray_features(occupancy.log_odds, voxels, frontier(occupancy), s.n)
        sums = rays.reshape(len(open_), -1, rays.shape[1]).sum(axis=1)
        top = sums.max(axis=0)
        relative = np.divide(sums, top, out=np.zeros_like(sums), where=top > 0)
        unit = poses[:, :3, 3] / np.linalg.norm(poses[:, :3, 3], axis=1, keepdims=True)
        order = [v for v, _ in views]
        angles = np.degrees(np.arccos(np.clip(unit[open_] @ unit[order].T, -1, 1))) / 180
        features = np.c_[relative, angles.min(axis=1), angles[:, -1], angles[:, 0],
                         np.full(len(open_), len(order) / 10)]  # fmt: skip
        return open_[int(np.argmax(scorer.scores(features)))]
    gains = numpy_ray_gains(occupancy.log_odds, voxels, settings.metric, frontier(occupancy))
    return open_[int(np.argmax(gains.reshape(len(open_), -1).sum(axis=1)))]


def decision(
    views, poses, intrinsics: Intrinsics, settings: InfoGainSettings,
    scorer: GainScorer | None = None,
) -> int:  # fmt: skip
    """The same decision as :func:`plain_decision` made by the policy itself: a fresh
    :class:`~nbv.policies.infogain.InfoGainPolicy` (``scorer``: a
    :class:`~nbv.policies.learned_gain.LearnedGainPolicy`) called once on the captured state
    (:func:`nbv.policies.episode.captured_state`, whose record holds the points as float32), as
    it makes its first decision on a viewspace: the map built, the candidates' voxels traced."""
    parts = [np.zeros((0, 3), np.float32)] * len(poses)
    for v, points in views:
        parts[v] = points
    state = captured_state(poses, parts, [v for v, _ in views])
    if scorer is not None:
        return LearnedGainPolicy(settings, intrinsics, scorer=scorer)(state)
    return InfoGainPolicy(settings, intrinsics)(state)


def decision_row(
    stored: list[np.ndarray], poses: np.ndarray, intrinsics: Intrinsics,
    scorer: GainScorer | None = None,
) -> dict:  # fmt: skip
    """The benchmark row of one information-gain decision (``scorer``: an ``ig_learned`` one)
    after two captured views (1 and 9) at the default settings: seconds of ours and of the plain
    reference, the same inputs, the same number of runs each."""
    settings = InfoGainSettings()
    # float32, as a record holds them and the policy reads them: both sides get the same points.
    views = [(v, stored[v].astype(np.float32)) for v in (1, 9)]
    ours = best_time(lambda: decision(views, poses, intrinsics, settings, scorer), repeat=3,
                     budget=10)  # fmt: skip
    plain = best_time(lambda: plain_decision(views, poses, intrinsics, settings, scorer),
                      repeat=3, budget=10)  # fmt: skip
    what = "ig_learned decision" if scorer is not None else "information-gain decision"
    return dict(
        name=f"{what}, 2 captured views, 2 cm voxels",
        ours=ours,
        reference=plain,
        ratio=plain / ours,
        target=0.050,
        note="compiled traversal and "
        + ("features" if scorer is not None else "gains")
        + " vs numpy",
    )
