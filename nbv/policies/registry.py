"""The registry of view-selection methods: the one place that names them.

Each :class:`Method` says its name, what it needs (a network checkpoint of some input, another
method's network, the ground truth), which disturbance checks apply to it, the score it is made to
raise, whether the evaluation runs it by default, how it is drawn, the paper's timing row when the
paper has one, and how to build a fresh policy for one episode. The evaluator, the disturbance
checks, the report and the plots read from :data:`METHODS`, so adding a method is one entry here.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nbv.assets.weights import SHIPPED_SCORER, shipped_weights
from nbv.geometry.camera import Intrinsics
from nbv.geometry.viewspace import original_viewspace
from nbv.infogain.gain_scorer import GainScorer, load_scorer
from nbv.infogain.settings import VolumetricSettings
from nbv.policies.baselines import OraclePolicy, RandomPolicy, SpreadPolicy
from nbv.policies.completion import (
    Completion,
    CompletionGainPolicy,
    CompletionHullPolicy,
    CompletionHullReplanPolicy,
)
from nbv.policies.conditioned_network import ConditionedPolicy
from nbv.policies.episode import Policy
from nbv.policies.hull_sco import HullSCOPolicy, HullSCOReplanPolicy
from nbv.policies.hybrid import HullThenGainPolicy
from nbv.policies.learned_gain import LearnedGainPolicy
from nbv.policies.network import NetworkPolicy
from nbv.policies.two_stage import NetworkThenHullPolicy
from nbv.policies.view_matching import MatchedNetworkPolicy
from nbv.policies.volumetric import InformationGainPolicy
from nbv.setcover.settings import HullSettings

log = logging.getLogger(__name__)

#: Disturbance checks (the paper's Fig. 18, and Gaussian position noise on the cloud a method
#: sees): what each one replaces of a policy's input.
CHECKS = ("random_cloud", "permuted_state", "random_hull", "position_noise")
#: The scores a method may be made to raise (:attr:`Method.score`).
SCORES = ("coverage", "vig")
#: The shipped weights' name of the completion network (``python -m train.completion``).
COMPLETION_WEIGHTS = "completion"


@dataclass(frozen=True)
class MethodContext:
    """What building a method's policy may use, the same for every episode of a run.

    Attributes:
        networks: network method name -> a loaded :class:`NetworkPolicy` (every network the
            built methods run: :attr:`Method.networks`).
        hull: the convex-hull set cover's settings.
        intrinsics: the dataset's camera.
        eps: the dataset's coverage distance (the planner's capture distance: of the raycast
            simulation, and of the analytic one's dilation).
        n_views: views per episode, start view included.
        volumetric: the information-gain planner's settings.
        traced: the information-gain planner's candidate voxels, shared by the episodes (they
            depend on the viewspace and the settings only).
        scorer: the learned score of ``ig_learned``; None: the weights the package ships
            (:data:`SHIPPED_SCORER`).
        completion: the completion of the completion planners (captured cloud -> points on
            the whole surface); None: the completion network the package ships, loaded once
            for the context (:func:`completion_of`).
    """

    networks: Mapping[str, NetworkPolicy]
    hull: HullSettings
    intrinsics: Intrinsics
    eps: float
    n_views: int
    volumetric: VolumetricSettings = field(default_factory=VolumetricSettings)
    traced: dict = field(default_factory=dict, compare=False, repr=False)
    scorer: GainScorer | None = field(default=None, compare=False, repr=False)
    completion: Completion | None = field(default=None, compare=False, repr=False)
    loaded: dict = field(default_factory=dict, compare=False, repr=False)


def completion_of(ctx: MethodContext) -> Completion:
    """The context's completion: ``ctx.completion``, else the shipped completion network
    (loaded on the first call and kept in ``ctx.loaded``).

    Raises:
        ValueError: the package ships no completion network.
    """
    if ctx.completion is not None:
        return ctx.completion
    if "completion" not in ctx.loaded:
        # Imported here: torch is heavy, and settings and listings read this module without it.
        from nbv.models.completion_inference import Completer

        path = shipped_weights(COMPLETION_WEIGHTS)
        if path is None:
            raise ValueError(f"no completion network shipped ({COMPLETION_WEIGHTS}.pt)")
        ctx.loaded["completion"] = Completer.from_checkpoint(path)
    return ctx.loaded["completion"]


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
        style: matplotlib colour and line style of its curves.
        learned_score: it ranks with the run's learned score (``MethodContext.scorer``, the
            evaluation's ``ig_scorer``).
        score: what its picks are made to raise (:data:`SCORES`): ``coverage``, or ``vig``
            for a method trained on VIG, greedy by it or led by a network trained on it (the
            report pairs these with random on the VIG curve's AUC).
        by_default: ``python -m nbv.eval`` runs it when ``methods`` is not given
            (:data:`DEFAULT_METHODS`); False for a variant registered but too costly for every
            run (run it by naming it).
        paper_times: the paper's Table 1 row, stage -> seconds per 9-view reconstruction
            (FACTS.md), when the paper times this method.
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
    style: tuple[str, str] = ("#8c564b", "-")
    learned_score: bool = False
    paper_times: Mapping[str, float] = field(default_factory=dict)
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

    def weights(self, checkpoint: str | Path | None) -> Path:
        """The weights this network method runs: ``checkpoint`` when it exists, else the weights
        the package ships for it (logged: which one, and why).

        Raises:
            ValueError: not a network method, or no checkpoint there and none shipped.
        """
        if self.network_input is None:
            raise ValueError(f"method {self.name!r} runs no network")
        if checkpoint is not None and Path(checkpoint).exists():
            return Path(checkpoint)
        shipped = shipped_weights(self.name)
        if shipped is None:
            raise ValueError(
                f"method={self.name} needs trained weights: checkpoint=<best.pt> (none at "
                f"{checkpoint})"
            )
        log.info("%s: no checkpoint at %s; using the shipped weights %s", self.name, checkpoint,
                 shipped)  # fmt: skip
        return shipped

    def load(
        self, path: str | Path, n_views: int | None, precision: str | None = None
    ) -> NetworkPolicy | ConditionedPolicy:
        """The network policy of the checkpoint at ``path`` (no fallback: see :meth:`weights`).

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


def _loaded(ctx: MethodContext, name: str) -> NetworkPolicy:
    """A fresh copy (empty timings) of the loaded network of method ``name``.

    Raises:
        ValueError: ``ctx.networks`` does not hold it (the message names it).
    """
    if name not in ctx.networks:
        raise ValueError(
            f"the network of {name} is not loaded (loaded: {sorted(ctx.networks) or 'none'}); "
            f"give checkpoints.{name}"
        )
    return ctx.networks[name].fresh()


def _network(name: str) -> Callable[[MethodContext, np.random.Generator], Policy]:
    """The builder of the network method ``name``: a fresh copy of its loaded network."""
    return lambda ctx, rng: _loaded(ctx, name)


def _hull_policy(
    ctx: MethodContext,
    rng: np.random.Generator,
    sph: bool = False,
    probes: bool = False,
    replan: bool = False,
) -> HullSCOPolicy:
    kind = HullSCOReplanPolicy if replan else HullSCOPolicy
    return kind(
        rng=rng,
        settings=ctx.hull,
        sph=sph,
        probes=ctx.hull.probes if probes else 0,
        n_views=ctx.n_views,
        intrinsics=ctx.intrinsics,
        eps=ctx.eps,
    )


RANDOM = Method(
    "random",
    "a seeded random unvisited view",
    lambda ctx, rng: RandomPolicy(rng),
    stochastic=True,
    style=("#7f7f7f", ":"),
)
SPREAD = Method(
    "spread",
    "the unvisited view farthest in angle from the visited ones (no geometry of the object; "
    "ties broken at random, seeded)",
    lambda ctx, rng: SpreadPolicy(rng),
    # Stochastic: on a viewspace of rings most decisions are ties (834 of 1056 on the original
    # viewspace, every start), so an episode is averaged over seeds as random's is.
    stochastic=True,
    style=("#bcbd22", ":"),
)
ORACLE = Method(
    "oracle",
    "greedy by the true coverage gain (reads the ground truth: the upper reference)",
    lambda ctx, rng: OraclePolicy("coverage"),
    ground_truth=True,
    style=("#000000", "--"),
)
ORACLE_VIG = Method(
    "oracle_vig",
    "greedy by the true VIG gain (reads the ground truth: the VIG methods' upper reference)",
    lambda ctx, rng: OraclePolicy("vig"),
    ground_truth=True,
    score="vig",
    style=("#525252", "--"),
    # One Qhull run per unvisited view a decision: 0.39 s an episode against pcnbv's 0.40 s on
    # 4 unseen models (2026-12-06), 16 % of the default run's time alone: named only.
    by_default=False,
)
PCNBV = Method(
    "pcnbv",
    "PCNBV on the accumulated cloud (a training checkpoint)",
    _network("pcnbv"),
    network_input="points",
    checks=("random_cloud", "permuted_state", "position_noise"),
    style=("#1f77b4", "-"),
    paper_times={"sampling": 3.12, "network": 0.21, "total": 3.24, "online": 3.24},
)
PCNBV_SPH = Method(
    "pcnbv_sph",
    "PCNBV on the cloud's spherical-harmonics signature (a training checkpoint)",
    _network("pcnbv_sph"),
    network_input="signature",
    checks=("random_cloud", "permuted_state", "position_noise"),
    style=("#17becf", "-"),
    paper_times={"signature": 2.53, "network": 0.02, "total": 2.55, "online": 2.55},
)
PCNBV_VIG = Method(
    "pcnbv_vig",
    "PCNBV on the accumulated cloud, trained on VIG (a checkpoint of `python -m train score=vig`)",
    _network("pcnbv_vig"),
    network_input="points",
    score="vig",
    style=("#aec7e8", "-."),
    # PCNBV's forwards are the costliest decisions of the default run (issue 41): named only.
    by_default=False,
)
PCNBV_SPH_VIG = Method(
    "pcnbv_sph_vig",
    "PCNBV on the cloud's spherical signature, trained on VIG (a checkpoint of `python -m train "
    "score=vig model=pcnbv_sph`)",
    _network("pcnbv_sph_vig"),
    network_input="signature",
    score="vig",
    style=("#9edae5", "-."),
)


def _matched(name: str) -> Callable[[MethodContext, np.random.Generator], Policy]:
    """The builder of network ``name`` run by direction on the episode's viewspace: a fresh copy
    of its loaded network behind a map from PC-NBV's 33 views (the viewspace it is trained on)."""
    return lambda ctx, rng: MatchedNetworkPolicy(_loaded(ctx, name), original_viewspace())


PCNBV_MATCHED = Method(
    "pcnbv_matched",
    "PCNBV's network on the episode's viewspace, its view state and gains matched with its "
    "training views by direction",
    _matched("pcnbv"),
    network="pcnbv",
    matched=True,
    style=("#08519c", ":"),
    # Identical to pcnbv on the original viewspace; PCNBV's forwards are the costliest of the
    # default run (issue 41): named only.
    by_default=False,
)
PCNBV_SPH_MATCHED = Method(
    "pcnbv_sph_matched",
    "PCNBV-sph's network on the episode's viewspace, its view state and gains matched with its "
    "training views by direction",
    _matched("pcnbv_sph"),
    network="pcnbv_sph",
    matched=True,
    style=("#0f7c86", ":"),
)


def _conditioned(name: str) -> Callable[[MethodContext, np.random.Generator], Policy]:
    """A fresh policy of the viewspace-conditioned checkpoint of method ``name``, with a fresh
    occupancy map of the run's ``ig`` settings (read only by a network of map features; an
    unused one costs nothing: its map is made on its first update)."""
    return lambda ctx, rng: ctx.networks[name].fresh(
        InformationGainPolicy(ctx.volumetric, ctx.intrinsics, traced=ctx.traced)
    )


VCNBV = Method(
    "vcnbv",
    "the viewspace-conditioned network: scores each candidate from its direction (a checkpoint "
    "of train.conditioned)",
    _conditioned("vcnbv"),
    network_input="directions",
    style=("#393b79", "-"),
)
VCNBV_MAP = Method(
    "vcnbv_map",
    "vcnbv whose head also reads each candidate's map features on ig's occupancy map (a "
    "checkpoint of train.conditioned map_features=true)",
    _conditioned("vcnbv_map"),
    network_input="directions",
    style=("#6b6ecf", "--"),
)
HULL_SCO = Method(
    "hull_sco",
    "convex-hull set cover, one-shot from the start view's cloud",
    lambda ctx, rng: _hull_policy(ctx, rng),
    checks=("random_hull", "position_noise"),
    geometric=True,
    style=("#d62728", "-"),
    # Its convex-hull row simulates views in Blender; its total (3.32 s) is as published.
    paper_times={"simulation": 3.32, "set_cover": 0.12, "total": 3.32, "online": 0.12},
)
HULL_SCO_SPH = Method(
    "hull_sco_sph",
    "convex-hull set cover on the hull of the cloud's spherical signature",
    lambda ctx, rng: _hull_policy(ctx, rng, sph=True),
    checks=("position_noise",),
    geometric=True,
    style=("#ff7f0e", "-"),
)
HULL_SCO_PROBES = Method(
    "hull_sco_probes",
    "hull_sco after `hull.probes` random probe views",
    lambda ctx, rng: _hull_policy(ctx, rng, probes=True),
    geometric=True,
    style=("#9467bd", "-."),
)


def _two_stage(
    sph: bool, matched: bool = False
) -> Callable[[MethodContext, np.random.Generator], Policy]:
    """The builder of the two-stage planner: ``PCNBV_SPH_VIG``'s picks for ``hull.network_views``
    decisions (its views matched with the episode's by direction with ``matched``), then a
    one-shot plan (on the signature's hull with ``sph``) on the whole cloud."""

    def build(ctx: MethodContext, rng: np.random.Generator) -> Policy:
        network = _loaded(ctx, PCNBV_SPH_VIG.name)
        if matched:
            network = MatchedNetworkPolicy(network, original_viewspace())
        return NetworkThenHullPolicy(network, _hull_policy(ctx, rng, sph=sph),
                                     ctx.hull.network_views)  # fmt: skip

    return build


VIG_HULL_SCO = Method(
    "vig_hull_sco",
    "the paper's two-stage planner: pcnbv_sph_vig picks `hull.network_views` views, then "
    "hull_sco plans the rest on the hull of the whole cloud",
    _two_stage(sph=False),
    network=PCNBV_SPH_VIG.name,
    geometric=True,
    score="vig",
    style=("#ff9896", "--"),
)
VIG_HULL_SCO_MATCHED = Method(
    "vig_hull_sco_matched",
    "vig_hull_sco with pcnbv_sph_vig's views matched with the episode's viewspace by direction",
    _two_stage(sph=False, matched=True),
    network=PCNBV_SPH_VIG.name,
    matched=True,
    geometric=True,
    score="vig",
    style=("#ad494a", "--"),
)
VIG_HULL_SCO_SPH = Method(
    "vig_hull_sco_sph",
    "vig_hull_sco planning on the hull of the whole cloud's spherical signature",
    _two_stage(sph=True),
    network=PCNBV_SPH_VIG.name,
    geometric=True,
    score="vig",
    style=("#ffbb78", "--"),
)
HULL_SCO_REPLAN = Method(
    "hull_sco_replan",
    "convex-hull set cover replanned on the whole cloud after every view",
    lambda ctx, rng: _hull_policy(ctx, rng, replan=True),
    geometric=True,
    style=("#2ca02c", "-."),
)
IG = Method(
    "ig",
    "volumetric information gain on an occupancy map of the captured views, replanned every view",
    lambda ctx, rng: InformationGainPolicy(ctx.volumetric, ctx.intrinsics, traced=ctx.traced),
    checks=("position_noise",),
    geometric=True,
    style=("#e377c2", "-"),
)
HULL_IG = Method(
    "hull_ig",
    "hull_sco's covering picks (its fill left out), then ig on the occupancy map",
    lambda ctx, rng: HullThenGainPolicy(
        _hull_policy(ctx, rng),
        InformationGainPolicy(ctx.volumetric, ctx.intrinsics, traced=ctx.traced),
    ),
    geometric=True,
    style=("#8c564b", "-"),
)

IG_LEARNED = Method(
    "ig_learned",
    "ig's occupancy map, candidates ranked by a perceptron over their rays' map features",
    lambda ctx, rng: LearnedGainPolicy(
        ctx.volumetric,
        ctx.intrinsics,
        traced=ctx.traced,
        scorer=ctx.scorer if ctx.scorer is not None else load_scorer(SHIPPED_SCORER),
    ),  # fmt: skip
    checks=("position_noise",),
    geometric=True,
    learned_score=True,
    style=("#c51b7d", "--"),
)


def _ig_metric(metric: str) -> Callable[[MethodContext, np.random.Generator], Policy]:
    """A fresh :class:`InformationGainPolicy` of the run's ``ig`` settings but ``metric``."""
    return lambda ctx, rng: InformationGainPolicy(
        dataclasses.replace(ctx.volumetric, metric=metric), ctx.intrinsics, traced=ctx.traced
    )


IG_AREA_FACTOR = Method(
    "ig_area_factor",
    "ig with Vasquez-Gomez et al.'s Area Factor: a view is best when a set share of its rays "
    "meets the captured surface and the unknown layer around it",
    _ig_metric("area_factor"),
    checks=("position_noise",),
    geometric=True,
    style=("#e7969c", "-."),
)
IG_PROXIMITY = Method(
    "ig_proximity",
    "ig with Proximity Count: unknown voxels weighted by their closeness to the captured surface",
    _ig_metric("proximity_count"),
    checks=("position_noise",),
    geometric=True,
    style=("#7b4173", ":"),
)


def _completion_hull(
    replan: bool = False,
) -> Callable[[MethodContext, np.random.Generator], Policy]:
    """The builder of the set cover on the hull of the captured cloud and its completion."""
    kind = CompletionHullReplanPolicy if replan else CompletionHullPolicy

    def build(ctx: MethodContext, rng: np.random.Generator) -> Policy:
        return kind(rng=rng, settings=ctx.hull, n_views=ctx.n_views, intrinsics=ctx.intrinsics,
                    eps=ctx.eps, complete=completion_of(ctx))  # fmt: skip

    return build


def _completion_gain(rule: str) -> Callable[[MethodContext, np.random.Generator], Policy]:
    """The builder of the view contribution of the context's completion by ``rule``."""
    return lambda ctx, rng: CompletionGainPolicy(
        completion_of(ctx), ctx.intrinsics, rule=rule, eps=ctx.eps
    )


COMPLETION_HULL_SCO = Method(
    "completion_hull_sco",
    "the paper's completed hull: convex-hull set cover, one-shot from the start view, on the "
    "hull of the cloud and its completion by the completion network",
    _completion_hull(),
    geometric=True,
    style=("#7f2704", "-"),
)
COMPLETION_HULL_SCO_REPLAN = Method(
    "completion_hull_sco_replan",
    "completion_hull_sco replanned after every view on the whole cloud's completion",
    _completion_hull(replan=True),
    geometric=True,
    style=("#a63603", "-."),
    by_default=False,
)
COMPLETION_GAIN = Method(
    "completion_gain",
    "the view contribution of the completed cloud, completed again every view: the predicted "
    "points a view would see (a z-buffer of the whole completed cloud) that no captured view "
    "sees",
    _completion_gain("visibility"),
    geometric=True,
    style=("#006d2c", "-"),
)
COMPLETION_GAIN_AUTHORS = Method(
    "completion_gain_authors",
    "[15]'s view contribution as the seed paper's authors ran it: the predicted points farther "
    "than eps from the captured cloud, counted by hidden-point removal from each view",
    _completion_gain("authors"),
    geometric=True,
    style=("#74c476", "--"),
    by_default=False,
)

#: Every method, in report order.
METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        RANDOM,
        SPREAD,
        ORACLE,
        ORACLE_VIG,
        PCNBV,
        PCNBV_SPH,
        PCNBV_VIG,
        PCNBV_SPH_VIG,
        PCNBV_MATCHED,
        PCNBV_SPH_MATCHED,
        VCNBV,
        VCNBV_MAP,
        HULL_SCO,
        HULL_SCO_SPH,
        HULL_SCO_PROBES,
        HULL_SCO_REPLAN,
        VIG_HULL_SCO,
        VIG_HULL_SCO_MATCHED,
        VIG_HULL_SCO_SPH,
        IG,
        HULL_IG,
        IG_LEARNED,
        IG_AREA_FACTOR,
        IG_PROXIMITY,
        COMPLETION_HULL_SCO,
        COMPLETION_HULL_SCO_REPLAN,
        COMPLETION_GAIN,
        COMPLETION_GAIN_AUTHORS,
    )
}
#: The methods ``python -m nbv.eval`` runs when none are given (``by_default``), in report order.
DEFAULT_METHODS: tuple[str, ...] = tuple(m.name for m in METHODS.values() if m.by_default)
#: The network methods (those that run a trained network of their own): name -> the checkpoint
#: input they need.
NETWORK_INPUTS: dict[str, str] = {
    m.name: m.network_input for m in METHODS.values() if m.network_input is not None
}
#: The geometric planners, in report order (the one-shot plan first: the reconstruction
#: plot's pick).
GEOMETRIC: tuple[str, ...] = tuple(m.name for m in METHODS.values() if m.geometric)
#: The baselines of the coverage comparisons: methods made to raise coverage that read no
#: network, plan nothing and learn no score (random, spread, the oracle), in report order.
BASELINES: tuple[str, ...] = tuple(
    m.name
    for m in METHODS.values()
    if m.network_input is None
    and m.network is None
    and not m.geometric
    and not m.learned_score
    and m.score == "coverage"
)
#: The methods that rank with a learned score file.
SCORED: tuple[str, ...] = tuple(m.name for m in METHODS.values() if m.learned_score)


def method(name: str) -> Method:
    """The registered method ``name``.

    Raises:
        ValueError: no such method (the message lists the registered ones).
    """
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; registered: {', '.join(METHODS)}")
    return METHODS[name]


def networks_of(methods: Iterable[str]) -> tuple[str, ...]:
    """The network methods whose networks ``methods`` run (:attr:`Method.networks`), each once,
    in the order the methods first need them (a network method's own place for itself).

    Raises:
        ValueError: an unregistered method.
    """
    out: dict[str, None] = {}
    for name in methods:
        out.update(dict.fromkeys(method(name).networks))
    return tuple(out)


def check_methods(check: str) -> tuple[str, ...]:
    """The methods a disturbance check applies to, in report order."""
    if check not in CHECKS:
        raise ValueError(f"unknown check {check!r}; allowed: {', '.join(CHECKS)}")
    return tuple(m.name for m in METHODS.values() if check in m.checks)
