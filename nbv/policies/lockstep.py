"""Episodes of one model stepped together, so that a network decides for all of them at once.

:func:`run_lockstep` runs many episodes (each its own viewspace, start view and policy) in
lockstep: at every step each episode that needs a decision asks its policy. A policy that is
:class:`Batchable` does not decide alone: it states what its network should be shown
(:meth:`Batchable.request`), and the requests of every episode that runs the same network are
answered by one batched forward pass (``NetworkPolicy.decide_many``). Every other policy, and a
batchable one whose decision runs no network (its request is None: the two-stage planner's plan),
is called as :func:`nbv.policies.episode.run_episode` calls it.

Each episode is exactly what :func:`~nbv.policies.episode.run_episode` gives for it alone: its
policy, state and generator are its own, so the order in which episodes are served changes no
draw, and a batched forward pass computes each row from its own episode's input (the views match
one-at-a-time inference; ``tests/test_lockstep.py`` checks it on the shipped weights in float32).
The seconds of a batched decision are shared equally among its episodes.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from nbv.policies.episode import (
    EPISODE_VIEWS,
    Episode,
    EpisodeState,
    GroundTruth,
    Policy,
    RunningEpisode,
    reads_ground_truth,
)


class Request(Protocol):
    """One episode's ask for a batched decision.

    Attributes:
        policy: the episode's own policy (a ``fresh()`` copy of a network policy: its ``model``
            is the network the episodes share); it records the decision's timings and notes.
    """

    policy: object

    @staticmethod
    def answer_all(requests: list) -> list[int]:
        """The chosen views of requests of one type and one network, one batched pass."""
        ...


class NetworkRequest(NamedTuple):
    """What a PCNBV episode's network should be shown for its next decision.

    Attributes:
        policy: the episode's own :class:`~nbv.policies.network.NetworkPolicy`.
        cloud: (N, 3) the cloud it is shown.
        shown: (V,) bool the view state it is shown.
        visited: (V,) bool the views it may not choose; None: ``shown``.
    """

    policy: object
    cloud: np.ndarray
    shown: np.ndarray
    visited: np.ndarray | None = None

    @staticmethod
    def answer_all(requests: list[NetworkRequest]) -> list[int]:
        """``decide_many`` of the first request's network for all of them."""
        return requests[0].policy.decide_many(
            [r.cloud for r in requests],
            [r.shown for r in requests],
            None if all(r.visited is None for r in requests)
            else [r.shown if r.visited is None else r.visited for r in requests],
            episodes=[r.policy for r in requests],
        )  # fmt: skip


class StateRequest(NamedTuple):
    """An episode's state, for a policy that batches whole states (``choose_many``)."""

    policy: object
    state: EpisodeState

    @staticmethod
    def answer_all(requests: list[StateRequest]) -> list[int]:
        """``choose_many`` of the first request's policy for all of them."""
        return requests[0].policy.choose_many(
            [r.state for r in requests], episodes=[r.policy for r in requests]
        )


@runtime_checkable
class Batchable(Protocol):
    """A policy whose decision is one forward pass of a network that others may share (or, for
    a policy that runs a network for some decisions only, may be)."""

    def request(self, state: EpisodeState) -> Request | None:
        """What its network should be shown in ``state`` (drawing what the decision draws);
        None: this decision runs no network, and the policy is called as alone."""
        ...


@dataclass
class EpisodeSpec:
    """One episode to run: its viewspace, start view and policy."""

    viewspace: str
    start: int
    policy: Policy


def _decide_batched(waiting: list[tuple[RunningEpisode, Request, float]]) -> None:
    """One batched decision for the requests of one network; each episode's time is its own
    request's seconds plus an equal share of the batched pass's."""
    requests = [r for _, r, _ in waiting]
    t0 = time.perf_counter()
    choices = type(requests[0]).answer_all(requests)
    share = (time.perf_counter() - t0) / len(waiting)
    for (run, _, asked), choice in zip(waiting, choices, strict=True):
        run.take(choice, asked + share)


def run_lockstep(
    model: GroundTruth, specs: Sequence[EpisodeSpec], n_views: int = EPISODE_VIEWS
) -> list[Episode]:
    """Run every episode of ``specs`` on ``model`` until each has ``n_views`` views (or its
    viewspace's size), the batchable policies' decisions batched by network.

    Returns:
        The episodes in the order of ``specs``: each as :func:`run_episode` gives it.

    Raises:
        ValueError: a start view outside its viewspace, or a policy that chose a visited or
            out-of-range view.
    """
    running = [
        RunningEpisode.start(model, s.viewspace, s.start, n_views, reads_ground_truth(s.policy))
        for s in specs
    ]
    while True:
        active = [run for run in running if not run.done]
        if not active:
            break
        batches: dict[tuple[type, int, int], list[tuple[RunningEpisode, Request, float]]] = {}
        for run, spec in zip(running, specs, strict=True):
            if run.done or run.queue:
                continue
            policy = spec.policy
            t0 = time.perf_counter()
            request = policy.request(run.state) if isinstance(policy, Batchable) else None
            if request is not None:
                # Batched by network (the fresh() copies of one checkpoint share its model) and
                # by the viewspace's size (a forward pass scores one V).
                key = (type(request), id(request.policy.model), len(run.state.view_state))
                batches.setdefault(key, []).append((run, request, time.perf_counter() - t0))
            else:
                choice = policy(run.state)
                run.take(choice, time.perf_counter() - t0)
        for waiting in batches.values():
            _decide_batched(waiting)
        for run in active:
            run.step()
    return [run.episode() for run in running]
