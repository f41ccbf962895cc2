"""Episodes in lockstep (nbv.policies.lockstep): a network decides for many episodes in one
batched forward pass, and every episode is the one it would be alone: the same views, for every
network method on the shipped weights in float32, for the disturbance checks, and for the
evaluator's records."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from datagen import make_tiny_dataset
from evalgen import tiny_settings
from tiny_nets import save_tiny_checkpoint

import nbv.dataset
from nbv.assets.weights import shipped_weights
from nbv.eval.disturb import disturbed
from nbv.eval.evaluate import evaluate
from nbv.eval.protocol import episode_rng
from nbv.geometry.camera import Intrinsics
from nbv.policies.conditioned_network import ConditionedPolicy
from nbv.policies.episode import run_episode
from nbv.policies.lockstep import Batchable, EpisodeSpec, run_lockstep
from nbv.policies.method import CHECKS, MethodContext
from nbv.policies.network import NetworkPolicy
from nbv.policies.registry import METHODS, NETWORK_INPUTS
from nbv.policies.two_stage import NetworkThenHullPolicy
from nbv.setcover.settings import SetCoverSettings

STARTS = (0, 1, 3, 7, 10, 15, 24, 27, 30, 32)
VIEWSPACES = ("original", "permuted")
#: The network methods the package ships weights for (the VIG ones may not be shipped yet).
SHIPPED = [m for m in NETWORK_INPUTS if shipped_weights(m) is not None]


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    ds = nbv.dataset.open(make_tiny_dataset(tmp_path_factory.mktemp("lockstep") / "data", 1))
    return ds.model(ds.keys()[0])


@pytest.fixture(scope="module")
def shipped_fp32() -> MethodContext:
    """The shipped networks, every one in float32 (the batched and single forwards may then
    differ only in the last bits of float32 sums). A network method without shipped weights runs
    those of the first shipped one of its input: batching is the code's, not the weights'."""
    networks = {}
    for method, kind in NETWORK_INPUTS.items():
        path = shipped_weights(method) or shipped_weights(
            next(m for m in SHIPPED if NETWORK_INPUTS[m] == kind)
        )
        networks[method] = (
            ConditionedPolicy.from_checkpoint(path)
            if kind.startswith("directions")
            else NetworkPolicy.from_checkpoint(path, n_views=33, precision="fp32")
        )
    return MethodContext(networks, SetCoverSettings(n_samp=2048), Intrinsics.centred(64, 48, 48.0),
                         0.0070710678, 10)  # fmt: skip


def _policies(
    ctx: MethodContext,
    method: str,
    check: str | None = None,
    sigma: float = 0.0,
    seeded_as: str | None = None,
):
    """Every episode's spec of ``method`` (drawing from the generators of ``seeded_as``)."""
    out = []
    for vs in VIEWSPACES:
        for start in STARTS:
            rng = episode_rng(0, seeded_as or method, check or "", vs, start)
            policy = METHODS[method].build(ctx, rng)
            if check is not None:
                policy = disturbed(check, policy, rng, 0.5, sigma)
            out.append(EpisodeSpec(vs, start, policy))
    return out


@pytest.mark.parametrize("method", SHIPPED)
@pytest.mark.slow
def test_every_network_picks_the_views_of_one_at_a_time_inference(model, shipped_fp32, method):
    batched = run_lockstep(model, _policies(shipped_fp32, method))
    single = [run_episode(model, s.viewspace, s.start, s.policy)
              for s in _policies(shipped_fp32, method)]  # fmt: skip
    assert all(isinstance(s.policy, Batchable) for s in _policies(shipped_fp32, method))
    assert len(batched) == len(VIEWSPACES) * len(STARTS)
    for a, b in zip(batched, single, strict=True):
        assert a.views == b.views
        np.testing.assert_array_equal(a.coverage, b.coverage)
        assert len(a.times) == len(b.times) == 9


MATCHED_AND_PLAIN = [
    ("pcnbv_sph_matched", "pcnbv_sph"),
    ("pcnbv_matched", "pcnbv"),
    ("vig_hull_sco_matched", "vig_hull_sco"),
]


@pytest.mark.parametrize(("method", "plain"), MATCHED_AND_PLAIN)
@pytest.mark.slow
def test_a_matched_network_is_the_plain_one_on_its_viewspace(model, shipped_fp32, method, plain):
    """Matched by direction, a network decides as alone on both viewspaces, and exactly as the
    plain network on the viewspace it is trained on (the map is the identity there; a planner's
    draws are seeded as the plain one's)."""
    batched = run_lockstep(model, _policies(shipped_fp32, method, seeded_as=plain))
    single = [run_episode(model, s.viewspace, s.start, s.policy)
              for s in _policies(shipped_fp32, method, seeded_as=plain)]  # fmt: skip
    assert [e.views for e in batched] == [e.views for e in single]
    plain_runs = run_lockstep(model, _policies(shipped_fp32, plain))
    on_original = [i for i, s in enumerate(_policies(shipped_fp32, plain))
                   if s.viewspace == "original"]  # fmt: skip
    assert [batched[i].views for i in on_original] == [plain_runs[i].views for i in on_original]
    off = [i for i in range(len(batched)) if i not in on_original]
    assert [batched[i].views for i in off] != [plain_runs[i].views for i in off]


@pytest.mark.parametrize(
    ("check", "sigma"),
    [("random_cloud", 0.0), ("permuted_state", 0.0), ("position_noise", 0.005)],
)
@pytest.mark.slow
def test_disturbed_networks_draw_and_pick_as_alone(model, shipped_fp32, check, sigma):
    for method in ("pcnbv", "pcnbv_sph"):
        batched = run_lockstep(model, _policies(shipped_fp32, method, check, sigma))
        single = [run_episode(model, s.viewspace, s.start, s.policy)
                  for s in _policies(shipped_fp32, method, check, sigma)]  # fmt: skip
        assert [e.views for e in batched] == [e.views for e in single]


@pytest.mark.slow
def test_mixed_policies_and_one_shot_plans_run_as_alone(model, shipped_fp32):
    """Batched networks beside policies that decide alone (random, a one-shot planner, ig) and
    a two-stage planner (its network's picks batched, its plan made alone)."""
    methods = ("random", "hull_sco", "ig", "pcnbv", "vcnbv_map", "vig_hull_sco")
    specs = lambda: [s for m in methods for s in _policies(shipped_fp32, m)]  # noqa: E731
    mixed = specs()
    batched = run_lockstep(model, mixed)
    single = [run_episode(model, s.viewspace, s.start, s.policy) for s in specs()]
    assert [e.views for e in batched] == [e.views for e in single]
    for a, b in zip(batched, single, strict=True):
        np.testing.assert_array_equal(a.vig, b.vig)
    two_stage = [s.policy for s in mixed if isinstance(s.policy, NetworkThenHullPolicy)]
    assert len(two_stage) == len(VIEWSPACES) * len(STARTS)
    for policy in two_stage:  # two batched network decisions, then one plan of 7 views
        assert len(policy.timings["network"]) == 2 and policy.counts["planned"] == 7


def test_a_bad_start_or_a_visited_pick_is_refused(model, shipped_fp32):
    with pytest.raises(ValueError, match="start view 40 is outside 0..32"):
        run_lockstep(model, [EpisodeSpec("original", 40, METHODS["random"].build(shipped_fp32,
                                          np.random.default_rng(0)))])  # fmt: skip
    with pytest.raises(ValueError, match="chose view 0, visited"):
        run_lockstep(model, [EpisodeSpec("original", 0, lambda state: 0)])


@pytest.mark.slow
def test_the_evaluator_records_the_same_episodes_batched_or_not(tmp_path):
    tiny = {
        "data": make_tiny_dataset(tmp_path / "data"),
        **{name: save_tiny_checkpoint(tmp_path / f"{name}.pt",
                                      "directions_map" if name == "vcnbv_map" else kind)
           for name, kind in NETWORK_INPUTS.items()},
    }  # fmt: skip
    base = tiny_settings(tiny, Path(tmp_path / "batched"), checks=CHECKS, random_repeats=2,
                         plots=False, methods=tuple(METHODS))  # fmt: skip
    one = evaluate(base).records
    two = evaluate(replace(base, run="single", batched=False)).records
    assert len(one) == len(two) > 0
    assert {r.method for r in one} == set(METHODS)
    for a, b in zip(one, two, strict=True):
        assert (a.method, a.check, a.key, a.viewspace, a.start, a.repeat, a.views) == (
            b.method, b.check, b.key, b.viewspace, b.start, b.repeat, b.views)  # fmt: skip
        np.testing.assert_array_equal(a.coverage, b.coverage)
        assert a.notes == b.notes and a.counts == b.counts
