"""What a view-selection method is: its declaration (:class:`Method`) and what building its
policy may use (:class:`MethodContext`).

The methods themselves are the rows of :data:`nbv.policies.registry.METHODS`; how each builds
its policy is :mod:`nbv.policies.builders`. How a method is drawn (:data:`nbv.eval.plots.STYLES`)
and the paper's times (:data:`nbv.eval.timing.PAPER_TIMES`) live beside the report that reads
them; the weights a network method runs, a checkpoint or the shipped ones, are resolved above
the policies (:mod:`nbv.scan.shipped`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.infogain.gain_scorer import GainScorer
from nbv.infogain.settings import InfoGainSettings
from nbv.policies.completion import Completion
from nbv.policies.conditioned_network import ConditionedPolicy
from nbv.policies.episode import Policy
from nbv.policies.network import NetworkPolicy
from nbv.setcover.settings import SetCoverSettings

#: Disturbance checks (the paper's Fig. 18, and Gaussian position noise on the cloud a method
#: sees): what each one replaces of a policy's input.
CHECKS = ("random_cloud", "permuted_state", "random_hull", "position_noise")
#: The scores a method may be made to raise (:attr:`Method.score`).
SCORES = ("coverage", "vig")


@dataclass(frozen=True)
class MethodContext:
    """What building a method's policy may use, the same for every episode of a run.

    Attributes:
        networks: network method name -> a loaded :class:`NetworkPolicy` (every network the
            built methods run: :attr:`Method.networks`).
        setcover: the convex-hull set cover's settings.
        intrinsics: the dataset's camera.
        eps: the dataset's coverage distance (the planner's capture distance: of the raycast
            simulation, and of the analytic one's dilation).
        n_views: views per episode, start view included.
        infogain: the information-gain planner's settings.
        traced: the information-gain planner's candidate voxels, shared by the episodes (they
            depend on the viewspace and the settings only).
        scorer: the learned score of ``ig_learned``; None: none given (the commands give the
            shipped one: :func:`nbv.scan.shipped.shipped_scorer`).
        completion: the completion of the completion planners (captured cloud -> points on
            the whole surface); None: none given (the commands give the shipped network,
            loaded on its first use: :class:`nbv.scan.shipped.ShippedCompletion`).
    """

    networks: Mapping[str, NetworkPolicy]
    setcover: SetCoverSettings
    intrinsics: Intrinsics
    eps: float
    n_views: int
    infogain: InfoGainSettings = field(default_factory=InfoGainSettings)
    traced: dict = field(default_factory=dict, compare=False, repr=False)
    scorer: GainScorer | None = field(default=None, compare=False, repr=False)
    completion: Completion | None = field(default=None, compare=False, repr=False)


def _given(value, what: str, field_name: str, shipped: str):
    if value is None:
        raise ValueError(f"no {what} given (MethodContext.{field_name}; the shipped one: "
                         f"nbv.scan.shipped.{shipped})")  # fmt: skip
    return value


def completion_of(ctx: MethodContext) -> Completion:
    """The context's completion.

    Raises:
        ValueError: the context has none.
    """
    return _given(ctx.completion, "completion network", "completion", "ShippedCompletion")


def scorer_of(ctx: MethodContext) -> GainScorer:
    """The context's learned score of ``ig_learned``.

    Raises:
        ValueError: the context has none.
    """
    return _given(ctx.scorer, "learned score", "scorer", "shipped_scorer")


@dataclass(frozen=True)
class Method:
    """One view-selection method.

    Attributes:
        name: its name in configs, results and reports.
        summary: one line for the report and ``--help``-like listings.
        build: ``(context, rng) -> policy`` for one episode (the policy's ``timings`` start
            empty).
        network_input: ``points`` or ``signature`` when the method runs a trained PCNBV
            checkpoint of that input, ``directions`` for the viewspace-conditioned network (it
            needs ``checkpoints.<name>``); None otherwise.
        network: the network method whose loaded network this method runs, when it is not a
            network method itself (a planner led by a network's first picks); it needs that
            method's ``checkpoints.<network>``. None otherwise.
        ground_truth: the method reads the ground truth (an upper reference, not a method a
            robot could run).
        checks: the disturbance checks that apply to it.
        geometric: a geometric planner (its plans' zero-gain picks are fill, not its score).
        stochastic: its picks are random by design; the evaluation averages several seeds
            per episode (``random_repeats``).
        learned_score: it ranks with the run's learned score (``MethodContext.scorer``, the
            evaluation's ``ig_scorer``).
        score: what its picks are made to raise (:data:`SCORES`): ``coverage``, or ``vig``
            for a method trained on VIG, greedy by it or led by a network trained on it (the
            report pairs these with random on the VIG curve's AUC).
        by_default: ``python -m nbv.eval`` runs it when ``methods`` is not given
            (:data:`nbv.policies.registry.DEFAULT_METHODS`); False for a variant registered
            but too costly for every run (run it by naming it).
        matched: it runs ``network``'s network on the episode's viewspace by direction
            (:mod:`nbv.policies.view_matching`); unless ``geometric`` (a two-stage planner led
            by it) it scores every view as a network method does.
    """

    name: str
    summary: str
    build: Callable[[MethodContext, np.random.Generator], Policy]
    network_input: str | None = None
    ground_truth: bool = False
    checks: tuple[str, ...] = ()
    geometric: bool = False
    stochastic: bool = False
    learned_score: bool = False
    network: str | None = None
    score: str = "coverage"
    by_default: bool = True
    matched: bool = False

    def __post_init__(self) -> None:
        if self.score not in SCORES:
            raise ValueError(f"method {self.name}: score={self.score!r}; allowed: {SCORES}")
        if self.network is not None and self.network_input is not None:
            raise ValueError(f"method {self.name}: a network method runs its own network")
        if self.matched and self.network is None:
            raise ValueError(f"method {self.name}: a matched method names the network it runs")

    @property
    def matched_network(self) -> bool:
        """A network run by direction on the episode's viewspace that scores every view as a
        network method does (``matched``, not a two-stage planner led by it)."""
        return self.matched and not self.geometric

    @property
    def networks(self) -> tuple[str, ...]:
        """The network methods whose loaded networks it runs (``MethodContext.networks`` must
        hold them): itself for a network method, ``network`` for one led by another's."""
        if self.network_input is not None:
            return (self.name,)
        return (self.network,) if self.network is not None else ()

    def load(
        self, path: str | Path, n_views: int | None, precision: str | None = None
    ) -> NetworkPolicy | ConditionedPolicy:
        """The network policy of the checkpoint at ``path`` (no fallback: the shipped weights are
        :func:`nbv.scan.shipped.resolve_weights`'s).

        Args:
            path: a checkpoint of ``python -m train`` (points, signature) or of
                ``python -m train.conditioned`` (directions).
            n_views: the viewspace's size (a PCNBV network has one output per view); None:
                any.
            precision: a PCNBV network's arithmetic (:data:`nbv.models.precision.PRECISIONS`);
                None: the checkpoint's (bfloat16 runs where the CPU has it natively).

        Raises:
            nbv.models.checkpoints.CheckpointError: the file is not a usable checkpoint.
        """
        if self.network_input == "directions":
            return ConditionedPolicy.from_checkpoint(path)
        return NetworkPolicy.from_checkpoint(path, n_views=n_views, precision=precision)
