"""Reconstruction episodes: from a start view, a policy picks views one after another.

An episode runs on one model of a dataset and one of its viewspaces. A policy sees what a camera
gives (:class:`~nbv.geometry.views.CapturedViews`: the poses and the captured views' points) and
the view state; only a policy that reads the ground truth (the oracle,
``reads_ground_truth = True``) is also given the model's true gains. After each captured view the
coverage (from the per-view coverage bits, i.e. the full-resolution views) and the VIG (from the
per-view hull vertices) of the views so far are recorded (:meth:`GroundTruth.curves`). The
protocol of PC-NBV's follow-up work:
start views 1, 3, 7, 10, 15, 24, 27, 30, then 9 more views (10 in all), visited views masked.

AUC (PC-NBV's definition) of a 10-view coverage curve: ``(cov_1 + ... + cov_9 + 0.5 cov_10) / 10``.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from nbv.geometry.views import CapturedViews

#: The start views of the evaluation protocol (indices into the original viewspace).
DEFAULT_START_VIEWS = (1, 3, 7, 10, 15, 24, 27, 30)
#: Views in an episode, the start view included.
EPISODE_VIEWS = 10


class GroundTruth(Protocol):
    """A model with its ground truth (a dataset record,
    :class:`nbv.dataset.records.ModelData`): what an episode is played on and scored against."""

    def captured(self, viewspace: str) -> CapturedViews:
        """What a policy sees of the views of ``viewspace``."""
        ...

    def view_gains(self, viewspace: str, score: str, view_state: np.ndarray) -> np.ndarray:
        """(V,) the true gain of every view after ``view_state``."""
        ...

    def curves(
        self, viewspace: str, views: list[int], notes: list[str] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Coverage and VIG after each view of ``views``."""
        ...


@dataclass
class EpisodeState:
    """What a policy may look at when it picks the next view.

    Attributes:
        views: what the camera gave: every candidate's pose and the captured views' points (a
            policy reads the points of the views in ``order`` only).
        view_state: (V,) bool, the views captured so far.
        order: the captured views in order.
        true_gains: ``(score, view_state) -> (V,)`` true gains of the views, given only to a
            policy that reads the ground truth (the oracle); None otherwise.
    """

    views: CapturedViews
    view_state: np.ndarray
    order: list[int]
    true_gains: Callable[[str, np.ndarray], np.ndarray] | None = None

    def cloud(self) -> np.ndarray:
        """(N, 3) float32: the accumulated cloud of the captured views (stored points)."""
        return np.concatenate([self.views.view_points(v) for v in self.order])


class Policy(Protocol):
    """A view-selection method for one episode: state -> the next view (an unvisited index), or
    a list of views to take in order.

    Every policy has these attributes; the evaluator and the planner read them after each
    decision.

    Attributes:
        timings: stage -> seconds of each decision (:func:`record_time`).
        notes: what the policy had to work around (an empty cloud, a flat hull), reported with
            the episode.
        counts: a planner's picks (``planned``) and those of zero predicted gain
            (``zero_gain``); empty for a method that predicts no gain.
        last_gains: a planner's predicted gain of each view of its last decision (what they
            count: its ``gain_unit``); empty for a method that predicts none.
    """

    timings: dict[str, list[float]]
    notes: list[str]
    counts: dict[str, int]
    last_gains: list[float]

    def __call__(self, state: EpisodeState) -> int | list[int]: ...


def stage_seconds(policy: Policy) -> dict[str, float]:
    """Seconds of each of the policy's stages, summed over its decisions so far."""
    return {k: float(np.sum(v)) for k, v in policy.timings.items()}


@dataclass
class Episode:
    """The outcome of one episode.

    Attributes:
        views: the captured views in order (start view first).
        coverage: (len(views),) coverage after each view.
        vig: (len(views),) VIG after each view (NaN when the ground truth has no hull volume).
        times: seconds the policy spent at each decision.
        notes: what scoring the episode had to work around (a Qhull failure: that VIG is NaN).
    """

    views: list[int]
    coverage: np.ndarray
    vig: np.ndarray
    times: list[float] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def auc(self) -> float:
        """AUC of the coverage curve (PC-NBV's definition)."""
        return auc(self.coverage)


def auc(curve: np.ndarray) -> float:
    """PC-NBV's area under a coverage curve: ``(c_1 + ... + c_{n-1} + 0.5 c_n) / n``."""
    curve = np.asarray(curve, dtype=np.float64)
    if curve.ndim != 1 or len(curve) == 0:
        raise ValueError(f"a curve is a non-empty 1-D array, got shape {curve.shape}")
    return float((curve[:-1].sum() + 0.5 * curve[-1]) / len(curve))


def reads_ground_truth(policy: object) -> bool:
    """Whether ``policy`` is given the ground truth (its class says ``reads_ground_truth``)."""
    return bool(getattr(policy, "reads_ground_truth", False))


@dataclass
class RunningEpisode:
    """An episode under way: its model and state, the views a one-shot policy has queued, and
    the seconds of each decision so far (the steps both :func:`run_episode` and
    :func:`nbv.policies.lockstep.run_lockstep` take)."""

    model: GroundTruth
    viewspace: str
    state: EpisodeState
    n_views: int
    queue: list[int] = field(default_factory=list)
    times: list[float] = field(default_factory=list)

    @classmethod
    def start(
        cls,
        model: GroundTruth,
        viewspace: str,
        start: int,
        n_views: int,
        ground_truth: bool = False,
    ) -> RunningEpisode:
        """The episode after its start view; ``n_views`` is capped at the viewspace's size.
        ``ground_truth``: the state carries the model's true gains (for the oracle).

        Raises:
            ValueError: a start view outside the viewspace.
        """
        views = model.captured(viewspace)
        n = len(views.poses)
        if not 0 <= start < n:
            raise ValueError(f"start view {start} is outside 0..{n - 1}")
        true_gains = functools.partial(model.view_gains, viewspace) if ground_truth else None
        state = EpisodeState(views, np.zeros(n, dtype=bool), [int(start)], true_gains)
        state.view_state[start] = True
        return cls(model, viewspace, state, min(n_views, n))

    @property
    def done(self) -> bool:
        """The episode holds its ``n_views`` views."""
        return len(self.state.order) >= self.n_views

    def take(self, choice: int | list[int] | tuple[int, ...], seconds: float) -> None:
        """Queue a decision's view (or a one-shot policy's views) and record its seconds.

        Raises:
            ValueError: the policy returned no view.
        """
        self.times.append(seconds)
        self.queue = [int(v) for v in (choice if isinstance(choice, list | tuple) else [choice])]
        if not self.queue:
            raise ValueError("the policy returned no view")

    def step(self) -> None:
        """Capture the next queued view.

        Raises:
            ValueError: a view visited already or outside the viewspace.
        """
        v = self.queue.pop(0)
        n = len(self.state.view_state)
        if not 0 <= v < n or self.state.view_state[v]:
            raise ValueError(f"the policy chose view {v}, visited or outside 0..{n - 1}")
        self.state.view_state[v] = True
        self.state.order.append(v)

    def episode(self) -> Episode:
        """The finished episode, with its coverage and VIG curves."""
        notes: list[str] = []
        cov, vig = self.model.curves(self.viewspace, self.state.order, notes)
        return Episode(self.state.order, cov, vig, self.times, notes)


def run_episode(
    model: GroundTruth,
    viewspace: str,
    start: int,
    policy: Policy,
    n_views: int = EPISODE_VIEWS,
) -> Episode:
    """Run ``policy`` from ``start`` until ``n_views`` views are captured.

    A policy returns one view, or a list of views (a one-shot planner), which are taken in order
    until the episode is full; a visited or out-of-range view is an error of the policy.
    """
    run = RunningEpisode.start(model, viewspace, start, n_views, reads_ground_truth(policy))
    while not run.done:
        if not run.queue:
            t0 = time.perf_counter()
            choice = policy(run.state)
            run.take(choice, time.perf_counter() - t0)
        run.step()
    return run.episode()


def captured_state(
    poses: np.ndarray,
    parts: list[np.ndarray],
    order: list[int],
    points_per_view: int = 0,
    misses: list | None = None,
) -> EpisodeState:
    """The state a policy reads after the captured views ``order`` of a real scanner, in the
    planners' frame (the object within radius 0.5 of the origin).

    Args:
        poses: (V, 4, 4) camera-to-world of the candidates (and any extra captured views).
        parts: V arrays (N_v, 3) of each view's points; empty for views not captured.
        order: the captured views in order.
        points_per_view: the subsampling the points were kept with (0 = all).
        misses: per view what its missing pixels mean (:attr:`CapturedViews.misses`); None for
            rendered views.

    Returns:
        An :class:`EpisodeState` of the captured views alone: no ground truth.
    """
    views = CapturedViews.of_parts(poses, parts, points_per_view, misses)
    state = EpisodeState(views, np.zeros(len(views.poses), dtype=bool), list(order))
    state.view_state[list(order)] = True
    return state
