"""The plan's method: the registry's policy built for a plan, and what the policy reports.

The policy is the registry's (:data:`nbv.policies.registry.METHODS`), built from
:func:`scan_context` with the generator :func:`policy_rng` gives, so that a plan from captures
is the evaluator's decision on the same views. After each decision the plan reads the policy's
own predicted gains (:func:`predicted_gains`, :class:`GainRecorder`) and stage timings
(:func:`nbv.policies.episode.stage_seconds`).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.policies.episode import EpisodeState, Policy
from nbv.policies.method import MethodContext
from nbv.policies.registry import METHODS, networks_of
from nbv.scan.settings import ScanSettings
from nbv.scan.shipped import resolve_weights, with_shipped
from nbv.utils.seeding import named_rng

if TYPE_CHECKING:
    from nbv.policies.conditioned_network import ConditionedPolicy
    from nbv.policies.network import NetworkPolicy


def policy_rng(seed: int, method: str) -> np.random.Generator:
    """The generator a plan's policy is built with (the same for every input)."""
    return named_rng(seed, "plan", method)


def scan_context(settings: ScanSettings, camera: Intrinsics, n_views: int) -> MethodContext:
    """The registry's context of the plan's method (the network it runs loaded, its own or, for
    a planner led by a network, the leading one's).

    Args:
        settings: the plan's settings.
        camera: the planner's camera.
        n_views: the candidates' number (a PCNBV network has one output per view).
    """
    # A network matched by direction runs on any number of candidates; any other has one
    # output per view of its viewspace.
    views = None if METHODS[settings.method].matched else n_views
    networks = {
        name: load_network(settings, views, name) for name in networks_of([settings.method])
    }
    return with_shipped(
        MethodContext(
            networks=networks,
            setcover=settings.setcover,
            intrinsics=camera,
            eps=settings.eps,
            n_views=settings.n_views,
            infogain=settings.infogain,
        ),
        [settings.method],
    )


def load_network(
    settings: ScanSettings, n_views: int | None, name: str
) -> NetworkPolicy | ConditionedPolicy:
    """The network policy of the network method ``name`` the plan runs: ``checkpoint``, else
    the weights the package ships (:func:`nbv.scan.shipped.resolve_weights`).

    Raises:
        ValueError: no weights, or a file that is not a usable checkpoint (``checkpoint: ...``).
    """
    from nbv.models.checkpoints import CheckpointError

    method = METHODS[name]
    path = resolve_weights(name, settings.checkpoint)
    try:
        return method.load(path, n_views)
    except CheckpointError as err:
        raise ValueError(f"checkpoint: {err}") from None


def predicted_gains(policy: Policy, chosen: list[int]) -> tuple[list | None, str]:
    """The planner's own predicted gain of each chosen view, and what it counts
    (``last_gains`` and ``gain_unit`` of the policy's last decision).

    The convex-hull planners report the hull samples each planned view newly covers, the
    information-gain planner the unknown voxels its rays count. Other methods predict no gain,
    and a replanning hull planner's plan is longer than its one pick: None.
    """
    gains = policy.last_gains
    if gains and len(gains) == len(chosen):
        return [float(g) for g in gains], policy.gain_unit
    return None, ""


class GainRecorder:
    """A policy that also keeps the planner's predicted gain of every view it picks
    (:func:`predicted_gains`, None where it predicts none) and the seconds of each of its own
    decisions (without the gains' reading)."""

    def __init__(self, policy: Policy) -> None:
        self.policy = policy
        self.gains: list[float | None] = []
        self.unit = ""
        self.seconds: list[float] = []

    def __call__(self, state: EpisodeState) -> int | list[int]:
        t0 = time.perf_counter()
        choice = self.policy(state)
        self.seconds.append(time.perf_counter() - t0)
        chosen = [int(v) for v in (choice if isinstance(choice, list | tuple) else [choice])]
        gains, self.unit = predicted_gains(self.policy, chosen)
        self.gains += gains if gains is not None else [None] * len(chosen)
        return choice
