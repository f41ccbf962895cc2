"""Ranking quality (``nbv.eval.ranking``): the states are the oracle's, every method's scores are
the ones it picks by, Spearman agrees with a brute-force rank correlation, the summary's exact
values on hand-made records, and the real command on a small dataset."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from datagen import make_tiny_dataset
from tiny_nets import save_tiny_checkpoint

import nbv.dataset
from nbv.eval.config import EvalSettings
from nbv.eval.ranking import RANKED, oracle_states, ranking, reliability_summary, summary
from nbv.policies.method import MethodContext
from nbv.policies.reference import OraclePolicy
from nbv.policies.registry import METHODS, NETWORK_INPUTS
from nbv.scan.shipped import with_shipped
from nbv.utils.ranking import spearman, spearman_per_sample, split_half_reliability

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("ranking")
    return {
        "data": make_tiny_dataset(tmp / "data", models=2),
        "pcnbv": save_tiny_checkpoint(tmp / "pcnbv.pt", "points"),
        "pcnbv_sph": save_tiny_checkpoint(tmp / "pcnbv_sph.pt", "signature"),
        "pcnbv_vig": save_tiny_checkpoint(tmp / "pcnbv_vig.pt", "points", seed=1),
        "pcnbv_sph_vig": save_tiny_checkpoint(tmp / "pcnbv_sph_vig.pt", "signature", seed=1),
        "vcnbv": save_tiny_checkpoint(tmp / "vcnbv.pt", "directions"),
        "vcnbv_map": save_tiny_checkpoint(tmp / "vcnbv_map.pt", "directions_map"),
    }


def _brute_spearman(p: np.ndarray, t: np.ndarray) -> float:
    """Pearson correlation of average ranks, ranks counted by hand."""

    def ranks(x):
        return np.array([np.sum(x < v) + (np.sum(x == v) + 1) / 2 for v in x])

    a, b = ranks(p) - ranks(p).mean(), ranks(t) - ranks(t).mean()
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))


def test_spearman_agrees_with_brute_force_ranks_and_skips_what_has_none():
    rng = np.random.default_rng(3)
    pred = rng.integers(0, 5, size=(40, 9)).astype(float)  # ties on purpose
    target = rng.integers(0, 4, size=(40, 9)).astype(float)
    state = rng.random((40, 9)) < 0.3
    target[0] = 2.0  # constant target: no ranks
    state[1] = True
    state[1, 4] = False  # one unvisited view: no ranks
    got = spearman_per_sample(pred, target, state)
    assert np.isnan(got[0]) and np.isnan(got[1])
    for i in range(2, 40):
        free = ~state[i]
        if np.ptp(pred[i][free]) and np.ptp(target[i][free]):
            assert got[i] == pytest.approx(_brute_spearman(pred[i][free], target[i][free]))
    assert spearman(pred, target, state) == pytest.approx(np.nanmean(got))
    assert spearman(target, target, state) == pytest.approx(1.0)


def test_the_states_are_the_oracles_episode(tiny):
    ds = nbv.dataset.open(tiny["data"])
    model = ds.model(ds.keys()[0])
    states = oracle_states(model, "permuted", 24, 10)
    assert [len(s.order) for s in states] == list(range(1, 10)) and states[0].order == [24]
    oracle = OraclePolicy("coverage")

    def truth(score, view_state):
        return model.view_gains("permuted", score, view_state)

    for before, after in zip(states[:-1], states[1:], strict=True):
        assert before.true_gains is None  # the ranked methods are given no ground truth
        assert after.order == [*before.order, oracle(dataclasses.replace(before, true_gains=truth))]
        assert np.array_equal(np.flatnonzero(after.view_state), sorted(after.order))


@pytest.mark.parametrize("name", RANKED)
@pytest.mark.slow
def test_every_ranked_method_picks_the_best_of_its_view_scores(tiny, name):
    ds = nbv.dataset.open(tiny["data"])
    model = ds.model(ds.keys()[1])
    settings = EvalSettings(run="unused", progress=False, methods=RANKED,
                            checkpoints={n: str(tiny[n]) for n in NETWORK_INPUTS})  # fmt: skip
    from nbv.eval.inputs import load_networks

    networks, skipped = load_networks(settings, 33)
    assert not skipped
    ctx = MethodContext(networks, settings.setcover, ds.intrinsics, float(ds.attrs["eps"]), 10)
    ctx = with_shipped(ctx)
    scoring = METHODS[name].build(ctx, np.random.default_rng(5))
    picking = METHODS[name].build(ctx, np.random.default_rng(5))
    for state in oracle_states(model, "original", 1, 10):
        scores = scoring.view_scores(state)
        assert scores.shape == (33,)
        if name == "random":  # its scores rank at random; its picks are a random choice
            continue
        best = np.where(state.view_state, -np.inf, scores)
        assert best[picking(state)] == best.max()


@pytest.mark.slow
def test_split_half_reliability_on_gains_with_known_order():
    rng = np.random.default_rng(0)
    # Views 1-3 add 0, 1,000 and 3,000 of 4,000 points to view 0's: any split keeps the order.
    covered = np.zeros((4, 4000), dtype=bool)
    covered[0, :1000], covered[2, 1000:2000], covered[3, 1000:] = True, True, True
    covered[1, :1000] = True  # nothing new
    visited = np.array([True, False, False, False])
    assert split_half_reliability(covered, visited, rng) == pytest.approx(1.0)
    # Twenty views that each cover every point with the same chance, 1 in 400: what orders their
    # gains is the draw alone, and the two halves' draws are independent. One state's value is
    # noisy (about 0.3 with 20 views); the mean over 100 such states is 0 within 0.1.
    values = []
    for _ in range(100):
        noise = rng.random((21, 20_000)) < 2.5e-3
        values.append(split_half_reliability(noise, np.arange(21) == 0, rng, splits=10))
    assert abs(np.mean(values)) < 0.1
    # Views that all add alike (or fewer than two unvisited ones): no ranks, NaN.
    assert np.isnan(split_half_reliability(covered[[0, 1, 1]], visited[:3], rng))
    assert np.isnan(split_half_reliability(covered, np.array([True, True, True, False]), rng))


def test_summary_exact_on_hand_made_records():
    def record(model, cat, a, s, hit, captured=1, truth=None, viewspace="original"):
        return {"model": model, "category": cat, "viewspace": viewspace,
                "spearman": {"a": a, "spread": s},
                "hit": {"a": hit, "spread": False}, "captured": captured,
                "truth_reliability": truth}  # fmt: skip

    records = [record("m1", "x", 0.5, 0.25, True, 1, 0.9), record("m1", "x", None, 0.5, False, 2),
               record("m2", "y", 1.0, 0.0, True, 1, 0.7),
               record("m2", "y", 0.0, None, False, 2, 0.2)]  # fmt: skip
    rows = {r["method"]: r for r in summary(records, ("spread", "a"))}
    assert rows["a"]["states"] == 3 and rows["spread"]["states"] == 3
    assert rows["a"]["spearman"].mean == pytest.approx(0.5)
    assert rows["a"]["minus_spread"].mean == pytest.approx(((0.5 - 0.25) + (1.0 - 0.0)) / 2)
    assert rows["a"]["hits"] == 0.5 and rows["spread"]["hits"] == 0.0
    assert rows["a"]["by"] == "category" and rows["a"]["by_group"] == {"x": 0.5, "y": 0.5}
    one = [{**r, "category": "default"} for r in records]  # a mesh folder: per model
    assert summary(one, ("a",))[0]["by_group"] == {"m1": 0.5, "m2": 0.5}
    assert "minus_spread" not in rows["spread"]
    assert rows["a"]["by_captured"] == {1: 0.75, 2: 0.0}
    assert rows["spread"]["by_captured"] == {1: 0.125, 2: 0.5}
    truth = reliability_summary(records)
    assert truth["states"] == 3 and truth["mean"].mean == pytest.approx(0.6)
    assert truth["by_captured"] == pytest.approx({1: 0.8, 2: 0.2})
    assert reliability_summary([{**r, "truth_reliability": None} for r in records]) is None
    # A second viewspace: each viewspace's rows are the summary of its states alone.
    permuted = [record("m1", "x", -0.5, 0.5, False, 1, None, "permuted"),
                record("m2", "y", 0.0, 0.25, False, 1, None, "permuted")]  # fmt: skip
    both = {r["method"]: r for r in summary(records + permuted, ("spread", "a"))}
    assert list(both["a"]["by_viewspace"]) == ["original", "permuted"]
    for name in ("a", "spread"):
        assert both[name]["by_viewspace"]["original"] == rows[name]["spearman"]
    assert both["a"]["minus_spread_by_viewspace"]["original"] == rows["a"]["minus_spread"]
    assert both["a"]["by_viewspace"]["permuted"].mean == pytest.approx(-0.25)
    assert both["spread"]["by_viewspace"]["permuted"].mean == pytest.approx(0.375)
    assert both["a"]["minus_spread_by_viewspace"]["permuted"].mean == pytest.approx(-0.625)
    assert both["a"]["spearman"].mean == pytest.approx((0.5 + 1.0 + 0.0 - 0.5 + 0.0) / 5)
    assert both["a"]["by_captured_viewspace"] == {"original": {1: 0.75, 2: 0.0},
                                                  "permuted": {1: -0.25}}  # fmt: skip


def test_ranking_is_deterministic_and_leaves_out_states_without_ranks(tiny):
    settings = EvalSettings(run="unused", data_dir=tiny["data"], start_views=(1,),
                            methods=("random", "spread", "ig"), progress=False)  # fmt: skip
    first, again = ranking(settings), ranking(settings)
    assert first == again
    assert len(first) == 2 * 2 * 9  # models x viewspaces x states of one episode
    ds = nbv.dataset.open(tiny["data"])
    for r in first:
        model = ds.model(r["model"])
        state = oracle_states(model, r["viewspace"], r["start"], 10)[r["captured"] - 1]
        gains = nbv.dataset.records.score_functions(model, "coverage", r["viewspace"])[0]
        if np.ptp(gains(state.view_state)[~state.view_state]) == 0:  # no ranks to agree with
            assert set(r["spearman"].values()) == {None}
    assert sum(r["spearman"]["ig"] is None for r in first) < len(first) / 2


@pytest.mark.slow
def test_the_command_writes_its_tables_and_refuses_methods_without_scores(tiny, tmp_path):
    base = [sys.executable, "-m", "nbv.eval.ranking", f"data_dir={tiny['data']}"]
    out = tmp_path / "rank"
    bad = subprocess.run([*base, "methods=[spread,hull_sco]", f"out={out}"],
                         capture_output=True, text=True, cwd=ROOT)  # fmt: skip
    assert bad.returncode == 2
    last = bad.stderr.strip().splitlines()[-1]
    assert last.startswith("nbv.eval.ranking: methods ['hull_sco'] have no per-view scores; "
                           "allowed: random, spread")  # fmt: skip
    assert not out.exists()  # the refused run left no folder
    done = subprocess.run(
        [*base, "limit=1", f"out={out}", "methods=[spread,vcnbv_map]",
         f"checkpoints.vcnbv_map={tiny['vcnbv_map']}"],
        capture_output=True, text=True, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "vcnbv_map: Spearman" in (out / "ranking.log").read_text()
    table = (out / "ranking.md").read_text()
    assert table.startswith("| method | states | Spearman [95 %] |") and "| vcnbv_map |" in table
    states = json.loads((out / "ranking.json").read_text())["states"]
    assert len(states) == 2 * 8 * 9
    values = [s["spearman"]["vcnbv_map"] for s in states if s["spearman"]["vcnbv_map"] is not None]
    assert f"{np.mean(values):+.3f}" in table
    assert "Spearman by views captured, and the split-half reliability" in table
    assert ("| method | original | original minus spread | permuted | permuted minus spread |"
            in table)  # fmt: skip
    assert "| method | 1 | 2 | 3 | 4 | 5 | 6 | 7 | 8 | 9 |" in table
    first = [s["spearman"]["vcnbv_map"] for s in states if s["captured"] == 1]
    row = next(line for line in table.splitlines()
               if line.startswith("| vcnbv_map |") and line.count("|") == 11)  # fmt: skip
    assert row.split(" | ")[1] == f"{np.nanmean(np.array(first, dtype=float)):.2f}"
    assert "| true gains' split-half reliability |" in table
    permuted = [s["spearman"]["vcnbv_map"] for s in states
                if s["captured"] == 1 and s["viewspace"] == "permuted"]  # fmt: skip
    row = next(line for line in table.splitlines() if line.startswith("| vcnbv_map, permuted |"))
    assert row.split(" | ")[1] == f"{np.nanmean(np.array(permuted, dtype=float)):.2f}"
