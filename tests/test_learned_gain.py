"""ig_learned: the candidates' map features against a plain walk along each ray, the scorer file
against a torch forward, the policy against ig and spread when the scorer reads one feature, and
a real (small) training run of python -m train.scorer."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from datagen import INFOGAIN, SMALL_CAMERA, make_tiny_dataset, make_train_dataset
from shapes import INTO_POCKET, cup, pocket_scene

import nbv.dataset
from nbv.assets.weights import SHIPPED_SCORER
from nbv.bench.infogain import decision, numpy_ray_features, plain_decision
from nbv.geometry.camera import Intrinsics, backproject, viewspace_poses
from nbv.infogain.gain import frontier, view_gains
from nbv.infogain.gain_scorer import GainScorer, ScorerError, load_scorer, save_scorer
from nbv.infogain.occupancy import OccupancyMap, OccupancySettings
from nbv.infogain.settings import InfoGainSettings
from nbv.infogain.view_features import FEATURES, RAY_FEATURES, ray_features, view_features
from nbv.policies.episode import EpisodeState, run_episode
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.learned_gain import LearnedGainPolicy
from nbv.policies.reference import SpreadPolicy
from nbv.render.raycast import render_raycast
from train.scorer import ScorerSettings, _scorer, captured, mixed_views, run


def _walk(row: np.ndarray, log_odds: np.ndarray, near: np.ndarray, n: int) -> list[float]:
    """The per-ray features of one ray, spelled out voxel by voxel."""
    voxels = list(row[: np.argmax(row < 0)] if (row < 0).any() else row)  # -1 pads the end
    states = ["unknown" if np.isnan(log_odds[v]) else "occ" if log_odds[v] >= 0 else "free"
              for v in voxels]  # fmt: skip
    end = states.index("occ") if "occ" in states else len(states)
    before = states[:end]
    unknown = [v for v, s in zip(voxels[:end], before, strict=True) if s == "unknown"]
    meets = end < len(states)
    first_unknown = before.index("unknown") if unknown else 0
    return [
        len(unknown),
        float(len(unknown) > 0),
        float(meets),
        float(meets and end > 0 and before[-1] == "unknown"),
        float(sum(near[v] for v in unknown)),
        float(min(len(unknown), 4)),
        float(len(unknown) > 0 and not meets),
        first_unknown / n if unknown else 0.0,
    ]


def test_ray_features_equal_a_plain_walk_along_each_ray():
    occupancy = OccupancyMap(OccupancySettings(resolution=0.1, bound=0.6, object_radius=None))
    rng = np.random.default_rng(3)
    size = len(occupancy.log_odds)
    state = rng.choice(3, size, p=[0.5, 0.35, 0.15])
    occupancy.log_odds[:] = np.where(state == 0, np.nan, np.where(state == 1, -0.4, 0.85))
    rows = rng.integers(0, size, (300, 14))
    rows[rng.random(rows.shape) < 0.15] = -1  # padding ends some rows early
    near = frontier(occupancy).astype(float)
    expected = [_walk(r, occupancy.log_odds, near, occupancy.settings.n) for r in rows]
    got = ray_features(occupancy, rows)
    assert got.shape == (300, len(RAY_FEATURES))
    np.testing.assert_allclose(got, expected, atol=1e-12)
    assert got[:, 3].sum() > 0 and got[:, 6].sum() > 0 and near.sum() > 0  # every branch taken


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    data = nbv.dataset.open(make_tiny_dataset(tmp_path_factory.mktemp("learned") / "data"))
    return data.model(data.keys()[0])


def _map_after(model, order: list[int]) -> InfoGainPolicy:
    policy = InfoGainPolicy(INFOGAIN, SMALL_CAMERA)
    state = np.isin(np.arange(33), order)
    policy.update(EpisodeState(model.captured("original"), state, order))
    return policy


def test_view_features_scale_ig_gain_and_measure_angles(tiny):
    order = [3, 17]
    policy = _map_after(tiny, order)
    poses = tiny.views["original"].poses
    open_ = np.setdiff1d(np.arange(33), order)
    voxels = policy.candidate_voxels(poses)[open_]
    features = view_features(policy.occupancy, voxels, poses[:, :3, 3], order, open_)
    assert features.shape == (31, len(FEATURES))
    gains = view_gains(policy.occupancy, voxels, "unobserved")
    # The first column is ig's gain over the best candidate's: it ranks as ig does.
    np.testing.assert_allclose(features[:, 0], gains / gains.max())
    relative = features[:, : len(RAY_FEATURES)]
    top = relative.max(axis=0)
    assert relative.min() >= 0 and np.all(np.isclose(top, 1) | (top == 0))
    # Angles over 180 degrees: to the nearest, the last and the first captured view.
    unit = poses[:, :3, 3] / np.linalg.norm(poses[:, :3, 3], axis=1, keepdims=True)
    deg = np.degrees(np.arccos(np.clip(unit[open_] @ unit[order].T, -1, 1))) / 180
    np.testing.assert_allclose(features[:, -4:-1], np.c_[deg.min(1), deg[:, 1], deg[:, 0]])
    assert np.all(features[:, -1] == 0.2)


def _one_feature_scorer(name: str) -> GainScorer:
    weight = np.zeros((len(FEATURES), 1))
    weight[FEATURES.index(name)] = 1.0
    return GainScorer((weight,), (np.zeros(1),))


def test_a_scorer_of_one_feature_plans_as_ig_or_as_spread(tiny):
    for start in (1, 10, 27):
        ig = run_episode(tiny, "original", start, InfoGainPolicy(INFOGAIN, SMALL_CAMERA))
        learned = LearnedGainPolicy(
            INFOGAIN, SMALL_CAMERA, scorer=_one_feature_scorer("unobserved_relative")
        )
        episode = run_episode(tiny, "original", start, learned)
        assert episode.views == ig.views
        assert learned.counts["planned"] == 9 and len(learned.last_gains) == 1
        far = LearnedGainPolicy(INFOGAIN, SMALL_CAMERA,
                                scorer=_one_feature_scorer("angle_nearest"))  # fmt: skip
        assert (
            run_episode(tiny, "permuted", start, far).views
            == run_episode(tiny, "permuted", start, SpreadPolicy()).views
        )


def test_the_shipped_scorer_is_deterministic_and_needs_a_scorer(tiny):
    scorer = load_scorer(SHIPPED_SCORER)
    assert scorer.info["dataset_identity"] and scorer.info["selection_keys"]
    loaded = LearnedGainPolicy.from_checkpoint(SHIPPED_SCORER, SMALL_CAMERA, INFOGAIN)
    assert loaded.scorer.info == scorer.info and loaded.settings == INFOGAIN
    runs = [
        run_episode(tiny, "permuted", 7, LearnedGainPolicy(INFOGAIN, SMALL_CAMERA, scorer=scorer))
        for _ in range(2)
    ]
    assert runs[0].views == runs[1].views and len(set(runs[0].views)) == 10
    with pytest.raises(ValueError, match="needs a scorer"):
        run_episode(tiny, "original", 7, LearnedGainPolicy(INFOGAIN, SMALL_CAMERA))


def test_scorer_file_round_trip_equals_the_torch_network(tmp_path):
    torch.manual_seed(0)
    net = torch.nn.Sequential(
        torch.nn.Linear(len(FEATURES), 5), torch.nn.ReLU(), torch.nn.Linear(5, 3),
        torch.nn.ReLU(), torch.nn.Linear(3, 1),
    )  # fmt: skip
    save_scorer(tmp_path / "s.json", _scorer(net, {"made": "here"}))
    scorer = load_scorer(tmp_path / "s.json")
    x = np.random.default_rng(0).random((40, len(FEATURES)))
    with torch.no_grad():
        expected = net(torch.from_numpy(x).float()).squeeze(-1).numpy()
    np.testing.assert_allclose(scorer.scores(x), expected, atol=1e-5)
    assert scorer.info == {"made": "here"}


def test_unusable_scorer_files_are_refused_with_their_name(tmp_path):
    path = tmp_path / "s.json"
    with pytest.raises(ScorerError, match="s.json: no such scorer file"):
        load_scorer(path)
    path.write_text("{not json")
    with pytest.raises(ScorerError, match="s.json: not a readable JSON"):
        load_scorer(path)
    path.write_text(json.dumps({"format": "other"}))
    with pytest.raises(ScorerError, match="not a scorer file"):
        load_scorer(path)
    good = json.loads(SHIPPED_SCORER.read_text())
    path.write_text(json.dumps({**good, "features": good["features"][:-1]}))
    with pytest.raises(ScorerError, match="train it again"):
        load_scorer(path)
    good["layers"][0]["bias"] = good["layers"][0]["bias"][:-1]
    path.write_text(json.dumps(good))
    with pytest.raises(ScorerError, match="unusable layers"):
        load_scorer(path)


def test_a_mixed_viewspace_keeps_each_view_whole(tiny):
    views = [tiny.views["original"], tiny.views["permuted"]]
    picks = np.array([[1, 4], [0, 0], [1, 32], [0, 7]])
    mixed = mixed_views(views, picks)
    assert mixed.poses.shape == (4, 4, 4) and len(mixed.offsets) == 5
    for row, (i, v) in enumerate(picks):
        np.testing.assert_array_equal(mixed.poses[row], views[i].poses[v])
        np.testing.assert_array_equal(mixed.view_points(row), views[i].view_points(v))
        np.testing.assert_array_equal(mixed.coverage[row], views[i].coverage[v])
        np.testing.assert_array_equal(mixed.view_hulls()[row], views[i].view_hulls()[v])


def test_captured_share_of_the_best_gain():
    gains = np.array([[0.2, 0.5, 0.0], [0.1, 0.3, 9.0]])
    pad = np.array([[False, False, False], [False, False, True]])
    scores = np.array([[1.0, 0.0, 5.0], [0.0, 1.0, 7.0]])
    # Row 0 picks the third candidate (gain 0 of the best 0.5); row 1 the second (0.3 of 0.3):
    # its padded third candidate is neither picked nor its best.
    assert captured(scores, gains, pad) == pytest.approx((0.0 + 0.3) / (0.5 + 0.3))


@pytest.mark.slow
def test_a_real_training_run_is_reproducible_and_keeps_its_decisions(tmp_path_factory):
    data = make_train_dataset(tmp_path_factory.mktemp("scorer_data"))
    out = tmp_path_factory.mktemp("scorer_run")
    settings = ScorerSettings(data, out, starts=1, n_views=4, epochs=3, workers=1, hidden=(4,))
    best = run(settings)
    assert 1 <= best["epoch"] <= 3 and 0 < best["val_captured"] <= 1
    assert 0 < best["val_captured_ig"] <= 1
    first = (out / "scorer.json").read_bytes()
    scorer = load_scorer(out / "scorer.json")
    assert scorer.info["epoch"] == best["epoch"] and len(scorer.info["selection_keys"]) == 8
    header, *rows = (out / "metrics.csv").read_text().splitlines()
    assert len(rows) == 3 and "train_spearman" in header and "val_spearman" in header
    # 8 models x 3 viewspaces (original, permuted, a mix) x 1 episode x 3 decisions, each split.
    decisions = np.load(out / "decisions.npz")
    assert decisions["train_gains"].shape == (8 * 3 * 3, 32)
    assert decisions["valid_gains"].shape == (8 * 3 * 3, 32)
    assert np.bincount(decisions["valid_model"]).tolist() == [9] * 8
    lines = (out / "val_spearman_by_model.csv").read_text().splitlines()
    assert lines[0] == "epoch,model,samples,spearman" and len(lines) == 1 + 3 * 8
    assert {line.split(",")[1] for line in lines[1:]} == set(scorer.info["selection_keys"])
    stamp = (out / "decisions.npz").stat().st_mtime_ns
    again = run(settings)
    assert (again["epoch"], again["val_captured"]) == (best["epoch"], best["val_captured"])
    assert (out / "scorer.json").read_bytes() == first
    assert (out / "decisions.npz").stat().st_mtime_ns == stamp  # kept, not made again
    # A smaller training set holds the same decisions of the same models, and says its size.
    small = run(replace(settings, out_dir=out / "small", max_models=3))
    assert load_scorer(out / "small" / "scorer.json").info["train_models"] == 3 and small
    full, part = decisions, np.load(out / "small" / "decisions.npz")
    keys = {
        name: json.loads(str(d["train_meta"]))["keys"]
        for name, d in (("full", full), ("part", part))
    }
    assert len(keys["part"]) == 3 and set(keys["part"]) < set(keys["full"])
    for i, key in enumerate(keys["part"]):
        mine = part["train_gains"][part["train_model"] == i]
        theirs = full["train_gains"][full["train_model"] == keys["full"].index(key)]
        np.testing.assert_array_equal(mine, theirs)
    # Other decision settings make the decisions again.
    run(ScorerSettings(data, out, starts=1, mixes=0, n_views=3, epochs=1, workers=1, hidden=(4,)))
    assert np.load(out / "decisions.npz")["train_gains"].shape == (8 * 2 * 2, 32)


def test_settings_are_checked_by_name():
    with pytest.raises(ValueError, match="oracle_step_prob=0.8: must be in"):
        ScorerSettings(Path("d"), Path("o"), ig_step_prob=0.5, oracle_step_prob=0.8)
    with pytest.raises(ValueError, match="hidden"):
        ScorerSettings(Path("d"), Path("o"), hidden=(0,))


def test_the_benchmark_references_compute_the_same_features_and_decision():
    occupancy = OccupancyMap(OccupancySettings(resolution=0.1, bound=0.6, object_radius=None))
    rng = np.random.default_rng(4)
    state = rng.choice(3, len(occupancy.log_odds), p=[0.5, 0.35, 0.15])
    occupancy.log_odds[:] = np.where(state == 0, np.nan, np.where(state == 1, -0.4, 0.85))
    rows = np.sort(rng.integers(-1, len(occupancy.log_odds), (300, 14)), axis=1)[:, ::-1]
    near = frontier(occupancy)
    np.testing.assert_allclose(
        numpy_ray_features(occupancy.log_odds, rows, near, occupancy.settings.n),
        ray_features(occupancy, rows),
    )
    mesh = cup()
    camera = Intrinsics.centred(96, 72, 72.0)
    directions = np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, 0, 1], [1, 1, 1.0], [0, -1, 1]])
    poses = viewspace_poses(directions / np.linalg.norm(directions, axis=1, keepdims=True))
    depth = render_raycast(mesh.vertices, mesh.faces, poses, camera)
    views = [(v, backproject(depth[v], camera, poses[v])) for v in (1, 3)]
    settings = InfoGainSettings(resolution=0.04, block=4)
    scorer = load_scorer(SHIPPED_SCORER)
    assert decision(views, poses, camera, settings, scorer) == plain_decision(
        views, poses, camera, settings, scorer
    )


def test_the_shipped_scorer_looks_into_the_pocket():
    directions, poses, _, captured, voxels, occupancy = pocket_scene()
    open_ = np.flatnonzero(~captured)
    features = view_features(
        occupancy, voxels[open_], poses[:, :3, 3], list(np.flatnonzero(captured)), open_
    )
    assert open_[np.argmax(load_scorer(SHIPPED_SCORER).scores(features))] == INTO_POCKET
