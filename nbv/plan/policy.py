"""What both inputs of ``python -m nbv.plan`` share: the registry's policy built for a plan, the
planner's predicted gains, and :class:`PlanResult`, what a plan found.

Both inputs become what the evaluator's policies read, a :class:`nbv.dataset.records.ModelData`
of one viewspace (:data:`VIEWSPACE`), in the planners' normalised frame (:mod:`nbv.plan.frame`):
the object's centre at the origin, its radius 0.5, the rig's up axis +y. The policy is the
registry's (:data:`nbv.policies.registry.METHODS`), built with the generator :func:`policy_rng`
gives, so a plan from captures is the evaluator's decision on the same views.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.dataset.records import ModelData
from nbv.geometry.camera import Intrinsics
from nbv.plan.config import PlanSettings
from nbv.plan.frame import ObjectFrame
from nbv.policies.episode import EpisodeState
from nbv.policies.registry import NETWORK_INPUTS, MethodContext
from nbv.utils.seeding import named_rng

log = logging.getLogger(__name__)

#: The viewspace's name in the plan's record.
VIEWSPACE = "plan"


def policy_rng(seed: int, method: str) -> np.random.Generator:
    """The generator a plan's policy is built with (the same for every input)."""
    return named_rng(seed, "plan", method)


@dataclass
class PlanResult:
    """What one plan found, in the planners' normalised frame unless said otherwise.

    Attributes:
        frame: the object's frame (world <-> normalised).
        model: the record the policy read (candidates first, then extra captured views).
        n_candidates: V, the viewspace's views (indices ``0..V-1``).
        visited: the captured views in order (candidate indices; extras ``>= V``).
        chosen: the planned views in order (candidate indices).
        gains: the planner's predicted gain of each chosen view (None when it predicts none),
            and ``gain_unit`` what it counts.
        coverage: mesh input: coverage of the ground truth after each view of the episode.
        decisions: seconds of each policy call; ``stages`` the policy's own timings.
        captured_files: captures input: each capture's file and its view index.
        notes: what the policy or the input had to work around.
        frame_estimated: the object's centre and radius were estimated from the captures.
        camera: the planner's camera (its view simulation, ``ig``'s rays).
    """

    frame: ObjectFrame
    model: ModelData
    n_candidates: int
    visited: list[int]
    chosen: list[int]
    gains: list[float] | None = None
    gain_unit: str = ""
    coverage: list[float] | None = None
    decisions: list[float] = field(default_factory=list)
    stages: dict[str, float] = field(default_factory=dict)
    captured_files: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    frame_estimated: bool = False
    camera: Intrinsics | None = None

    @property
    def cloud(self) -> np.ndarray:
        """(N, 3) float32 accumulated cloud of the visited views, normalised frame."""
        view = self.model.views[VIEWSPACE]
        return np.concatenate([view.view_points(v) for v in self.visited])


def method_context(settings: PlanSettings, camera, n_views: int) -> MethodContext:
    """The registry's context of the plan's method (its network loaded when it has one)."""
    networks = {}
    if settings.method in NETWORK_INPUTS:
        networks[settings.method] = load_network(settings, n_views)
    return MethodContext(
        networks=networks,
        planner=settings.hull,
        intrinsics=camera,
        eps=settings.eps,
        n_views=settings.n_views,
        volumetric=settings.ig,
    )


def load_network(settings: PlanSettings, n_views: int):
    """The network of a network method: ``checkpoint``, else the weights the package ships."""
    from nbv.assets.weights import shipped_weights
    from nbv.models.checkpoints import CheckpointError
    from nbv.policies.conditioned import ConditionedPolicy
    from nbv.policies.network import NetworkPolicy

    path = settings.checkpoint
    if path is None or not Path(path).exists():
        shipped = shipped_weights(settings.method)
        if shipped is None:
            raise ValueError(
                f"method={settings.method} needs trained weights: checkpoint=<best.pt> (none at "
                f"{path})"
            )
        log.info("%s: no checkpoint at %s; using the shipped weights %s", settings.method, path,
                 shipped)  # fmt: skip
        path = shipped
    try:
        if NETWORK_INPUTS[settings.method] == "directions":
            return ConditionedPolicy.from_checkpoint(path)
        return NetworkPolicy.from_checkpoint(path, n_views=n_views)
    except CheckpointError as err:
        raise ValueError(f"checkpoint: {err}") from None


def predicted_gains(policy, chosen: list[int]) -> tuple[list | None, str]:
    """The planner's own predicted gain of each chosen view, and what it counts
    (``last_gains`` and ``gain_unit`` of the policy's last decision).

    The convex-hull planners report the hull samples each planned view newly covers, the
    information-gain planner the unknown voxels its rays count. Other methods predict no gain,
    and a replanning hull planner's plan is longer than its one pick: None.
    """
    gains = getattr(policy, "last_gains", None)
    if gains and len(gains) == len(chosen):
        return [float(g) for g in gains], policy.gain_unit
    return None, ""


class GainRecorder:
    """A policy that also keeps the planner's predicted gain of every view it picks
    (:func:`predicted_gains`, None where it predicts none) and the seconds of each of its own
    decisions (without the gains' reading)."""

    def __init__(self, policy) -> None:
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


def stage_seconds(policy) -> dict[str, float]:
    return {k: float(np.sum(v)) for k, v in getattr(policy, "timings", {}).items()}


def object_frame(settings: PlanSettings, center, radius) -> ObjectFrame:
    c = settings.center if settings.center is not None else center
    r = settings.radius if settings.radius is not None else radius
    frame = ObjectFrame(np.asarray(c, dtype=np.float64), float(r), settings.viewspace.up)
    if settings.distance is not None and settings.distance <= frame.radius:
        raise ValueError(
            f"viewspace.radius={settings.distance}: the cameras would sit inside the object's "
            f"sphere (radius {frame.radius:.4g})"
        )
    return frame
