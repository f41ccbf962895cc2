"""Reconstruction episodes: from a start view, a policy picks views one after another.

An episode runs on one model of a dataset and one of its viewspaces. After each captured view the
coverage (from the per-view coverage bits, i.e. the full-resolution views) and the VIG (from the
per-view hull vertices) of the views so far are recorded. The protocol of PC-NBV's follow-up work:
start views 1, 3, 7, 10, 15, 24, 27, 30, then 9 more views (10 in all), visited views masked.

AUC (PC-NBV's definition) of a 10-view coverage curve: ``(cov_1 + ... + cov_9 + 0.5 cov_10) / 10``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from nbv.dataset.records import ModelData, ViewData, offsets_of
from nbv.geometry.hull import QhullFailure
from nbv.geometry.scores import coverage_from_bits

#: The start views of the evaluation protocol (indices into the original viewspace).
DEFAULT_START_VIEWS = (1, 3, 7, 10, 15, 24, 27, 30)
#: Views in an episode, the start view included.
EPISODE_VIEWS = 10


@dataclass
class EpisodeState:
    """What a policy may look at when it picks the next view.

    Attributes:
        model: the model's dataset record (a policy other than the oracle should read only the
            captured views' points).
        viewspace: name of the viewspace in ``model.views``.
        view_state: (V,) bool, the views captured so far.
        order: the captured views in order.
    """

    model: ModelData
    viewspace: str
    view_state: np.ndarray
    order: list[int]

    def cloud(self) -> np.ndarray:
        """(N, 3) float32: the accumulated cloud of the captured views (stored points)."""
        view = self.model.views[self.viewspace]
        return np.concatenate([view.view_points(v) for v in self.order])


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


def curves(
    model: ModelData, viewspace: str, views: list[int], notes: list[str] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Coverage and VIG after each view of ``views`` (in order): two (len(views),) arrays.

    VIG is NaN where it is undefined (a flat ground truth, or one Qhull failed on) and where
    Qhull fails on the union of the visited views; each such failure is added to ``notes``.
    The hull volumes come from the view record's memo (:class:`nbv.geometry.union.UnionHulls`).
    """
    view = model.views[viewspace]
    n_gt = len(model.gt_points)
    defined = model.gt_hull_volume > 0
    state = np.zeros(len(view.poses), dtype=bool)
    cov, vig = [], []
    for i, v in enumerate(views):
        state[v] = True
        cov.append(coverage_from_bits(view.coverage, state, n_gt))
        try:
            vig.append(
                view.unions.volume(views[: i + 1]) / model.gt_hull_volume if defined else np.nan
            )
        except QhullFailure as err:
            vig.append(np.nan)
            if notes is not None:
                notes.append(f"VIG after {len(vig)} views unknown: {err}")
    return np.array(cov), np.array(vig)


@dataclass
class RunningEpisode:
    """An episode under way: its state, the views a one-shot policy has queued, and the seconds
    of each decision so far (the steps both :func:`run_episode` and
    :func:`nbv.policies.lockstep.run_lockstep` take)."""

    state: EpisodeState
    n_views: int
    queue: list[int] = field(default_factory=list)
    times: list[float] = field(default_factory=list)

    @classmethod
    def start(cls, model: ModelData, viewspace: str, start: int, n_views: int) -> RunningEpisode:
        """The episode after its start view; ``n_views`` is capped at the viewspace's size.

        Raises:
            ValueError: a start view outside the viewspace.
        """
        n = len(model.views[viewspace].poses)
        if not 0 <= start < n:
            raise ValueError(f"start view {start} is outside 0..{n - 1}")
        state = EpisodeState(model, viewspace, np.zeros(n, dtype=bool), [int(start)])
        state.view_state[start] = True
        return cls(state, min(n_views, n))

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
        cov, vig = curves(self.state.model, self.state.viewspace, self.state.order, notes)
        return Episode(self.state.order, cov, vig, self.times, notes)


def run_episode(
    model: ModelData,
    viewspace: str,
    start: int,
    policy: Policy,
    n_views: int = EPISODE_VIEWS,
) -> Episode:
    """Run ``policy`` from ``start`` until ``n_views`` views are captured.

    A policy returns one view, or a list of views (a one-shot planner), which are taken in order
    until the episode is full; a visited or out-of-range view is an error of the policy.
    """
    run = RunningEpisode.start(model, viewspace, start, n_views)
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
    viewspace: str = "captures",
) -> EpisodeState:
    """The state a policy reads after the captured views ``order`` of a real scanner, in the
    planners' frame (the object within radius 0.5 of the origin).

    Args:
        poses: (V, 4, 4) camera-to-world of the candidates (and any extra captured views).
        parts: V arrays (N_v, 3) of each view's points; empty for views not captured.
        order: the captured views in order.
        points_per_view: the subsampling the points were kept with (0 = all), for the record.
        viewspace: the name of the record's one viewspace.

    Returns:
        An :class:`EpisodeState` over a one-viewspace record without ground truth (its
        coverage bits and hull vertices are empty: only the oracle would read them).
    """
    poses = np.asarray(poses, dtype=np.float64)
    view = ViewData(
        poses=poses, points=np.concatenate(parts).astype(np.float32), offsets=offsets_of(parts),
        coverage=np.zeros((len(poses), 1), np.uint8), hull_points=np.zeros((0, 3), np.float32),
        hull_offsets=np.zeros(len(poses) + 1, dtype=np.int64), points_per_view=points_per_view,
    )  # fmt: skip
    model = ModelData(
        key="captures", category="", split="", source="captures", source_path="",
        center=np.zeros(3), scale=1.0, seed=0, gt_points=np.zeros((0, 3), np.float32),
        gt_hull_volume=float("nan"), views={viewspace: view},
    )  # fmt: skip
    state = EpisodeState(model, viewspace, np.zeros(len(poses), dtype=bool), list(order))
    state.view_state[list(order)] = True
    return state
