"""Disturbance checks (the paper's Fig. 18): what the methods lean on.

* ``random_cloud``: a network gets a random cloud (as many points as the true accumulated cloud,
  uniform in a ball) with the true view state.
* ``permuted_state``: a network gets the true cloud with a random view state that has as many
  visited views as the true one (it still may only pick an unvisited view).
* ``random_hull``: the one-shot convex-hull planner plans on the hull of random points (as many
  as the start view's cloud) instead of the start view's cloud.

A method that ignores its cloud loses nothing under ``random_cloud``; one that ignores its view
state loses nothing under ``permuted_state``. :func:`auc_changes` compares each check's AUC with
the undisturbed method's on the same episodes.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from nbv.policies.episode import EpisodeState
from nbv.policies.hull import HullSCOPolicy
from nbv.policies.network import NetworkPolicy
from nbv.policies.registry import CHECKS


def random_ball(n: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniform in the ball of ``radius`` about the origin: (n, 3) float32."""
    direction = rng.normal(size=(n, 3))
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
    r = radius * np.cbrt(rng.random(n))
    return (direction * r[:, None]).astype(np.float32)


def permuted_state(view_state: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A view state with as many visited views as ``view_state``, at random positions."""
    return rng.permutation(np.asarray(view_state, dtype=bool))


class _Wrapper:
    """A disturbed policy reports the timings and notes of the policy it wraps (``inner``)."""

    inner: NetworkPolicy | HullSCOPolicy

    @property
    def timings(self) -> dict[str, list[float]]:
        return self.inner.timings

    @property
    def notes(self) -> list[str]:
        return self.inner.notes


@dataclass
class RandomCloudNetwork(_Wrapper):
    """The wrapped network decides on a random cloud (the true cloud's size), true view state."""

    inner: NetworkPolicy
    rng: np.random.Generator
    radius: float = 0.5

    def __call__(self, state: EpisodeState) -> int:
        cloud = random_ball(max(len(state.cloud()), 1), self.radius, self.rng)
        return self.inner.decide(cloud, state.view_state)


@dataclass
class PermutedStateNetwork(_Wrapper):
    """The wrapped network decides on the true cloud and a permuted view state; visited views stay
    masked by the true state."""

    inner: NetworkPolicy
    rng: np.random.Generator

    def __call__(self, state: EpisodeState) -> int:
        shown = permuted_state(state.view_state, self.rng)
        return self.inner.decide(state.cloud(), shown, visited=state.view_state)


@dataclass
class RandomHullPlanner(_Wrapper):
    """The one-shot hull planner on the hull of random points (as many as the start view's)."""

    inner: HullSCOPolicy
    rng: np.random.Generator
    radius: float = 0.5

    def __call__(self, state: EpisodeState) -> list[int]:
        view = state.model.views[state.viewspace]
        n = max(len(view.view_points(state.order[0])), 4)
        remaining = min(self.inner.n_views, len(view.poses)) - len(state.order)
        cloud = random_ball(n, self.radius, self.rng)
        return self.inner.plan_from(cloud, view.poses, list(state.order), remaining)


def disturbed(check: str, policy, rng: np.random.Generator, radius: float = 0.5):
    """The policy of ``check`` around an undisturbed ``policy`` of a method it applies to."""
    if check == "random_cloud":
        return RandomCloudNetwork(policy, rng, radius)
    if check == "permuted_state":
        return PermutedStateNetwork(policy, rng)
    if check == "random_hull":
        return RandomHullPlanner(policy, rng, radius)
    raise ValueError(f"unknown check {check!r}; allowed: {', '.join(CHECKS)}")


def auc_changes(records: list) -> list[dict]:
    """Each check's AUC beside the undisturbed method's on the same episodes.

    Args:
        records: :class:`nbv.eval.protocol.EpisodeRecord` of both the checks and the methods.

    Returns:
        One row per (check, method, dataset, viewspace): ``n`` paired episodes, ``auc`` of the
        method, ``auc_disturbed``, ``change`` (disturbed minus undisturbed, mean of the paired
        differences) and ``change_se`` (its standard error).
    """
    plain = {
        (r.method, r.dataset, r.viewspace, r.key, r.start): r.auc
        for r in records
        if r.check is None
    }
    groups: dict[tuple, list[tuple[float, float]]] = defaultdict(list)
    for r in records:
        if r.check is None:
            continue
        base = plain.get((r.method, r.dataset, r.viewspace, r.key, r.start))
        if base is not None:
            groups[(r.check, r.method, r.dataset, r.viewspace)].append((base, r.auc))
    rows = []
    for (check, method, dataset, viewspace), pairs in groups.items():
        base, dist = np.array(pairs).T
        diff = dist - base
        se = float(diff.std(ddof=1) / np.sqrt(len(diff))) if len(diff) > 1 else float("nan")
        rows.append(
            dict(
                check=check,
                method=method,
                dataset=dataset,
                viewspace=viewspace,
                n=len(pairs),
                auc=float(base.mean()),
                auc_disturbed=float(dist.mean()),
                change=float(diff.mean()),
                change_se=se,
            )
        )
    return rows
