"""The method registry: every method builds a fresh policy of its kind from one context, and the
lists that the evaluator, the checks and the report read are derived from it."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from datagen import SMALL_CAMERA

from nbv.assets.weights import SHIPPED_SCORER
from nbv.infogain.gain_scorer import GainScorer, load_scorer
from nbv.infogain.view_features import FEATURES
from nbv.policies.conditioned_network import ConditionedPolicy
from nbv.policies.hybrid import HullThenGainPolicy
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.learned_gain import LearnedGainPolicy
from nbv.policies.method import CHECKS, Method, MethodContext
from nbv.policies.network import NetworkPolicy
from nbv.policies.reference import OraclePolicy, RandomPolicy, SpreadPolicy
from nbv.policies.registry import (
    BASELINES,
    DEFAULT_METHODS,
    GEOMETRIC,
    METHODS,
    NETWORK_INPUTS,
    SCORED,
    check_methods,
    method,
    networks_of,
)
from nbv.policies.setcover import SetCoverPolicy, SetCoverReplanPolicy
from nbv.policies.two_stage import NetworkThenHullPolicy
from nbv.scan.shipped import resolve_weights, with_shipped
from nbv.setcover.settings import SetCoverSettings


def _context(setcover: SetCoverSettings | None = None) -> MethodContext:
    # Stand-ins for the networks' models: building a policy reads no weights (a PCNBV's number
    # of outputs only, which its views matched by direction check).
    pcnbv_model = SimpleNamespace(config=SimpleNamespace(n_views=33))
    networks = {
        name: ConditionedPolicy(model=object())
        if kind == "directions"
        else NetworkPolicy(model=pcnbv_model, input=kind)
        for name, kind in NETWORK_INPUTS.items()
    }
    ctx = MethodContext(networks, setcover or SetCoverSettings(), SMALL_CAMERA, 0.02, 7)
    return with_shipped(ctx)


def test_every_method_builds_a_fresh_policy_of_its_kind():
    ctx = _context(SetCoverSettings(n_samp=123, probes=2, lmax=1))
    kinds = {}
    for name, m in METHODS.items():
        assert m.name == name
        first = m.build(ctx, np.random.default_rng(0))
        second = m.build(ctx, np.random.default_rng(0))
        assert first is not second and first.timings == {} and first.timings is not second.timings
        kinds[name] = type(first)
    assert kinds["random"] is RandomPolicy and kinds["oracle"] is OraclePolicy
    assert kinds["spread"] is SpreadPolicy
    assert kinds["pcnbv"] is NetworkPolicy and kinds["pcnbv_sph"] is NetworkPolicy
    # The oracles: greedy by the true coverage gain, and by the true VIG gain.
    assert METHODS["oracle"].build(ctx, None).score == "coverage"
    assert (
        kinds["oracle_vig"] is OraclePolicy
        and METHODS["oracle_vig"].build(ctx, None).score == "vig"
    )
    # Each network method runs its own loaded network (a fresh copy: its own timings).
    for name in NETWORK_INPUTS:
        policy = METHODS[name].build(ctx, np.random.default_rng(0))
        assert policy.model is ctx.networks[name].model and policy is not ctx.networks[name]
    # The two-stage planners: pcnbv_sph_vig's network, then the one-shot planner on the run's
    # hull settings (the signature's hull for the sph one), after setcover.network_views picks.
    for name, sph in (("vig_hull_sco", False), ("vig_hull_sco_sph", True)):
        policy = METHODS[name].build(ctx, np.random.default_rng(0))
        assert kinds[name] is NetworkThenHullPolicy and policy.network_views == 2
        assert policy.network.model is ctx.networks["pcnbv_sph_vig"].model
        assert type(policy.hull) is SetCoverPolicy and policy.hull.sph is sph
        assert policy.hull.settings is ctx.setcover and policy.hull.probes == 0
        assert policy.hull.n_views == 7 and policy.hull.eps == 0.02
    three = dataclasses.replace(ctx, setcover=SetCoverSettings(network_views=3))
    assert METHODS["vig_hull_sco"].build(three, np.random.default_rng(0)).network_views == 3
    # Without its network loaded, a method that runs one says which.
    bare = dataclasses.replace(ctx, networks={})
    for name in ("pcnbv", "vig_hull_sco"):
        with pytest.raises(ValueError, match="give checkpoints.pcnbv"):
            METHODS[name].build(bare, np.random.default_rng(0))
    assert kinds["vcnbv"] is ConditionedPolicy
    assert kinds["hull_sco_replan"] is SetCoverReplanPolicy
    for name in ("hull_sco", "hull_sco_sph", "hull_sco_probes"):
        assert kinds[name] is SetCoverPolicy
    # The planners share the context's settings; only the probing one takes probe views and
    # only the signature one plans on the signature.
    assert kinds["ig"] is InfoGainPolicy and kinds["hull_ig"] is HullThenGainPolicy
    assert kinds["ig_learned"] is LearnedGainPolicy
    # The commands give the shipped scorer (with_shipped); a context with none is refused.
    shipped = METHODS["ig_learned"].build(ctx, np.random.default_rng(0)).scorer
    assert shipped.info == load_scorer(SHIPPED_SCORER).info
    bare_scorer = dataclasses.replace(ctx, scorer=None)
    with pytest.raises(ValueError, match="no learned score given"):
        METHODS["ig_learned"].build(bare_scorer, np.random.default_rng(0))
    own = GainScorer((np.ones((len(FEATURES), 1)),), (np.zeros(1),))
    given = dataclasses.replace(ctx, scorer=own)
    assert METHODS["ig_learned"].build(given, np.random.default_rng(0)).scorer is own
    ig = METHODS["ig"].build(ctx, np.random.default_rng(0))
    assert ig.settings == ctx.infogain and ig.intrinsics == SMALL_CAMERA
    # The field's volumetric baselines: ig with the run's settings but their own metric, on
    # the run's shared candidate voxels.
    for name, metric in (("ig_area_factor", "area_factor"), ("ig_proximity", "proximity_count")):
        policy = METHODS[name].build(ctx, np.random.default_rng(0))
        assert kinds[name] is InfoGainPolicy and policy.traced is ctx.traced
        assert policy.settings == dataclasses.replace(ctx.infogain, metric=metric)
        assert policy.intrinsics == SMALL_CAMERA
    # Spread breaks its ties with the episode's generator (the same draws for the same seed).
    spread = METHODS["spread"].build(ctx, np.random.default_rng(4))
    assert spread.rng.random() == np.random.default_rng(4).random()
    assert spread.counts == {"decisions": 0, "ties": 0}
    for name in [p for p in GEOMETRIC if p.startswith("hull_sco")]:
        policy = METHODS[name].build(ctx, np.random.default_rng(0))
        assert policy.settings.n_samp == 123 and policy.n_views == 7 and policy.eps == 0.02
        assert policy.intrinsics == SMALL_CAMERA
        assert policy.probes == (2 if name == "hull_sco_probes" else 0)
        assert policy.sph == (name == "hull_sco_sph")


def test_derived_lists_follow_the_entries():
    assert list(METHODS) == [
        "random", "spread", "oracle", "oracle_vig", "pcnbv", "pcnbv_sph", "pcnbv_vig",
        "pcnbv_sph_vig", "pcnbv_matched", "pcnbv_sph_matched", "vcnbv", "vcnbv_map", "hull_sco",
        "hull_sco_sph", "hull_sco_probes", "hull_sco_replan", "vig_hull_sco",
        "vig_hull_sco_matched", "vig_hull_sco_sph",
        "ig", "hull_ig", "ig_learned", "ig_area_factor", "ig_proximity", "completion_hull_sco",
        "completion_hull_sco_replan", "completion_gain", "completion_gain_authors",
    ]  # fmt: skip
    assert NETWORK_INPUTS == {"pcnbv": "points", "pcnbv_sph": "signature", "pcnbv_vig": "points",
                              "pcnbv_sph_vig": "signature", "vcnbv": "directions",
                              "vcnbv_map": "directions"}  # fmt: skip
    assert GEOMETRIC == (
        "hull_sco", "hull_sco_sph", "hull_sco_probes", "hull_sco_replan", "vig_hull_sco",
        "vig_hull_sco_matched", "vig_hull_sco_sph", "ig", "hull_ig", "ig_learned", "ig_area_factor",
        "ig_proximity", "completion_hull_sco", "completion_hull_sco_replan", "completion_gain",
        "completion_gain_authors",
    )  # fmt: skip
    # Every method runs by default but the point network trained on VIG, the VIG oracle and
    # PCNBV matched by direction (the costliest decisions of the default run after pcnbv's, and
    # as costly), and the completion planners' variants (replanned; [15]'s rule).
    assert DEFAULT_METHODS == tuple(
        m for m in METHODS if m not in ("oracle_vig", "pcnbv_vig", "pcnbv_matched",
                                        "completion_hull_sco_replan", "completion_gain_authors")
    )  # fmt: skip
    # The methods made to raise VIG; the coverage baselines leave the VIG oracle out.
    assert [m.name for m in METHODS.values() if m.score == "vig"] == [
        "oracle_vig",
        "pcnbv_vig",
        "pcnbv_sph_vig",
        "vig_hull_sco",
        "vig_hull_sco_matched",
        "vig_hull_sco_sph",
    ]
    assert BASELINES == ("random", "spread", "oracle")
    # A method led by another's network names a network method; the networks each run.
    led = {m.name: m.network for m in METHODS.values() if m.network is not None}
    assert led == {
        "pcnbv_matched": "pcnbv",
        "pcnbv_sph_matched": "pcnbv_sph",
        "vig_hull_sco": "pcnbv_sph_vig",
        "vig_hull_sco_matched": "pcnbv_sph_vig",
        "vig_hull_sco_sph": "pcnbv_sph_vig",
    }
    assert [m.name for m in METHODS.values() if m.matched] == [
        "pcnbv_matched",
        "pcnbv_sph_matched",
        "vig_hull_sco_matched",
    ]
    # Of these, the two-stage planner does not score every view as a network does.
    assert [m.name for m in METHODS.values() if m.matched_network] == [
        "pcnbv_matched",
        "pcnbv_sph_matched",
    ]
    assert networks_of(
        ["random", "vig_hull_sco", "pcnbv", "pcnbv_sph_vig", "vig_hull_sco_sph"]
    ) == ("pcnbv_sph_vig", "pcnbv")
    assert networks_of(DEFAULT_METHODS) == tuple(n for n in NETWORK_INPUTS if n != "pcnbv_vig")
    # Random and spread pick at random (spread among its ties): averaged over seeds.
    assert [m.name for m in METHODS.values() if m.stochastic] == ["random", "spread"]
    assert check_methods("position_noise")[-3:] == ("ig_learned", "ig_area_factor",
                                                    "ig_proximity")  # fmt: skip
    assert [m.name for m in METHODS.values() if m.ground_truth] == ["oracle", "oracle_vig"]
    assert SCORED == ("ig_learned",)
    assert check_methods("random_cloud") == ("pcnbv", "pcnbv_sph")
    assert check_methods("permuted_state") == ("pcnbv", "pcnbv_sph")
    assert check_methods("random_hull") == ("hull_sco",)
    for m in METHODS.values():
        assert set(m.checks) <= set(CHECKS)


def test_every_method_is_drawn_in_its_own_colour():
    from nbv.eval.plots import STYLES

    assert set(STYLES) == set(METHODS)  # no style for a method that is gone
    assert all(len(style) == 2 for style in STYLES.values())
    # Every method has its own colour, so that the plots tell them apart.
    assert len({colour for colour, _ in STYLES.values()}) == len(METHODS)


def test_unknown_names_are_refused_with_the_registered_ones():
    assert method("hull_sco") is METHODS["hull_sco"]
    with pytest.raises(ValueError, match="registered: random, spread, oracle, oracle_vig"):
        method("spread_out")
    with pytest.raises(ValueError, match="unknown method 'dqn'"):
        networks_of(["pcnbv", "dqn"])
    build = METHODS["random"].build
    with pytest.raises(ValueError, match="score='volume'"):
        Method("m", "", build, score="volume")
    with pytest.raises(ValueError, match="runs its own network"):
        Method("m", "", build, network_input="points", network="pcnbv")
    with pytest.raises(ValueError, match="allowed: random_cloud, permuted_state, random_hull"):
        check_methods("noise")


def test_a_network_method_runs_its_checkpoint_else_the_shipped_weights(tmp_path, caplog):
    from nbv.assets.weights import shipped_weights

    mine = tmp_path / "best.pt"
    mine.write_bytes(b"")
    assert resolve_weights("pcnbv", mine) == mine
    with caplog.at_level("INFO", logger="nbv.scan.shipped"):
        assert resolve_weights("pcnbv", tmp_path / "missing.pt") == shipped_weights("pcnbv")
    assert "using the shipped weights" in caplog.text and "missing.pt" in caplog.text
    assert resolve_weights("pcnbv", None) == shipped_weights("pcnbv")
    with pytest.raises(ValueError, match="runs no network"):
        resolve_weights("ig", None)


def test_the_vig_networks_fall_back_to_their_own_shipped_file(tmp_path, monkeypatch):
    import nbv.assets.weights

    # An empty weights folder: no shipped file yet, the clear error naming the method.
    monkeypatch.setattr(nbv.assets.weights, "FOLDER", tmp_path)
    for name in ("pcnbv_vig", "pcnbv_sph_vig"):
        with pytest.raises(ValueError, match=f"method={name} needs trained weights"):
            resolve_weights(name, tmp_path / "missing.pt")
        (tmp_path / f"{name}.pt").write_bytes(b"")
        assert resolve_weights(name, tmp_path / "missing.pt") == tmp_path / f"{name}.pt"
    with pytest.raises(ValueError, match="runs no network"):
        resolve_weights("vig_hull_sco", None)  # it runs pcnbv_sph_vig's: that method's weights


def test_load_gives_the_policy_of_the_method_input():
    from nbv.policies.registry import METHODS

    for name in ("pcnbv", "pcnbv_sph", "vcnbv", "vcnbv_map"):
        m = METHODS[name]
        assert m.load(resolve_weights(name, None), 33).input == m.network_input


def test_every_policy_has_the_attributes_the_policy_protocol_declares():
    from nbv.policies.episode import Policy

    declared = Policy.__annotations__
    assert set(declared) == {"timings", "notes", "counts", "last_gains"}
    for name, m in METHODS.items():
        policy = m.build(_context(), np.random.default_rng(0))
        for attribute in declared:
            value = getattr(policy, attribute)  # no getattr default: every policy has it
            assert isinstance(value, dict | list), (name, attribute)
        assert not policy.last_gains and all(v == 0 for v in policy.counts.values()), name


def test_completion_methods_use_the_contexts_completion_or_the_shipped_network():
    from nbv.models.completion_inference import Completer
    from nbv.policies.completion import CompletionGainPolicy, CompletionHullPolicy
    from nbv.policies.method import completion_of

    def truth(cloud):
        return cloud

    ctx = _context(None)
    ctx = dataclasses.replace(ctx, completion=truth)
    gain = METHODS["completion_gain"].build(ctx, np.random.default_rng(0))
    assert isinstance(gain, CompletionGainPolicy) and gain.complete is truth
    assert gain.rule == "visibility" and gain.eps == 0.02
    assert METHODS["completion_gain_authors"].build(ctx, np.random.default_rng(0)).rule == "authors"
    hull = METHODS["completion_hull_sco"].build(ctx, np.random.default_rng(0))
    assert isinstance(hull, CompletionHullPolicy) and hull.complete is truth
    assert hull.n_views == 7 and hull.intrinsics == SMALL_CAMERA
    shipped = completion_of(_context(None))
    first = shipped.completer()
    assert isinstance(first, Completer) and shipped.completer() is first  # loaded once
    assert first.fill > 0  # the shipped network's validation CD-L1
    with pytest.raises(ValueError, match="no completion network given"):
        completion_of(dataclasses.replace(ctx, completion=None))
