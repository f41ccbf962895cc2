"""The evaluator end to end on a tiny dataset: outputs, skipped methods, disturbance checks,
the timing table, mesh folders (a flat mesh among them), and refused configurations."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from datagen import SMALL_CAMERA, make_tiny_dataset, write_meshes
from evalgen import STARTS, tiny_settings
from tiny_nets import save_tiny_checkpoint

import nbv.dataset
from nbv.assets.weights import SHIPPED_SCORER
from nbv.eval.config import (
    ENTRY,
    DisturbSettings,
    EvalConfigError,
    EvalSettings,
    PrepareSettings,
)
from nbv.eval.disturb import auc_changes, disturbed, permuted_state, random_ball
from nbv.eval.evaluate import evaluate, run
from nbv.eval.inputs import EvalDataError
from nbv.eval.metric_tables import metrics_tables, tie_lines
from nbv.eval.prepare import prepare_meshes
from nbv.eval.protocol import episode_rng
from nbv.eval.statistics import (
    episode_values,
    groups,
    paired_metric,
    run_statistics,
    summaries,
)
from nbv.eval.timing import PAPER_TIMES, paper_ratios, timing_table
from nbv.geometry.reconstruction_metrics import cloud_scores
from nbv.geometry.scores import coverage_from_bits
from nbv.geometry.viewspace import spread_views
from nbv.infogain.gain_scorer import GainScorer, ScorerError, save_scorer
from nbv.infogain.settings import InfoGainSettings
from nbv.infogain.view_features import FEATURES
from nbv.policies.episode import auc, run_episode
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.method import CHECKS, MethodContext
from nbv.policies.network import NetworkPolicy
from nbv.policies.registry import DEFAULT_METHODS, GEOMETRIC, check_methods
from nbv.policies.registry import METHODS as METHODS_BY_NAME
from nbv.scan.shipped import with_shipped
from nbv.setcover.settings import SetCoverSettings

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("eval")
    return {
        "data": make_tiny_dataset(tmp / "data"),
        "pcnbv": save_tiny_checkpoint(tmp / "pcnbv.pt", "points"),
        "pcnbv_sph": save_tiny_checkpoint(tmp / "pcnbv_sph.pt", "signature"),
        "pcnbv_vig": save_tiny_checkpoint(tmp / "pcnbv_vig.pt", "points", seed=1),
        "pcnbv_sph_vig": save_tiny_checkpoint(tmp / "pcnbv_sph_vig.pt", "signature", seed=1),
        "vcnbv": save_tiny_checkpoint(tmp / "vcnbv.pt", "directions"),
        "vcnbv_map": save_tiny_checkpoint(tmp / "vcnbv_map.pt", "directions_map"),
    }


@pytest.fixture(scope="module")
def full_run(tiny, tmp_path_factory):
    """Every default method, both viewspaces, every check, outputs and plots."""
    out = tmp_path_factory.mktemp("run") / "out"
    run(tiny_settings(tiny, out))
    return out


@pytest.mark.slow
def test_full_run_writes_every_output(full_run):
    names = {p.name for p in full_run.iterdir()}
    assert {"results.json", "summary.csv", "report.md"} <= names
    pngs = ("coverage_by_view.png", "vig_by_view.png", "disturbance.png", "noise.png",
            "reconstruction.png", "metrics.png")  # fmt: skip
    for png in pngs:
        assert (full_run / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
    data = json.loads((full_run / "results.json").read_text())
    # The settings keep the flat layout runs have always stored (EvalSettings.stored).
    assert list(data["settings"]) == [
        "out_dir", "methods", "datasets", "data_dir", "mesh_dir", "limit", "prepare",
        "viewspaces", "start_views", "n_views", "checkpoints", "setcover", "infogain", "ig_scorer",
        "checks", "disturb_viewspaces", "disturb_start_views", "disturb_radius", "noise_sigmas",
        "random_repeats", "seed", "threads", "workers", "progress", "plots", "batched",
        "precision",
    ]  # fmt: skip
    assert list(data["settings"]["prepare"]) == [
        "dir", "backend", "blender", "width", "height", "focal", "n_gt", "eps",
        "points_per_view", "seed",
    ]  # fmt: skip
    assert data["settings"]["out_dir"] == str(full_run)
    assert data["settings"]["disturb_start_views"] == [24]
    assert data["settings"]["noise_sigmas"] == [0.002, 0.005, 0.01]
    episodes = data["episodes"]
    plain = [e for e in episodes if e["check"] is None]
    # 2 models x 2 viewspaces x every method (a stochastic one with 10 seeds) x 2 starts, then
    # the checks on 1 start of original: each check's methods, position noise at 3 levels.
    seeds = sum(10 if METHODS_BY_NAME[m].stochastic else 1 for m in DEFAULT_METHODS)
    n_checks = sum((3 if c == "position_noise" else 1) * len(check_methods(c)) for c in CHECKS)
    assert len(plain) == 2 * 2 * seeds * 2
    assert sorted(e["repeat"] for e in plain if e["method"] == "random")[-1] == 9
    assert len(episodes) - len(plain) == n_checks * 2
    assert data["skipped"] == {}
    for e in episodes:
        assert len(e["views"]) == len(e["coverage"]) == len(e["vig"]) == 10
        assert e["views"][0] == e["start"] and len(set(e["views"])) == 10
        assert e["auc"] == pytest.approx(auc(np.array(e["coverage"])))
        assert e["timings"]["total"] == pytest.approx(sum(e["decision_times"]))
    report = (full_run / "report.md").read_text()
    for section in ("## AUC", "Mean coverage after each view", "Mean VIG", "AUC per category",
                    "Replanning", "Disturbance checks", "Timing per reconstruction",
                    "paper / ours", "The paper's claims", "![disturbance.png]",
                    "## AUC minus spread", "## AUC minus random", "## Filler picks",
                    "## Position noise", "![noise.png]", "verdict vs spread",
                    "## Reconstruction, coverage and path metrics", "## The metrics minus spread",
                    "## The metrics minus random", "## Seconds per decision", "![metrics.png]",
                    "## VIG-AUC minus random",
                    f"`ig_learned` from `{SHIPPED_SCORER}` (the weights the package"):  # fmt: skip
        assert section in report, section
    with open(full_run / "summary.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 * len(DEFAULT_METHODS) + n_checks  # (viewspace, method), the checks
    by = {(r["viewspace"], r["method"], r["check"]): r for r in rows}
    random_original = [e for e in plain if e["method"] == "random" and e["viewspace"] == "original"]
    assert float(by[("original", "random", "")]["auc"]) == pytest.approx(
        np.mean([e["auc"] for e in random_original]), abs=1e-6
    )
    assert float(by[("original", "random", "")]["coverage_2"]) == pytest.approx(
        np.mean([e["coverage"][1] for e in random_original]), abs=1e-6
    )


def _vig_auc(vig: list) -> float:
    """The AUC formula on a stored VIG curve (null: NaN)."""
    v = np.array([np.nan if x is None else x for x in vig], dtype=float)
    return float((v[:-1].sum() + 0.5 * v[-1]) / len(v))


def test_the_vig_methods_vig_auc_is_paired_with_randoms(full_run):
    episodes = [e for e in json.loads((full_run / "results.json").read_text())["episodes"]
                if e["check"] is None and e["viewspace"] == "permuted"]  # fmt: skip
    per: dict[tuple, list] = {}
    for e in episodes:  # random's repeats averaged per episode
        per.setdefault((e["method"], e["key"], e["start"]), []).append(_vig_auc(e["vig"]))
    report = (full_run / "report.md").read_text()
    section = report.split("## VIG-AUC minus random")[1].split("\n## ")[0]
    rows = [line for line in section.splitlines() if line.startswith("| ")][1:]
    # the default's
    vig_methods = ["pcnbv_sph_vig", "vig_hull_sco", "vig_hull_sco_matched", "vig_hull_sco_sph"]
    assert [r.split(" | ")[0] for r in rows] == [f"| {m}" for m in vig_methods]
    for m, row in zip(vig_methods, rows, strict=True):
        diffs = [np.mean(v) - np.mean(per[("random", k, s)])
                 for (mm, k, s), v in per.items() if mm == m]  # fmt: skip
        assert len(diffs) == 2 * len(STARTS) and np.isfinite(diffs).all()
        # Columns: unseen / original, unseen / permuted.
        assert row.split(" | ")[2].startswith(f"{np.mean(diffs):+.3f} ["), (m, row)


def test_every_episode_has_the_fields_metrics_checked_independently(full_run, tiny):
    data = json.loads((full_run / "results.json").read_text())
    ds = nbv.dataset.open(tiny["data"])
    eps = float(ds.attrs["eps"])
    models = {k: ds.model(k) for k in {e["key"] for e in data["episodes"]}}
    for i, e in enumerate(data["episodes"]):
        m, model = e["metrics"], models[e["key"]]
        view = model.views[e["viewspace"]]
        assert m["final_coverage"] == e["coverage"][-1]
        every = np.ones(len(view.poses), bool)
        full = coverage_from_bits(view.coverage, every, len(model.gt_points))
        assert m["full_coverage"] == pytest.approx(full)
        for name, frac in (("90", 0.9), ("95", 0.95)):
            first = next((k + 1 for k, c in enumerate(e["coverage"]) if c >= frac * full - 1e-12),
                         None)  # fmt: skip
            assert m[f"views_to_{name}"] == first and m[f"censored_{name}"] == (first is None)
        # The camera path, from the stored poses: arcs of the angle between directions.
        cams = view.poses[e["views"], :3, 3]
        radius = np.linalg.norm(view.poses[:, :3, 3], axis=1).mean()
        unit = cams / np.linalg.norm(cams, axis=1, keepdims=True)
        cosines = np.clip(np.sum(unit[:-1] * unit[1:], axis=1), -1, 1)
        assert m["path_length"] == pytest.approx(radius * np.arccos(cosines).sum(), rel=1e-6)
        assert m["shortest_path"] <= m["path_length"] + 1e-9
        if i % 97 == 0:  # a sample of episodes: the scores of the concatenated cloud
            cloud = np.concatenate([view.view_points(v) for v in e["views"]])
            want = cloud_scores(cloud, model.gt_points, eps)
            for key in want:
                assert m[key] == pytest.approx(want[key], rel=1e-9), key
    with open(full_run / "summary.csv", newline="") as handle:
        rows = {(r["viewspace"], r["method"], r["check"]): r for r in csv.DictReader(handle)}
    oracle = [e for e in data["episodes"]
              if e["method"] == "oracle" and e["viewspace"] == "original"]  # fmt: skip
    row = rows[("original", "oracle", "")]
    chamfer = np.mean([e["metrics"]["chamfer"] for e in oracle])
    assert float(row["chamfer"]) == pytest.approx(chamfer, rel=1e-5)
    censored = sum(e["metrics"]["censored_95"] for e in oracle)
    assert float(row["censored_95"]) == censored
    # hull_sco plans once per episode: one decision, its stages divided by one.
    assert float(rows[("original", "hull_sco", "")]["decisions"]) == 1.0
    assert float(rows[("original", "ig", "")]["decisions"]) == 9.0


def test_the_metric_tables_pair_against_spread_and_count_censored_episodes(tiny, tmp_path):
    ev = evaluate(tiny_settings(tiny, tmp_path, methods=("spread", "oracle"),
                                viewspaces=("original",), checks=()))  # fmt: skip
    values = episode_values(ev.records, 10)
    a, b = ("unseen", "original", "spread", None), ("unseen", "original", "oracle", None)
    for key in ("final_coverage", "chamfer", "fscore_2eps", "path_length", "views_to_95"):
        diff = paired_metric(values, a, b, key, seed=0)

        def value(m, key=key):
            if key == "views_to_95":  # censored: the restricted count, n_views + 1
                return 11 if m["censored_95"] else m["views_to_95"]
            return m[key]

        # Each side's per-episode mean over its seeds (spread breaks ties at random).
        per: dict[tuple, list] = {}
        for r in ev.records:
            per.setdefault((r.method, r.key, r.start), []).append(value(r.metrics))
        episodes = {(k, s) for _, k, s in per}
        want = np.mean(
            [np.mean(per[("oracle", *e)]) - np.mean(per[("spread", *e)]) for e in episodes]
        )
        assert diff.mean == pytest.approx(want) and diff.n == 2 * len(STARTS)
        assert diff.low <= diff.mean <= diff.high
    stats = run_statistics(ev.records, 10)
    lines = "\n".join(metrics_tables(stats, ["unseen"], ["original"], 10, seed=0))
    assert "## The metrics minus spread" in lines and "## The metrics minus random" not in lines
    final = paired_metric(values, a, b, "final_coverage", seed=0)
    assert f"| oracle | {final.text(3)} |" in lines
    # A hand-made censored episode: two of three censored, the mean over the one that reached.
    rec = ev.records[0]
    made = [replace(rec, start=s, metrics={**rec.metrics, "views_to_90": v,
                                           "censored_90": v is None})
            for s, v in ((1, None), (2, 4), (3, None))]  # fmt: skip
    s = summaries(episode_values(made, 10))[(rec.dataset, rec.viewspace, rec.method, None)]
    assert s["views_to_90"] == 4 and s["censored_90"] == 2
    assert s["restricted_90"] == pytest.approx((11 + 4 + 11) / 3)


def test_spread_ties_are_reported_when_recorded(tiny, tmp_path):
    ev = evaluate(tiny_settings(tiny, tmp_path, methods=("spread",), viewspaces=("original",),
                                checks=(), random_repeats=1))  # fmt: skip
    counted = [replace(r, counts={"decisions": 9, "ties": 3}) for r in ev.records]
    lines = tie_lines(run_statistics(counted, 10), ["unseen"], ["original"])
    n = len(counted)
    assert f"| unseen | original | {n} | {3 * n} | {9 * n} | 33.3 |" in lines
    bare = run_statistics([replace(r, counts={}) for r in ev.records], 10)
    assert tie_lines(bare, ["unseen"], ["original"]) == []


def test_oracle_leads_at_the_second_view_in_the_run(full_run):
    episodes = json.loads((full_run / "results.json").read_text())["episodes"]
    oracle = {
        (e["viewspace"], e["key"], e["start"]): e["coverage"][1]
        for e in episodes
        if e["method"] == "oracle"
    }
    for e in episodes:
        assert e["coverage"][1] <= oracle[(e["viewspace"], e["key"], e["start"])] + 1e-12


def test_auc_of_a_known_curve_and_group_means(tiny, tmp_path):
    assert auc(np.linspace(0.1, 1.0, 10)) == pytest.approx(0.5)
    ev = evaluate(tiny_settings(tiny, tmp_path, methods=("random",), viewspaces=("original",),
                                checks=()))  # fmt: skip
    curves = np.array([r.coverage for r in ev.records])
    expected = (curves[:, :9].sum(axis=1) + 0.5 * curves[:, 9]) / 10
    assert [r.auc for r in ev.records] == pytest.approx(expected.tolist())
    g = groups(ev.records)[("unseen", "original", "random", None)]
    assert g["n"] == 2 * len(STARTS) and g["auc"] == pytest.approx(expected.mean())
    np.testing.assert_allclose(g["coverage"], curves.mean(axis=0))


def test_seeded_runs_repeat_and_seeds_matter(tiny, tmp_path):
    kw = dict(methods=("random", "hull_sco_probes"), viewspaces=("permuted",), checks=())
    a = evaluate(tiny_settings(tiny, tmp_path / "a", **kw)).records
    b = evaluate(tiny_settings(tiny, tmp_path / "b", **kw)).records
    c = evaluate(tiny_settings(tiny, tmp_path / "c", seed=1, **kw)).records
    assert [r.views for r in a] == [r.views for r in b]
    assert [r.views for r in a] != [r.views for r in c]
    assert episode_rng(0, "random", "k", 3).random() == episode_rng(0, "random", "k", 3).random()


@pytest.mark.slow
def test_a_missing_checkpoint_takes_the_shipped_weights_and_a_wrong_one_refuses(tiny, tmp_path):
    from nbv.assets.weights import shipped_weights
    from nbv.eval.inputs import EvalDataError

    missing = tmp_path / "nowhere" / "best.pt"
    settings = tiny_settings(
        tiny, tmp_path / "out", methods=("random", "pcnbv", "pcnbv_sph", "hull_sco"),
        viewspaces=("original",), start_views=(1,), disturb_start_views=(1,),
        checkpoints={"pcnbv": str(missing), "pcnbv_sph": str(tiny["pcnbv"])}, plots=False,
    )  # fmt: skip
    # A file that is there but holds the wrong network is an error, never a skip.
    with pytest.raises(EvalDataError, match="checkpoints.pcnbv_sph: .* not signature"):
        run(settings)
    assert not (tmp_path / "out").exists()
    settings = replace(settings, methods=("random", "pcnbv", "hull_sco"))
    run(settings)
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert data["skipped"] == {}
    assert {e["method"] for e in data["episodes"]} == {"random", "pcnbv", "hull_sco"}
    noise = {f"position_noise_{x}" for x in ("0.002", "0.005", "0.01")}
    checks = {None, "random_hull", "random_cloud", "permuted_state"} | noise
    assert {e["check"] for e in data["episodes"]} == checks
    report = (tmp_path / "out" / "report.md").read_text()
    assert f"`pcnbv` from `{shipped_weights('pcnbv')}` (the weights the package ships" in report
    # Without the fallback (evaluate alone) a missing checkpoint is skipped, naming the path.
    bare = evaluate(replace(settings, run="bare", disturb=DisturbSettings(checks=())))
    assert str(missing) in bare.skipped["pcnbv"]


def test_a_method_led_by_a_network_loads_it_and_is_skipped_without_it(tiny, tmp_path):
    kw = dict(methods=("pcnbv_sph_vig", "vig_hull_sco"), viewspaces=("original",), checks=())
    for batched in (True, False):
        ev = evaluate(tiny_settings(tiny, tmp_path / f"b{batched}", batched=batched, **kw))
        assert ev.skipped == {}
        views = {(r.method, r.key, r.start): r.views for r in ev.records}
        led = [r for r in ev.records if r.method == "vig_hull_sco"]
        assert len(led) == 2 * len(STARTS)
        for r in led:  # the network's two picks, then one plan (three decisions)
            assert r.views[:3] == views[("pcnbv_sph_vig", r.key, r.start)][:3]
            assert len(r.decision_times) == 3 and r.counts["planned"] == 7
    # The network's checkpoint alone, for the method it leads: loaded though not selected.
    alone = evaluate(
        tiny_settings(tiny, tmp_path / "alone", **{**kw, "methods": ("vig_hull_sco",)})
    )
    assert [r.views for r in alone.records] == [r.views for r in led]
    # A points network given for it: the run is refused, saying why (never a skip).
    wrong = {"pcnbv_sph_vig": str(tiny["pcnbv"])}
    with pytest.raises(EvalDataError, match="holds a network on points, not signature"):
        evaluate(tiny_settings(tiny, tmp_path / "wrong", **kw, checkpoints=wrong))
    # A checkpoint that is not there (a default path with nothing shipped behind it) is
    # skipped, and so is the method it leads; with nothing left to run, the run is refused.
    gone = {"pcnbv_sph_vig": str(tmp_path / "nowhere.pt")}
    with pytest.raises(EvalDataError, match=r"no episode can run \(.*nowhere.pt"):
        evaluate(tiny_settings(tiny, tmp_path / "gone", **kw, checkpoints=gone))
    with pytest.raises(EvalConfigError, match=r"checkpoints: no entry for \['pcnbv_sph_vig'\]"):
        tiny_settings(
            tiny, tmp_path / "none", checkpoints={}, **{**kw, "methods": ("vig_hull_sco",)}
        )


def test_disturbances(full_run, tiny, tmp_path):
    rng = np.random.default_rng(0)
    ball = random_ball(5000, 0.5, rng)
    assert ball.shape == (5000, 3) and np.linalg.norm(ball, axis=1).max() <= 0.5
    # Uniform in the ball: a quarter... of the volume, (1/2)^3 = 1/8, lies within radius 0.25.
    assert np.mean(np.linalg.norm(ball, axis=1) < 0.25) == pytest.approx(1 / 8, abs=0.02)
    np.testing.assert_array_equal(random_ball(10, 0.5, np.random.default_rng(3)),
                                  random_ball(10, 0.5, np.random.default_rng(3)))  # fmt: skip
    state = np.zeros(33, bool)
    state[[2, 5, 9]] = True
    shown = permuted_state(state, rng)
    assert shown.sum() == 3 and shown.dtype == bool
    data = json.loads((full_run / "results.json").read_text())
    checks = {(e["check"], e["method"]) for e in data["episodes"] if e["check"]}
    noisy = {(f"position_noise_{x}", m) for x in ("0.002", "0.005", "0.01")
             for m in ("pcnbv", "pcnbv_sph", "hull_sco", "hull_sco_sph", "ig",
                       "ig_learned", "ig_area_factor", "ig_proximity")}  # fmt: skip
    assert checks == {("random_cloud", "pcnbv"), ("random_cloud", "pcnbv_sph"),
                      ("permuted_state", "pcnbv"), ("permuted_state", "pcnbv_sph"),
                      ("random_hull", "hull_sco")} | noisy  # fmt: skip
    ev = evaluate(tiny_settings(tiny, tmp_path, methods=("hull_sco",), viewspaces=("original",),
                                checks=("random_hull",)))  # fmt: skip
    rows = auc_changes(ev.records)
    assert len(rows) == 1 and rows[0]["check"] == "random_hull" and rows[0]["n"] == 2
    plain = {(r.key, r.start): r.auc for r in ev.records if r.check is None}
    dist = [(r.key, r.start, r.auc) for r in ev.records if r.check]
    change = rows[0]["change"]
    assert change.mean == pytest.approx(np.mean([a - plain[(k, s)] for k, s, a in dist]))
    assert change.low <= change.mean <= change.high


def test_timing_table_and_paper_ratios(full_run, tiny, tmp_path):
    ev = evaluate(tiny_settings(tiny, tmp_path, methods=("pcnbv", "hull_sco", "hull_sco_replan"),
                                viewspaces=("original",), checks=()))  # fmt: skip
    table = timing_table(ev.records)
    assert table["pcnbv"]["network"] > 0 and table["pcnbv"]["simulation"] == 0
    assert table["hull_sco"]["simulation"] > 0 and table["hull_sco"]["network"] == 0
    for m in table:
        parts = sum(table[m][c] for c in ("sampling", "network", "hull", "simulation", "set_cover"))
        assert parts <= table[m]["total"] + 1e-9
        assert table[m]["online"] == pytest.approx(table[m]["total"] - table[m]["simulation"])
    ratios = paper_ratios(table)
    assert set(ratios) == {"pcnbv", "hull_sco"}
    assert ratios["hull_sco"]["set_cover"] == pytest.approx(
        PAPER_TIMES["hull_sco"]["set_cover"] / table["hull_sco"]["set_cover"]
    )


def flat_square(path: Path) -> None:
    """A flat mesh (zero thickness, like woody.obj): its ground truth has no hull volume."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    trimesh.Trimesh(vertices, [[0, 1, 2], [0, 2, 3]], process=False).export(path)


@pytest.mark.slow
def test_mesh_folder_is_prepared_once_and_a_flat_mesh_gives_nan_vig(tiny, tmp_path):
    folder = write_meshes(tmp_path / "meshes", bad=True)
    flat_square(folder / "flat.ply")
    prep = PrepareSettings(dir=tmp_path / "prepared", camera=SMALL_CAMERA, n_gt=1000,
                           points_per_view=50)  # fmt: skip
    path, failures = prepare_meshes(folder, prep, progress=False)
    assert [k for k, _ in failures] == ["broken"]
    shard = next(path.glob("shard-*.h5"))
    stamp = shard.stat().st_mtime_ns
    assert prepare_meshes(folder, prep, progress=False)[0] == path
    assert shard.stat().st_mtime_ns == stamp  # reused, not rendered again
    settings = tiny_settings(
        tiny, tmp_path / "out", datasets=("meshes",), mesh_dir=folder, prepare=prep,
        methods=("random", "pcnbv_sph", "hull_sco", "hull_sco_sph"), viewspaces=("original",),
        start_views=(1, 30), checks=(), plots=False,
    )  # fmt: skip
    run(settings)
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    flat = [e for e in data["episodes"] if e["key"] == "flat"]
    assert flat and all(v is None for e in flat for v in e["vig"])
    assert all(0 <= c <= 1 for e in flat for c in e["coverage"])
    box = [e for e in data["episodes"] if e["key"] == "box"]
    assert all(v is not None for e in box for v in e["vig"])
    report = (tmp_path / "out" / "report.md").read_text()
    assert "flat ground truth" in report and "flat" in report and "broken" in report


@pytest.mark.parametrize(
    "override, message",
    [
        (dict(methods=["random", "magic"]), "methods: unknown 'magic'; allowed: random, spread"),
        (dict(viewspace="sideways"), "viewspace: unknown 'sideways'; allowed: original, permuted"),
        (dict(dataset="shapenet"), "dataset: unknown 'shapenet'; allowed: unseen, test, meshes"),
        (dict(dataset="meshes"), "mesh_dir"),
        (dict(disturb={"checks": ["noise"], "viewspace": ["original"], "radius": 0.5}),
         "disturb.checks: unknown 'noise'"),
        (dict(setcover={"simulation": "guess"}),
         "setcover.simulation='guess': must be one of analytic, raycast"),
        # OmegaConf reads yes/no/on/off as booleans; anything else is refused.
        (dict(setcover={"dilate": "maybe"}), "setcover.dilate='maybe': must be true or false"),
        (dict(n_views=1), "n_views=1"),
        (dict(seed="abc"), "seed='abc': must be an integer"),
        (dict(colour="red"), "colour: unknown key; allowed: run, out_root, methods"),
        (dict(setcover={"radius": 2}), "setcover.radius: unknown key; allowed: n_samp, simulation"),
        (dict(start_views=[24, 40]),
         "start_views=[40]: the viewspace 'original' has 33 views (indices 0..32)"),
        (dict(checkpoints={"pcnbv": "a.pt", "dqn": "b.pt"}), "checkpoints: unknown ['dqn']"),
    ],
)  # fmt: skip
@pytest.mark.slow
def test_bad_config_is_refused(override, message):
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("eval", overrides=["run=x"])
    from omegaconf import OmegaConf

    c = OmegaConf.to_container(cfg, resolve=True)
    for key, value in override.items():  # a section's keys replace those keys only
        if isinstance(value, dict) and isinstance(c.get(key), dict):
            c[key] = {**c[key], **value}
        else:
            c[key] = value
    with pytest.raises(EvalConfigError) as err:
        ENTRY.build(c)
    assert message in str(err.value)


@pytest.mark.slow
def test_worker_processes_give_the_records_of_one_process(tiny, tmp_path):
    kw = dict(methods=("random", "pcnbv", "ig"), viewspaces=("original",), checks=(),
              random_repeats=2)  # fmt: skip
    one = evaluate(tiny_settings(tiny, tmp_path / "one", **kw)).records
    two = evaluate(tiny_settings(tiny, tmp_path / "two", workers=2, **kw)).records
    assert len(one) == len(two) > 0
    for a, b in zip(one, two, strict=True):
        assert (a.method, a.key, a.start, a.repeat, a.views) == (b.method, b.key, b.start,
                                                                 b.repeat, b.views)  # fmt: skip
        np.testing.assert_array_equal(a.coverage, b.coverage)
        np.testing.assert_array_equal(a.vig, b.vig)


def test_default_config_composes_to_the_documented_defaults():
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("eval", overrides=["run=x"])
    s = ENTRY.build(cfg)
    assert s.methods == DEFAULT_METHODS and s.datasets == ("unseen",)
    assert set(METHODS_BY_NAME) - set(s.methods) == {
        "oracle_vig", "pcnbv_vig", "pcnbv_matched", "completion_hull_sco_replan",
        "completion_gain_authors",
    }  # fmt: skip
    assert s.viewspaces == ("original", "permuted") and s.start_views == (
        1,
        3,
        7,
        10,
        15,
        24,
        27,
        30,
    )
    assert s.out_dir == Path("outputs/eval/x")
    assert s.checkpoints["pcnbv"] == "outputs/train/pcnbv_coverage_fold0/best.pt"
    assert s.checkpoints["pcnbv_sph"] == "outputs/train/pcnbv_sph_coverage_fold0/best.pt"
    assert s.checkpoints["pcnbv_vig"] == "outputs/train/pcnbv_vig_fold0/best.pt"
    assert s.checkpoints["pcnbv_sph_vig"] == "outputs/train/pcnbv_sph_vig_fold0/best.pt"
    assert s.setcover.network_views == 2
    assert s.check_start_views == (1, 10, 24)
    assert s.setcover == SetCoverSettings() and s.setcover.dilate is False
    assert s.infogain == InfoGainSettings() and s.workers == 0
    assert compose_with(["setcover.dilate=true"]).setcover.dilate is True
    with_meshes = compose_with(["mesh_dir=" + str(ROOT / "tests")])
    assert with_meshes.datasets == ("unseen", "meshes")


def compose_with(overrides: list[str]) -> EvalSettings:
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(str(ROOT / "conf"), version_base="1.3"):
        return ENTRY.build(compose("eval", overrides=["run=x", *overrides]))


def test_missing_dataset_and_bad_start_view_stop_before_any_episode(tiny, tmp_path):
    with pytest.raises(EvalDataError, match="make dataset"):
        evaluate(tiny_settings(tiny, tmp_path, data_dir=tmp_path / "none"))
    # Refused with the settings, before any dataset is opened: the viewspace has 33 views.
    with pytest.raises(
        EvalConfigError, match=r"start_views=\[40\]: the viewspace 'original' has 33"
    ):
        evaluate(tiny_settings(tiny, tmp_path, start_views=(24, 40)))
    with pytest.raises(EvalDataError, match="8 training categories"):
        evaluate(tiny_settings(tiny, tmp_path, datasets=("test",)))


@pytest.mark.slow
def test_cli_refuses_a_bad_method_with_one_line(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "nbv.eval", "methods=[random,magic]", f"out_root={tmp_path}"],
        cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 2
    assert "methods: unknown 'magic'; allowed: random, spread, oracle, oracle_vig" in done.stderr
    assert not list(tmp_path.rglob("results.json"))
    assert not list(tmp_path.iterdir())  # not even hydra's run folder


def test_settings_are_replaceable_and_validated_on_replace(tiny, tmp_path):
    settings = tiny_settings(tiny, tmp_path)
    with pytest.raises(EvalConfigError, match="disturb.start_views"):
        replace(settings, disturb=DisturbSettings(start_views=(2,)))
    # Null: every start view; stored resolved, as runs have always stored it.
    every = replace(settings, disturb=DisturbSettings(start_views=None))
    assert every.check_start_views == STARTS
    assert every.stored()["disturb_start_views"] == STARTS
    # A nested group's range names its key path, made in code as from a config.
    with pytest.raises(EvalConfigError, match=r"disturb.radius=0: must be a positive distance"):
        DisturbSettings(radius=0)
    with pytest.raises(EvalConfigError, match=r"prepare.n_gt=0: must be an integer >= 1"):
        PrepareSettings(n_gt=0)


def test_interrupted_evaluation_resumes_from_its_log(tiny, tmp_path):
    kw = dict(methods=("random", "hull_sco"), viewspaces=("original",), checks=(), plots=False)
    settings = tiny_settings(tiny, tmp_path / "out", **kw)
    first = evaluate(settings).records
    log = tmp_path / "out" / "episodes.jsonl"
    lines = log.read_text().splitlines(keepends=True)
    done_lines = [i for i, line in enumerate(lines) if line.startswith('{"done"')]
    assert len(done_lines) == 2  # the two models of the tiny dataset
    # A kill while the second model's records were being written: its done line never came
    # and the last record is torn.
    log.write_text("".join(lines[: done_lines[0] + 2]) + lines[done_lines[0] + 2][:25])
    resumed = evaluate(settings)
    second = resumed.records
    assert resumed.resumed == len(first) // 2
    assert [(r.key, r.method, r.start, r.views, r.coverage) for r in second] == [
        (r.key, r.method, r.start, r.views, r.coverage) for r in first
    ]
    n_first = len(first) // 2
    # The first model was read back (same measured times), the second one run again.
    assert [r.decision_times for r in second[:n_first]] == [
        r.decision_times for r in first[:n_first]
    ]
    assert [r.decision_times for r in second[n_first:]] != [
        r.decision_times for r in first[n_first:]
    ]
    assert log.read_text().count('{"done"') == 2
    assert all(r.metrics for r in second)
    # A log written before the metrics existed: the episodes read back get them computed.
    old = [json.loads(line) for line in log.read_text().splitlines()]
    for entry in old:
        entry.pop("metrics", None)
    log.write_text("".join(json.dumps(e) + "\n" for e in old))
    again = evaluate(settings)
    assert again.resumed == len(first)
    # The metrics are functions of the views and the dataset: the same numbers to the bit.
    assert [r.metrics for r in again.records] == [r.metrics for r in second]
    # Other settings: the old log is set aside and everything runs again.
    evaluate(replace(settings, seed=7))
    assert (tmp_path / "out" / "episodes.jsonl.stale").exists()
    assert log.read_text().count('{"done"') == 2


def test_ig_learned_runs_the_given_scorer_and_its_bytes_decide_the_log(tiny, tmp_path):
    kw = dict(methods=("ig_learned",), viewspaces=("permuted",), checks=(), plots=False)
    missing = tmp_path / "none.json"
    with pytest.raises(ScorerError, match="none.json: no such scorer file"):
        evaluate(tiny_settings(tiny, tmp_path / "out", ig_scorer=missing, **kw))
    assert not (tmp_path / "out").exists()
    own = tmp_path / "own.json"
    # A scorer of one feature (the angle to the nearest captured view) plans as spread does, ties
    # going to the lowest index (the deterministic spread: spread_views without a generator).
    weight = np.zeros((len(FEATURES), 1))
    weight[FEATURES.index("angle_nearest")] = 1.0
    save_scorer(own, GainScorer((weight,), (np.zeros(1),)))
    settings = tiny_settings(tiny, tmp_path / "out", ig_scorer=own, **kw)
    first = evaluate(settings).records
    positions = nbv.dataset.open(tiny["data"])[first[0].key].views["permuted"].poses[:, :3, 3]
    directions = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    for record in first:
        closed = np.zeros(len(directions), dtype=bool)
        closed[record.views[0]] = True
        expected = [record.views[0], *spread_views(directions, closed, len(record.views) - 1)]
        assert record.views == expected
    # The same file resumes; other weights in it are another run (the old log is set aside).
    assert evaluate(settings).resumed == len(first)
    save_scorer(own, GainScorer((-weight,), (np.zeros(1),)))
    assert evaluate(settings).resumed == 0
    assert (tmp_path / "out" / "episodes.jsonl.stale").exists()


def test_hull_policies_get_the_dilation_setting():
    from nbv.policies.completion import CompletionGainPolicy

    # A stand-in model: building reads only its number of outputs (the matched planner checks it).
    model = SimpleNamespace(config=SimpleNamespace(n_views=33))
    networks = {"pcnbv_sph_vig": NetworkPolicy(model=model, input="signature")}
    two_stage = ("hull_ig", "vig_hull_sco", "vig_hull_sco_matched", "vig_hull_sco_sph")
    for dilate in (False, True):
        ctx = with_shipped(
            MethodContext(networks, SetCoverSettings(dilate=dilate), SMALL_CAMERA, 0.03, 10)
        )
        for method in GEOMETRIC:
            policy = METHODS_BY_NAME[method].build(ctx, np.random.default_rng(0))
            hull = policy.hull if method in two_stage else policy
            # The volumetric ones and the view contribution of a completion have no hull.
            if not isinstance(hull, InfoGainPolicy | CompletionGainPolicy):
                assert hull.settings.dilate is dilate and hull.eps == 0.03, method


@dataclass
class _Recorder:
    """A policy that records what it is shown and picks the lowest free view (the disturbance
    wrappers call it in each of the ways they call a network or a planner)."""

    n_views: int = 10
    seen: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    def __call__(self, state):
        self.seen.append(("state", state.cloud().copy(), state.view_state.copy()))
        return int(np.flatnonzero(~state.view_state)[0])

    def decide(self, cloud, view_state, visited=None):
        self.seen.append(("decide", np.array(cloud), np.array(view_state)))
        return int(np.flatnonzero(~(view_state if visited is None else visited))[0])

    def plan_from(self, cloud, poses, visited, n_iter):
        self.seen.append(("plan", np.array(cloud), np.array(visited)))
        return [v for v in range(len(poses)) if v not in visited][:n_iter]


def test_disturbed_policies_are_really_shown_disturbed_inputs(tiny):
    ds = nbv.dataset.open(tiny["data"])
    model = ds.model(ds.keys()[0], ("original",))
    start_cloud = model.views["original"].view_points(5)
    for check, sigma in (("random_cloud", 0.0), ("permuted_state", 0.0), ("random_hull", 0.0),
                         ("position_noise", 0.005)):  # fmt: skip
        inner = _Recorder()
        run_episode(model, "original", 5, disturbed(check, inner, np.random.default_rng(1), 0.5,
                                                    sigma))  # fmt: skip
        kind, cloud, shown = inner.seen[0]
        if check == "permuted_state":
            # The true cloud, and a state with one visited view that is not always the true one.
            assert kind == "decide" and np.array_equal(cloud, start_cloud)
            assert all(s.sum() == i + 1 for i, (_, _, s) in enumerate(inner.seen))
            assert any(not s[5] for _, _, s in inner.seen)
        elif check == "position_noise":
            # The true views' points, every coordinate moved by noise of the given sigma.
            assert kind == "state" and cloud.shape == start_cloud.shape
            moved = cloud - start_cloud
            assert (moved != 0).all() and np.std(moved) == pytest.approx(sigma, rel=0.1)
        else:
            # Random points in the ball of radius 0.5 instead of the view's.
            assert kind == ("decide" if check == "random_cloud" else "plan")
            assert len(cloud) == max(len(start_cloud), 4)
            assert np.linalg.norm(cloud, axis=1).max() <= 0.5 + 1e-6
            assert not np.isin(cloud, start_cloud).any()


def test_models_that_chose_a_checkpoint_are_not_scored(tiny, tmp_path):
    keys = nbv.dataset.open(tiny["data"]).keys()
    chosen = save_tiny_checkpoint(tmp_path / "chosen.pt", "points", selection_keys=[keys[0]])
    ev = evaluate(tiny_settings(
        tiny, tmp_path / "out", methods=("random", "spread", "pcnbv"), viewspaces=("original",),
        checks=(), checkpoints={"pcnbv": str(chosen), "pcnbv_sph": str(tiny["pcnbv_sph"])},
    ))  # fmt: skip
    assert ev.datasets[0].keys == keys[1:]
    assert ev.datasets[0].excluded == [(keys[0], "chose the checkpoint of pcnbv")]
    assert {r.key for r in ev.records} == set(keys[1:])  # for every method, not only pcnbv


def test_a_dataset_of_another_eps_is_refused_by_name(tiny, tmp_path):
    settings = tiny_settings(tiny, tmp_path / "out", methods=("spread",), checks=(), plots=False)
    other = replace(settings, prepare=replace(settings.prepare, eps=0.00707))
    with pytest.raises(EvalDataError, match=r"eps=.*protocol\.eps=0\.00707"):
        evaluate(other)


@pytest.mark.slow
def test_a_run_in_this_process_takes_the_workers_thread_limits():
    """workers=1 runs the models in the calling process, with the threads of a worker (one torch
    and one BLAS thread by default), not the pools' defaults that oversubscribe the cores."""
    code = (
        "import torch, threadpoolctl\n"
        "from nbv.eval.evaluate import _pool\n"
        "with _pool(1, 1, 5) as pool:\n"
        "    assert list(pool(abs, [-1, 2])) == [1, 2]\n"
        "blas = [p['num_threads'] for p in threadpoolctl.threadpool_info()"
        " if p['user_api'] == 'blas']\n"
        "print(torch.get_num_threads(), blas)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    torch_threads, blas = out.stdout.split(" ", 1)
    assert torch_threads == "1"
    assert set(json.loads(blas)) <= {1}


_FINISH_ORDER_SCRIPT = """
import os, sys, time
from nbv.eval.evaluate import _pool

FLAG = sys.argv[1]

def slow_or_quick(item):
    # Item 0 waits for the flag the caller writes once it has item 1's result; in-order
    # results would never deliver item 1 first, and item 0 gives up after 120 s.
    if item == 0:
        deadline = time.monotonic() + 120
        while not os.path.exists(FLAG):
            if time.monotonic() > deadline:
                return "gave up"
            time.sleep(0.05)
    return item

if __name__ == "__main__":
    got = []
    with _pool(2, 1, 2) as pool:
        for result in pool(slow_or_quick, [0, 1]):
            got.append(result)
            open(FLAG, "w").close()
    print(got)
"""


@pytest.mark.slow
def test_the_workers_give_each_model_as_it_finishes(tmp_path):
    """A slow model does not hold back the ones that finish after it: the evaluator logs each as
    it ends, so a run killed during the slow one keeps them."""
    script = tmp_path / "order.py"
    script.write_text(_FINISH_ORDER_SCRIPT)
    out = subprocess.run([sys.executable, str(script), str(tmp_path / "flag")],
                         capture_output=True, text=True, check=True, timeout=300)  # fmt: skip
    assert out.stdout.strip() == "[1, 0]"


def test_a_flat_ground_truth_leaves_out_the_vig_oracle_only():
    """VIG is undefined for a flat object: the method greedy by the true VIG cannot play it (it
    stopped a whole run); every other method, VIG-led ones included, still plays it."""
    from nbv.eval.evaluate import Job, playable_jobs

    jobs = [Job(m, None, None, "original", 1, 0) for m in
            ("random", "oracle", "oracle_vig", "pcnbv_sph_vig", "vig_hull_sco")]  # fmt: skip
    assert playable_jobs(jobs, 0.0, "flat") == [j for j in jobs if j.method != "oracle_vig"]
    assert playable_jobs(jobs, float("nan"), "flat") == playable_jobs(jobs, 0.0, "flat")
    assert playable_jobs(jobs, 0.02, "solid") == jobs
