"""Planners with a shape prior: the captured cloud completed, then planned on.

A *completion* is any function from the captured cloud ((N, 3), the planners' frame: the object
within radius 0.5 of the origin) to points on the whole surface ((M, 3)): the trained network
(:class:`nbv.models.completion_inference.Completer`), or in the tests the true surface itself.

- :class:`CompletionGainPolicy` (``completion_gain``): the view contribution of a completion,
  completed again after every view. The default rule (``visibility``) sees the whole completed
  cloud from each camera with a z-buffer of its points
  (:func:`nbv.geometry.point_visibility.visible_points`), so that the seen surface occludes what
  lies behind it, and counts the predicted points a candidate sees that no captured view sees:
  the drop of what is already seen is by visibility from the captured cameras, so it does not
  depend on how densely the captured views were sampled. The ``authors`` rule is [15]'s as the
  seed paper's authors ran it (FACTS.md): drop the predicted points within ``eps`` of a captured
  point, then count each candidate's visible ones by hidden-point removal on what is left.
- :class:`CompletionHullPolicy` (``completion_hull_sco``): the paper's "convex hull of the
  predicted point cloud": the one-shot set cover of :class:`~nbv.policies.setcover.SetCoverPolicy`
  planned on the hull of the captured cloud and its completion;
  :class:`CompletionHullReplanPolicy` plans again after every view.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from nbv.geometry.camera import Intrinsics
from nbv.geometry.clouds import near
from nbv.geometry.point_visibility import SplatSettings, cloud_spacing, visible_points
from nbv.geometry.scores import DEFAULT_EPS
from nbv.geometry.viewspace import angular_distances, unit_directions
from nbv.policies.episode import EpisodeState
from nbv.policies.inputs import cloud_or_origin, record_time
from nbv.policies.setcover import SetCoverPolicy

#: A completion: (N, 3) captured points -> (M, 3) points on the whole surface.
Completion = Callable[[np.ndarray], np.ndarray]
#: The view-contribution rules of :class:`CompletionGainPolicy`.
RULES = ("visibility", "authors")
#: The captured points kept as occluders, per predicted point (a stride through the captured
#: cloud: the z-buffer's cells are sized by the predicted points, so more add nothing).
OCCLUDERS_PER_POINT = 2
#: Hidden-point removal's radius, in diameters of the cloud (the authors' setting).
HPR_RADIUS = 100.0
#: The note of a decision whose captured views saw nothing.
NOTHING_SEEN = "the views saw nothing: completed from the origin alone"


def predict(complete: Completion, captured: np.ndarray, notes: list[str]) -> np.ndarray:
    """(M, 3) float64 the completion of ``captured`` (N, 3); of the origin alone (and a note)
    when the captured views saw nothing."""
    if len(captured) == 0:
        notes.append(NOTHING_SEEN)
    return np.asarray(complete(cloud_or_origin(captured)), dtype=np.float64)


def occluders(cloud: np.ndarray, n_predicted: int) -> np.ndarray:
    """Every ``k``-th point of the captured ``cloud`` (N, 3), at most ``OCCLUDERS_PER_POINT *
    n_predicted`` of them (deterministic)."""
    step = max(1, -(-len(cloud) // max(OCCLUDERS_PER_POINT * n_predicted, 1)))
    return cloud[::step]


def visibility_gains(
    predicted: np.ndarray,
    captured: np.ndarray,
    poses: np.ndarray,
    visited: np.ndarray,
    intrinsics: Intrinsics,
    splat: SplatSettings,
    eps: float = DEFAULT_EPS,
) -> np.ndarray:
    """(V,) the predicted points each camera sees that are not seen yet: seen from no visited
    camera, and farther than ``eps`` from every captured point.

    Args:
        predicted: (M, 3) the completion.
        captured: (N, 3) captured points (occluders only; a stride of them is kept).
        poses: (V, 4, 4) camera-to-world of the candidates, the visited ones among them.
        visited: (V,) bool.
        intrinsics: the camera.
        splat: the z-buffer's sizes, in units of the predicted points' spacing.
        eps: the coverage distance.

    Returns:
        (V,) int64 counts (a visited camera's count is 0).
    """
    spacing = max(cloud_spacing(predicted), 1e-6)
    points = np.concatenate([predicted, occluders(captured, len(predicted))])
    sizes = (splat.cell * spacing, splat.tolerance * spacing, splat.hole * spacing)
    seen = visible_points(points, poses, intrinsics, *sizes)[:, : len(predicted)]
    already = seen[visited].any(axis=0) | near(captured, predicted, eps)
    return (seen & ~already).sum(axis=1)


def authors_gains(
    predicted: np.ndarray, captured: np.ndarray, positions: np.ndarray, eps: float
) -> np.ndarray:
    """(V,) [15]'s view contribution as the seed paper's authors ran it (FACTS.md): the
    predicted points at distance >= ``eps`` from every captured point, each camera's count of
    them visible by Open3D's hidden-point removal (radius ``HPR_RADIUS`` diameters).

    Args:
        predicted: (M, 3) the completion.
        captured: (N, 3) captured points.
        positions: (V, 3) camera centres.
        eps: the drop distance (the coverage distance).
    """
    import open3d as o3d  # heavy: only this rule needs it

    new = np.asarray(predicted, dtype=np.float64)
    if len(captured):  # the authors keep the points at distance >= eps
        new = new[cKDTree(captured).query(new)[0] >= eps]
    gains = np.zeros(len(positions), dtype=np.int64)
    if len(new) < 4:  # hidden-point removal's hull needs four points
        return gains
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(new))
    diameter = float(np.linalg.norm(new.max(0) - new.min(0)))
    for v, eye in enumerate(np.asarray(positions, dtype=np.float64)):
        try:
            _, index = pcd.hidden_point_removal(eye, HPR_RADIUS * max(diameter, 1e-6))
        except RuntimeError:  # Qhull on a degenerate set: it sees nothing
            continue
        gains[v] = len(index)
    return gains


def spread_tie_break(scores: np.ndarray, state: EpisodeState) -> int:
    """The unvisited view of the highest score; among views tied for it (all of them once the
    completion has nothing left to see), the one farthest in angle from the visited views, as
    ``spread`` picks (then the lowest index)."""
    best = np.max(scores[~state.view_state])
    tied = np.flatnonzero((scores == best) & ~state.view_state)
    if len(tied) == 1:
        return int(tied[0])
    d = unit_directions(state.views.poses[:, :3, 3])
    far = angular_distances(d[tied], d[state.view_state]).min(axis=1)
    return int(tied[int(np.argmax(far))])


@dataclass
class CompletionGainPolicy:
    """The unvisited view whose camera sees the most predicted points not yet seen (ties, and
    every view once none sees anything new, broken by :func:`spread_tie_break`); see the module
    docstring.

    Attributes:
        complete: the completion.
        intrinsics: the camera.
        rule: ``visibility`` (the default) or ``authors`` (:data:`RULES`).
        splat: the z-buffer's sizes (``visibility``).
        eps: the coverage distance: a predicted point this near a captured one is seen (both
            rules).
    """

    complete: Completion
    intrinsics: Intrinsics = field(default_factory=Intrinsics)
    rule: str = "visibility"
    splat: SplatSettings = field(default_factory=SplatSettings)
    eps: float = DEFAULT_EPS
    timings: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=lambda: {"planned": 0, "zero_gain": 0})
    last_gains: list[float] = field(default_factory=list)
    gain_unit: str = "predicted points newly seen"

    def __post_init__(self) -> None:
        if self.rule not in RULES:
            raise ValueError(f"completion_gain rule={self.rule!r}; allowed: {', '.join(RULES)}")

    def view_scores(self, state: EpisodeState) -> np.ndarray:
        """(V,) each view's count of predicted points newly seen (-inf for visited views)."""
        t0 = time.perf_counter()
        captured = state.cloud().astype(np.float64)
        predicted = predict(self.complete, captured, self.notes)
        t1 = time.perf_counter()
        poses = state.views.poses
        if self.rule == "visibility":
            gains = visibility_gains(
                predicted, captured, poses, state.view_state, self.intrinsics, self.splat, self.eps
            ).astype(np.float64)
        else:
            gains = authors_gains(predicted, captured, poses[:, :3, 3], self.eps).astype(float)
        gains[state.view_state] = -np.inf
        record_time(self.timings, "completion", t1 - t0)
        record_time(self.timings, "gains", time.perf_counter() - t1)
        return gains

    def __call__(self, state: EpisodeState) -> int:
        scores = self.view_scores(state)
        choice = spread_tie_break(scores, state)
        self.last_gains = [float(scores[choice])]
        self.counts["planned"] += 1
        self.counts["zero_gain"] += int(scores[choice] <= 0)
        return choice


@dataclass
class CompletionHullPolicy(SetCoverPolicy):
    """:class:`SetCoverPolicy` planned once, from the start view, on the hull of the captured
    cloud and its completion (``probes`` is not used)."""

    complete: Completion | None = field(default=None, kw_only=True)

    def completed(self, cloud: np.ndarray) -> np.ndarray:
        """(N + M, 3) the captured cloud and its completion."""
        if self.complete is None:
            raise ValueError("CompletionHullPolicy needs a completion (complete=...)")
        t0 = time.perf_counter()
        predicted = predict(self.complete, np.asarray(cloud, dtype=np.float64), self.notes)
        cloud = np.asarray(cloud_or_origin(cloud), dtype=np.float64)
        record_time(self.timings, "completion", time.perf_counter() - t0)
        return np.concatenate([cloud, predicted])

    def __call__(self, state: EpisodeState) -> list[int]:
        return self.plan_rest(state, self.completed(state.cloud()))


@dataclass
class CompletionHullReplanPolicy(CompletionHullPolicy):
    """:class:`CompletionHullPolicy` planned again after every view on the whole captured
    cloud's completion; the first view of each plan is taken."""

    def __call__(self, state: EpisodeState) -> int:  # type: ignore[override]
        cloud = self.completed(state.cloud())
        return self.plan_from(cloud, state.views.poses, list(state.order), 1)[0]
