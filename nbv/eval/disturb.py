"""Disturbance checks (the paper's Fig. 18): what the methods lean on.

* ``random_cloud``: a network gets a random cloud (as many points as the true accumulated cloud,
  uniform in a ball) with the true view state.
* ``permuted_state``: a network gets the true cloud with a random view state that has as many
  visited views as the true one (it still may only pick an unvisited view).
* ``random_hull``: the one-shot convex-hull planner plans on the hull of random points (as many
  as the start view's cloud) instead of the start view's cloud.
* ``position_noise``: a network or a planner sees every captured point moved by isotropic
  Gaussian noise of standard deviation sigma (object frame units: the object fits in radius
  0.5), one check per sigma (``position_noise_<sigma>``). Coverage is still scored on the true
  views: only what the method sees is noisy.

A method that ignores its cloud loses nothing under ``random_cloud``; one that ignores its view
state loses nothing under ``permuted_state``. :func:`auc_changes` compares each check's AUC with
the undisturbed method's on the same episodes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from nbv.eval.statistics import episode_means, paired_from_means
from nbv.geometry.views import CapturedViews
from nbv.policies.episode import EpisodeState
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.lockstep import Batchable, NetworkRequest, Request
from nbv.policies.method import CHECKS
from nbv.policies.network import NetworkPolicy
from nbv.policies.setcover import SetCoverPolicy


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

    inner: NetworkPolicy | SetCoverPolicy

    @property
    def timings(self) -> dict[str, list[float]]:
        return self.inner.timings

    @property
    def notes(self) -> list[str]:
        return self.inner.notes

    @property
    def counts(self) -> dict[str, int]:
        return self.inner.counts

    @property
    def last_gains(self) -> list[float]:
        return self.inner.last_gains


@dataclass
class RandomCloudNetwork(_Wrapper):
    """The wrapped network decides on a random cloud (the true cloud's size), true view state."""

    inner: NetworkPolicy
    rng: np.random.Generator
    radius: float = 0.5

    def request(self, state: EpisodeState) -> NetworkRequest:
        """The random cloud and the true state, for a batched decision (the same draw as a
        call)."""
        cloud = random_ball(max(len(state.cloud()), 1), self.radius, self.rng)
        return NetworkRequest(self.inner, cloud, state.view_state)

    def __call__(self, state: EpisodeState) -> int:
        asked = self.request(state)
        return self.inner.decide(asked.cloud, asked.shown, visited=asked.visited)


@dataclass
class PermutedStateNetwork(_Wrapper):
    """The wrapped network decides on the true cloud and a permuted view state; visited views stay
    masked by the true state."""

    inner: NetworkPolicy
    rng: np.random.Generator

    def request(self, state: EpisodeState) -> NetworkRequest:
        """The true cloud and a permuted state, for a batched decision (the same draw as a
        call)."""
        shown = permuted_state(state.view_state, self.rng)
        return NetworkRequest(self.inner, state.cloud(), shown, state.view_state)

    def __call__(self, state: EpisodeState) -> int:
        asked = self.request(state)
        return self.inner.decide(asked.cloud, asked.shown, visited=asked.visited)


@dataclass
class RandomHullPlanner(_Wrapper):
    """The one-shot hull planner on the hull of random points (as many as the start view's)."""

    inner: SetCoverPolicy
    rng: np.random.Generator
    radius: float = 0.5

    def __call__(self, state: EpisodeState) -> list[int]:
        view = state.views
        n = max(len(view.view_points(state.order[0])), 4)
        remaining = min(self.inner.n_views, len(view.poses)) - len(state.order)
        cloud = random_ball(n, self.radius, self.rng)
        return self.inner.plan_from(cloud, view.poses, list(state.order), remaining)


@dataclass
class NoisyPoints(_Wrapper):
    """The wrapped policy (a network, a one-shot hull planner, the information-gain planner)
    sees every view's points moved by Gaussian noise of ``sigma``.

    The noise of the episode's viewspace is drawn once, on the first call, for all its views;
    the episode's own record (coverage, VIG) still comes from the true model.
    """

    inner: NetworkPolicy | SetCoverPolicy | InfoGainPolicy
    rng: np.random.Generator
    sigma: float
    _views: CapturedViews | None = None

    def noisy(self, views: CapturedViews) -> CapturedViews:
        """``views`` with their points disturbed (the same ones on every call)."""
        if self._views is None:
            noise = self.rng.normal(0.0, self.sigma, size=views.points.shape)
            self._views = replace(views, points=(views.points + noise).astype(views.points.dtype))
        return self._views

    def __call__(self, state: EpisodeState) -> int | list[int]:
        return self.inner(self.shown(state))

    def shown(self, state: EpisodeState) -> EpisodeState:
        """The state the wrapped policy is shown: the views' points disturbed."""
        return replace(state, views=self.noisy(state.views))


@dataclass
class NoisyNetwork(NoisyPoints):
    """:class:`NoisyPoints` around a network that decides in batches (:class:`Batchable`)."""

    inner: Batchable

    def request(self, state: EpisodeState) -> Request:
        """The wrapped network's request on the disturbed state."""
        return self.inner.request(self.shown(state))


#: Prefix of the checks' names in the records: ``position_noise_0.005``.
NOISE_PREFIX = "position_noise_"


def noise_check(sigma: float) -> str:
    """The record name of the position-noise check of ``sigma``."""
    return f"{NOISE_PREFIX}{sigma:g}"


def check_sigma(name: str) -> float | None:
    """The sigma of a position-noise record name, None for the other checks."""
    return float(name[len(NOISE_PREFIX) :]) if name.startswith(NOISE_PREFIX) else None


def disturbed(
    check: str, policy, rng: np.random.Generator, radius: float = 0.5, sigma: float = 0.0
):
    """The policy of ``check`` around an undisturbed ``policy`` of a method it applies to
    (``sigma``: the noise of ``position_noise``)."""
    if check == "position_noise":
        return (NoisyNetwork if isinstance(policy, Batchable) else NoisyPoints)(policy, rng, sigma)
    if check == "random_cloud":
        return RandomCloudNetwork(policy, rng, radius)
    if check == "permuted_state":
        return PermutedStateNetwork(policy, rng)
    if check == "random_hull":
        return RandomHullPlanner(policy, rng, radius)
    raise ValueError(f"unknown check {check!r}; allowed: {', '.join(CHECKS)}")


def auc_changes(records: list, seed: int = 0) -> list[dict]:
    """Each check's AUC beside the undisturbed method's on the same episodes.

    Args:
        records: :class:`nbv.eval.protocol.EpisodeRecord` of both the checks and the methods.
        seed: the bootstrap's seed.

    Returns:
        One row per (check, method, dataset, viewspace): ``n`` paired episodes, ``auc`` of the
        method, ``auc_disturbed``, ``change`` (disturbed minus undisturbed: an
        :class:`nbv.utils.stats.Interval` over the paired episodes, models resampled) and
        ``sigma`` (the position noise, None for the other checks).
    """
    keys = sorted({(r.check, r.method, r.dataset, r.viewspace) for r in records if r.check})
    means = episode_means(records)
    rows = []
    for check, method, dataset, viewspace in keys:
        change = paired_from_means(
            means, (dataset, viewspace, method, None), (dataset, viewspace, method, check), seed
        )
        if change is None:
            continue
        rows.append(dict(
            check=check, method=method, dataset=dataset, viewspace=viewspace,
            n=change.interval.n, auc=change.mean_a, auc_disturbed=change.mean_b,
            change=change.interval, sigma=check_sigma(check),
        ))  # fmt: skip
    return rows
