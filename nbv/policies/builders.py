"""How the registry's methods build their policy for one episode: ``(context, rng) -> policy``.

Each function here returns a builder (or is one) that :class:`nbv.policies.method.Method` keeps
in ``build``; the rows of :data:`nbv.policies.registry.METHODS` name them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from nbv.geometry.viewspace import original_viewspace
from nbv.policies.completion import (
    CompletionGainPolicy,
    CompletionHullPolicy,
    CompletionHullReplanPolicy,
)
from nbv.policies.episode import Policy
from nbv.policies.hybrid import HullThenGainPolicy
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.learned_gain import LearnedGainPolicy
from nbv.policies.method import MethodContext, completion_of, scorer_of
from nbv.policies.network import NetworkPolicy
from nbv.policies.reference import OraclePolicy, RandomPolicy, SpreadPolicy
from nbv.policies.setcover import SetCoverPolicy, SetCoverReplanPolicy
from nbv.policies.two_stage import NetworkThenHullPolicy
from nbv.policies.view_matching import MatchedNetworkPolicy

#: A method's builder: the run's context and the episode's generator -> a fresh policy.
Builder = Callable[[MethodContext, np.random.Generator], Policy]


def loaded(ctx: MethodContext, name: str) -> NetworkPolicy:
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


def random(ctx: MethodContext, rng: np.random.Generator) -> Policy:
    """A seeded random unvisited view."""
    return RandomPolicy(rng)


def spread(ctx: MethodContext, rng: np.random.Generator) -> Policy:
    """The unvisited view farthest in angle from the visited ones."""
    return SpreadPolicy(rng)


def oracle(score: str) -> Builder:
    """Greedy by the true gain of ``score`` (``coverage`` or ``vig``)."""
    return lambda ctx, rng: OraclePolicy(score)


def network(name: str) -> Builder:
    """The network method ``name``: a fresh copy of its loaded network."""
    return lambda ctx, rng: loaded(ctx, name)


def matched(name: str) -> Builder:
    """Network ``name`` run by direction on the episode's viewspace: a fresh copy of its loaded
    network behind a map from PC-NBV's 33 views (the viewspace it is trained on)."""
    return lambda ctx, rng: MatchedNetworkPolicy(loaded(ctx, name), original_viewspace())


def conditioned(name: str) -> Builder:
    """A fresh policy of the viewspace-conditioned checkpoint of method ``name``, with a fresh
    occupancy map of the run's ``infogain`` settings (read only by a network of map features; an
    unused one costs nothing: its map is made on its first update)."""
    return lambda ctx, rng: ctx.networks[name].fresh(infogain(ctx, rng))


def setcover_policy(
    ctx: MethodContext,
    rng: np.random.Generator,
    sph: bool = False,
    probes: bool = False,
    replan: bool = False,
) -> SetCoverPolicy:
    """The convex-hull set cover of the run's ``setcover`` settings: on the signature's hull with
    ``sph``, after ``setcover.probes`` random views with ``probes``, replanned every view with
    ``replan``."""
    kind = SetCoverReplanPolicy if replan else SetCoverPolicy
    return kind(
        rng=rng,
        settings=ctx.setcover,
        sph=sph,
        probes=ctx.setcover.probes if probes else 0,
        n_views=ctx.n_views,
        intrinsics=ctx.intrinsics,
        eps=ctx.eps,
    )


def setcover(sph: bool = False, probes: bool = False, replan: bool = False) -> Builder:
    """The builder of :func:`setcover_policy` with these options."""
    return lambda ctx, rng: setcover_policy(ctx, rng, sph=sph, probes=probes, replan=replan)


def two_stage(leader: str, sph: bool, matched: bool = False) -> Builder:
    """The two-stage planner: network ``leader``'s picks for ``setcover.network_views`` decisions
    (its views matched with the episode's by direction with ``matched``), then a one-shot plan
    (on the signature's hull with ``sph``) on the whole cloud."""

    def build(ctx: MethodContext, rng: np.random.Generator) -> Policy:
        network = loaded(ctx, leader)
        if matched:
            network = MatchedNetworkPolicy(network, original_viewspace())
        return NetworkThenHullPolicy(network, setcover_policy(ctx, rng, sph=sph),
                                     ctx.setcover.network_views)  # fmt: skip

    return build


def infogain(ctx: MethodContext, rng: np.random.Generator) -> InfoGainPolicy:
    """Volumetric information gain of the run's ``infogain`` settings (candidate voxels shared)."""
    return InfoGainPolicy(ctx.infogain, ctx.intrinsics, traced=ctx.traced)


def infogain_by(metric: str) -> Builder:
    """:func:`infogain` with the run's ``infogain`` settings but ``metric``."""
    return lambda ctx, rng: InfoGainPolicy(
        dataclasses.replace(ctx.infogain, metric=metric), ctx.intrinsics, traced=ctx.traced
    )


def hull_then_gain(ctx: MethodContext, rng: np.random.Generator) -> Policy:
    """The one-shot hull plan's covering picks, then information gain."""
    return HullThenGainPolicy(setcover_policy(ctx, rng), infogain(ctx, rng))


def learned_gain(ctx: MethodContext, rng: np.random.Generator) -> Policy:
    """Information gain's map, candidates ranked by the context's learned score."""
    return LearnedGainPolicy(ctx.infogain, ctx.intrinsics, traced=ctx.traced,
                             scorer=scorer_of(ctx))  # fmt: skip


def completion_hull(replan: bool = False) -> Builder:
    """The set cover on the hull of the captured cloud and its completion."""
    kind = CompletionHullReplanPolicy if replan else CompletionHullPolicy

    def build(ctx: MethodContext, rng: np.random.Generator) -> Policy:
        return kind(rng=rng, settings=ctx.setcover, n_views=ctx.n_views, intrinsics=ctx.intrinsics,
                    eps=ctx.eps, complete=completion_of(ctx))  # fmt: skip

    return build


def completion_gain(rule: str) -> Builder:
    """The view contribution of the context's completion by ``rule``."""
    return lambda ctx, rng: CompletionGainPolicy(
        completion_of(ctx), ctx.intrinsics, rule=rule, eps=ctx.eps
    )
