"""The registry of view-selection methods: the one table that names them.

Each row is a :class:`~nbv.policies.method.Method`: its name, a one-line summary, how it builds
its policy (:mod:`nbv.policies.builders`), what it needs (a network checkpoint of some input,
another method's network, the ground truth), which disturbance checks apply to it, the score it
is made to raise and whether the evaluation runs it by default. The evaluator, the planner, the
disturbance checks, the report and the plots read :data:`METHODS`, so adding a method is one
row here (and, when it needs one, a builder); docs/development.md, "Adding a method".
"""

from __future__ import annotations

from collections.abc import Iterable

from nbv.policies import builders
from nbv.policies.method import CHECKS, Method
from nbv.utils.declared import look_up

RANDOM = Method(
    "random",
    "a seeded random unvisited view",
    builders.random,
    stochastic=True,
)
SPREAD = Method(
    "spread",
    "the unvisited view farthest in angle from the visited ones (no geometry of the object; "
    "ties broken at random, seeded)",
    builders.spread,
    # Stochastic: on a viewspace of rings most decisions are ties (834 of 1056 on the original
    # viewspace, every start), so an episode is averaged over seeds as random's is.
    stochastic=True,
)
ORACLE = Method(
    "oracle",
    "greedy by the true coverage gain (reads the ground truth: the upper reference)",
    builders.oracle("coverage"),
    ground_truth=True,
)
ORACLE_VIG = Method(
    "oracle_vig",
    "greedy by the true VIG gain (reads the ground truth: the VIG methods' upper reference)",
    builders.oracle("vig"),
    ground_truth=True,
    score="vig",
    # One Qhull run per unvisited view a decision: 0.39 s an episode against pcnbv's 0.40 s on
    # 4 unseen models (2026-12-06), 16 % of the default run's time alone: named only.
    by_default=False,
)
PCNBV = Method(
    "pcnbv",
    "PCNBV on the accumulated cloud (a training checkpoint)",
    builders.network("pcnbv"),
    network_input="points",
    checks=("random_cloud", "permuted_state", "position_noise"),
)
PCNBV_SPH = Method(
    "pcnbv_sph",
    "PCNBV on the cloud's spherical-harmonics signature (a training checkpoint)",
    builders.network("pcnbv_sph"),
    network_input="signature",
    checks=("random_cloud", "permuted_state", "position_noise"),
)
PCNBV_VIG = Method(
    "pcnbv_vig",
    "PCNBV on the accumulated cloud, trained on VIG (a checkpoint of `python -m train score=vig`)",
    builders.network("pcnbv_vig"),
    network_input="points",
    score="vig",
    # PCNBV's forwards are the costliest decisions of the default run (issue 41): named only.
    by_default=False,
)
PCNBV_SPH_VIG = Method(
    "pcnbv_sph_vig",
    "PCNBV on the cloud's spherical signature, trained on VIG (a checkpoint of `python -m train "
    "score=vig model=pcnbv_sph`)",
    builders.network("pcnbv_sph_vig"),
    network_input="signature",
    score="vig",
)
PCNBV_MATCHED = Method(
    "pcnbv_matched",
    "PCNBV's network on the episode's viewspace, its view state and gains matched with its "
    "training views by direction",
    builders.matched("pcnbv"),
    network="pcnbv",
    matched=True,
    # Identical to pcnbv on the original viewspace; PCNBV's forwards are the costliest of the
    # default run (issue 41): named only.
    by_default=False,
)
PCNBV_SPH_MATCHED = Method(
    "pcnbv_sph_matched",
    "PCNBV-sph's network on the episode's viewspace, its view state and gains matched with its "
    "training views by direction",
    builders.matched("pcnbv_sph"),
    network="pcnbv_sph",
    matched=True,
)
VCNBV = Method(
    "vcnbv",
    "the viewspace-conditioned network: scores each candidate from its direction (a checkpoint "
    "of train.conditioned)",
    builders.conditioned("vcnbv"),
    network_input="directions",
)
VCNBV_MAP = Method(
    "vcnbv_map",
    "vcnbv whose head also reads each candidate's map features on ig's occupancy map (a "
    "checkpoint of train.conditioned map_features=true)",
    builders.conditioned("vcnbv_map"),
    network_input="directions",
)
HULL_SCO = Method(
    "hull_sco",
    "convex-hull set cover, one-shot from the start view's cloud",
    builders.setcover(),
    checks=("random_hull", "position_noise"),
    geometric=True,
)
HULL_SCO_SPH = Method(
    "hull_sco_sph",
    "convex-hull set cover on the hull of the cloud's spherical signature",
    builders.setcover(sph=True),
    checks=("position_noise",),
    geometric=True,
)
HULL_SCO_PROBES = Method(
    "hull_sco_probes",
    "hull_sco after `setcover.probes` random probe views",
    builders.setcover(probes=True),
    geometric=True,
)
VIG_HULL_SCO = Method(
    "vig_hull_sco",
    "the paper's two-stage planner: pcnbv_sph_vig picks `setcover.network_views` views, then "
    "hull_sco plans the rest on the hull of the whole cloud",
    builders.two_stage(PCNBV_SPH_VIG.name, sph=False),
    network=PCNBV_SPH_VIG.name,
    geometric=True,
    score="vig",
)
VIG_HULL_SCO_MATCHED = Method(
    "vig_hull_sco_matched",
    "vig_hull_sco with pcnbv_sph_vig's views matched with the episode's viewspace by direction",
    builders.two_stage(PCNBV_SPH_VIG.name, sph=False, matched=True),
    network=PCNBV_SPH_VIG.name,
    matched=True,
    geometric=True,
    score="vig",
)
VIG_HULL_SCO_SPH = Method(
    "vig_hull_sco_sph",
    "vig_hull_sco planning on the hull of the whole cloud's spherical signature",
    builders.two_stage(PCNBV_SPH_VIG.name, sph=True),
    network=PCNBV_SPH_VIG.name,
    geometric=True,
    score="vig",
)
HULL_SCO_REPLAN = Method(
    "hull_sco_replan",
    "convex-hull set cover replanned on the whole cloud after every view",
    builders.setcover(replan=True),
    geometric=True,
)
IG = Method(
    "ig",
    "volumetric information gain on an occupancy map of the captured views, replanned every view",
    builders.infogain,
    checks=("position_noise",),
    geometric=True,
)
HULL_IG = Method(
    "hull_ig",
    "hull_sco's covering picks (its fill left out), then ig on the occupancy map",
    builders.hull_then_gain,
    geometric=True,
)

IG_LEARNED = Method(
    "ig_learned",
    "ig's occupancy map, candidates ranked by a perceptron over their rays' map features",
    builders.learned_gain,
    checks=("position_noise",),
    geometric=True,
    learned_score=True,
)
IG_AREA_FACTOR = Method(
    "ig_area_factor",
    "ig with Vasquez-Gomez et al.'s Area Factor: a view is best when a set share of its rays "
    "meets the captured surface and the unknown layer around it",
    builders.infogain_by("area_factor"),
    checks=("position_noise",),
    geometric=True,
)
IG_PROXIMITY = Method(
    "ig_proximity",
    "ig with Proximity Count: unknown voxels weighted by their closeness to the captured surface",
    builders.infogain_by("proximity_count"),
    checks=("position_noise",),
    geometric=True,
)
COMPLETION_HULL_SCO = Method(
    "completion_hull_sco",
    "the paper's completed hull: convex-hull set cover, one-shot from the start view, on the "
    "hull of the cloud and its completion by the completion network",
    builders.completion_hull(),
    geometric=True,
)
COMPLETION_HULL_SCO_REPLAN = Method(
    "completion_hull_sco_replan",
    "completion_hull_sco replanned after every view on the whole cloud's completion",
    builders.completion_hull(replan=True),
    geometric=True,
    by_default=False,
)
COMPLETION_GAIN = Method(
    "completion_gain",
    "the view contribution of the completed cloud, completed again every view: the predicted "
    "points a view would see (a z-buffer of the whole completed cloud) that no captured view "
    "sees",
    builders.completion_gain("visibility"),
    geometric=True,
)
COMPLETION_GAIN_AUTHORS = Method(
    "completion_gain_authors",
    "[15]'s view contribution as the seed paper's authors ran it: the predicted points farther "
    "than eps from the captured cloud, counted by hidden-point removal from each view",
    builders.completion_gain("authors"),
    geometric=True,
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
    return look_up(METHODS, name, "method", "registered")


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
