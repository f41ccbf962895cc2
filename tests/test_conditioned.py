"""The viewspace-conditioned network: equivariance to the candidates' order, its checkpoints, its
training samples, and a real (tiny) training run whose checkpoint plays both viewspaces."""

import runpy
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from datagen import make_train_dataset
from tiny_nets import save_tiny_checkpoint

import nbv.dataset
from nbv.geometry.scores import coverage_gains
from nbv.infogain.settings import InfoGainSettings
from nbv.infogain.view_features import FEATURES
from nbv.models.checkpoints import CheckpointError
from nbv.models.view_conditioned import (
    ConditionedConfig,
    ViewConditionedNet,
    load_conditioned,
    save_conditioned,
)
from nbv.policies.conditioned_network import ConditionedPolicy
from nbv.policies.episode import EpisodeState, run_episode
from nbv.policies.infogain import InfoGainPolicy
from train.conditioned import _pool, draw_samples, run, split_models
from train.conditioned_config import VIEWSPACES, ConditionedSettings
from train.scorer import mixed_views

TINY = ConditionedConfig(point_channels=(8, 16), view_channels=(8,), visited_channels=4,
                         head_channels=(16,))  # fmt: skip


def _inputs(rng, b=3, n=40, v=7):
    points = torch.from_numpy(rng.normal(size=(b, n, 3)).astype(np.float32)) * 0.3
    directions = torch.nn.functional.normalize(torch.from_numpy(rng.normal(size=(b, v, 3))), dim=-1)
    state = torch.zeros(b, v)
    state[:, 0] = 1
    state[1, 3] = 1
    return points, directions.float(), state


def test_scores_follow_the_candidates_not_their_order():
    torch.manual_seed(0)
    net = ViewConditionedNet(TINY).eval()
    points, directions, state = _inputs(np.random.default_rng(0))
    order = torch.tensor([4, 2, 6, 0, 1, 5, 3])
    with torch.no_grad():
        scores = net(points, directions, state)
        shuffled = net(points, directions[:, order], state[:, order])
        # A point order means nothing either.
        again = net(points[:, torch.randperm(points.shape[1])], directions, state)
    torch.testing.assert_close(shuffled, scores[:, order])
    torch.testing.assert_close(again, scores)
    assert scores.shape == (3, 7) and scores.std() > 0
    # Any number of candidates: the first four alone score as among seven.
    with torch.no_grad():
        four = net(points, directions[:, :4], state[:, :4])
    torch.testing.assert_close(four[0], scores[0, :4])  # sample 0's visited view is among them


def test_checkpoint_round_trip_and_foreign_files(tmp_path):
    net = ViewConditionedNet(TINY)
    save_conditioned(tmp_path / "a.pt", net, {"eval_points": 64, "selection_keys": ["k"]})
    loaded, extra = load_conditioned(tmp_path / "a.pt")
    assert loaded.config == TINY and extra["eval_points"] == 64
    for name, value in net.state_dict().items():
        torch.testing.assert_close(loaded.state_dict()[name], value)
    policy = ConditionedPolicy.from_checkpoint(tmp_path / "a.pt")
    assert policy.n_points == 64 and policy.selected_on == ("k",)
    pcnbv = save_tiny_checkpoint(tmp_path / "pcnbv.pt", "points")
    with pytest.raises(CheckpointError, match="not a view-conditioned network checkpoint"):
        load_conditioned(pcnbv)
    with pytest.raises(CheckpointError, match="does not exist"):
        load_conditioned(tmp_path / "missing.pt")


def test_map_features_join_each_candidates_head():
    torch.manual_seed(0)
    net = ViewConditionedNet(replace(TINY, map_features=3)).eval()
    points, directions, state = _inputs(np.random.default_rng(1))
    features = torch.rand(3, 7, 3)
    with pytest.raises(ValueError, match="reads 3 map features per candidate; got features of "
                                         "shape None"):  # fmt: skip
        net(points, directions, state)
    with pytest.raises(ValueError, match=r"shape \(3, 7, 2\)"):
        net(points, directions, state, features[..., :2])
    with pytest.raises(ValueError, match="reads 0 map features"):
        ViewConditionedNet(TINY)(points, directions, state, features)
    order = torch.tensor([4, 2, 6, 0, 1, 5, 3])
    changed = features.clone()
    changed[:, 5] += 1.0
    with torch.no_grad():
        scores = net(points, directions, state, features)
        shuffled = net(points, directions[:, order], state[:, order], features[:, order])
        moved = net(points, directions, state, changed)
    torch.testing.assert_close(shuffled, scores[:, order])
    # A candidate's features change its own score only.
    torch.testing.assert_close(moved[:, :5], scores[:, :5])
    torch.testing.assert_close(moved[:, 6:], scores[:, 6:])
    assert (moved[:, 5] != scores[:, 5]).all()
    # Checkpoints keep the width; a config written before the option reads as none.
    assert (
        ConditionedConfig.from_dict(
            {k: v for k, v in TINY.to_dict().items() if k != "map_features"}
        )
        == TINY
    )


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return make_train_dataset(tmp_path_factory.mktemp("conditioned"))


@pytest.mark.slow
def test_samples_hold_the_true_gains_of_a_turned_scene(dataset):
    ds = nbv.dataset.open(dataset)
    pool = _pool(ds.model(ds.keys(split="train")[0]), ds.intrinsics)
    assert len(pool.directions) == 66
    settings = ConditionedSettings(dataset, dataset / "x", trajectories=3, steps=4, candidates=12,
                                   train_points=50)  # fmt: skip
    samples = draw_samples([pool], settings, np.random.default_rng(0))
    again = draw_samples([pool], settings, np.random.default_rng(0))
    for k, v in samples.items():
        np.testing.assert_array_equal(again[k], v)  # seeded
    assert samples["points"].shape == (12, 50, 3) and samples["target"].shape == (12, 12)
    assert (samples["view_state"].sum(axis=1) == np.tile(np.arange(1, 5), 3)).all()
    turns = set()
    for points, d, s, t, pick in zip(*(samples[k] for k in
                                      ("points", "directions", "view_state", "target", "pick")),
                                     strict=True):  # fmt: skip
        # The candidates are the pool's directions turned by one orthogonal map ...
        turn, *_ = np.linalg.lstsq(pool.directions[pick], d, rcond=None)
        np.testing.assert_allclose(turn.T @ turn, np.eye(3), atol=1e-5)
        np.testing.assert_allclose(turn[:, 1], [0, 1, 0], atol=1e-5)  # about the up axis
        turns.add(round(float(turn[0, 0]), 4))
        # ... the cloud is the visited views' points turned by the same map ...
        visited = np.concatenate([pool.points[p] for p in pick[s]])
        tree = np.abs(points[:, None] - (visited @ turn)[None]).sum(-1).min(axis=1)
        assert tree.max() < 1e-5
        # ... and the targets are the true gains of those candidates.
        np.testing.assert_allclose(t, coverage_gains(pool.bits[pick], s, pool.n_gt), atol=1e-7)
        assert t[s].max() == 0 and t.max() > 0
    assert len(turns) == 3  # every trajectory its own turn


def test_training_map_features_are_those_the_policy_reads(dataset):
    """The samples' map features (the pool's views traced once, a map per trajectory) equal
    the policy's (ig's incremental map of an episode on the same viewspace)."""
    ds = nbv.dataset.open(dataset)
    model = ds.model(ds.keys(split="train")[1], VIEWSPACES)
    settings = ConditionedSettings(dataset, dataset / "x", trajectories=2, steps=5, candidates=12,
                                   train_points=50, map_features=True)  # fmt: skip
    pool = _pool(model, ds.intrinsics, InfoGainSettings())
    samples = draw_samples([pool], settings, np.random.default_rng(3))
    plain = draw_samples([_pool(model, ds.intrinsics)], replace(settings, map_features=False),
                         np.random.default_rng(3))  # fmt: skip
    assert set(samples) == set(plain) | {"features"}
    for k, v in plain.items():  # the option adds features and changes nothing else
        np.testing.assert_array_equal(samples[k], v)
    assert samples["features"].shape == (10, 12, len(FEATURES))
    net = ViewConditionedNet(replace(TINY, map_features=len(FEATURES))).eval()
    stored = [model.views[name] for name in VIEWSPACES]
    n0 = len(stored[0].poses)
    for first in (0, 5):  # each trajectory's five samples
        pick = samples["pick"][first]
        model.views["mix"] = mixed_views(stored, np.stack([pick // n0, pick % n0], axis=1))
        policy = ConditionedPolicy(net).fresh(InfoGainPolicy(InfoGainSettings(), ds.intrinsics))
        order: list[int] = []
        for i in range(first, first + 5):
            state = samples["view_state"][i]
            order += [int(v) for v in np.flatnonzero(state) if v not in order]
            got = policy.map_features(
                EpisodeState(model.captured("mix"), state.copy(), list(order))
            )
            np.testing.assert_allclose(samples["features"][i], got, atol=1e-6)
            assert (got[state] == 0).all() and got[~state, 0].max() == 1.0
    with pytest.raises(ValueError, match="reads map features: build its policy with fresh"):
        ConditionedPolicy(net).map_features(EpisodeState(model.captured("mix"), state, order))


@pytest.mark.slow
def test_a_real_training_run_plays_both_viewspaces(dataset, tmp_path):
    settings = ConditionedSettings(
        dataset, tmp_path / "run", epochs=2, trajectories=1, steps=3, train_points=64,
        eval_points=64, start_views=(1, 10), net=TINY,
    )  # fmt: skip
    result = run(settings)
    assert set(result["last"]) >= {"train_spearman", "val_spearman", "val_auc_permuted"}
    assert (tmp_path / "run" / "metrics.csv").read_text().count("\n") == 3
    policy = ConditionedPolicy.from_checkpoint(tmp_path / "run" / "best.pt")
    ds = nbv.dataset.open(dataset)
    # Validation Spearman per epoch and per validation model.
    lines = (tmp_path / "run" / "val_spearman_by_model.csv").read_text().splitlines()
    valid = load_conditioned(tmp_path / "run" / "best.pt")[1]["selection_keys"]
    assert lines[0] == "epoch,model,samples,spearman"
    assert sorted(line.split(",")[1] for line in lines[1:]) == sorted(valid * 2)
    model = ds.model(ds.keys(split="valid")[0])
    for viewspace in ("original", "permuted"):
        episode = run_episode(model, viewspace, 1, policy.fresh())
        assert len(set(episode.views)) == 10
    # Resuming a finished run trains nothing more and gives the same result.
    assert run(settings)["last"] == result["last"]
    # So does a run saved before select_categories existed.
    shutil.copytree(tmp_path / "run", tmp_path / "older")
    net, extra = load_conditioned(tmp_path / "older" / "last.pt")
    del extra["settings"]["select_categories"]
    save_conditioned(tmp_path / "older" / "last.pt", net, extra)
    assert run(replace(settings, out_dir=tmp_path / "older"))["last"] == result["last"]
    # More epochs extend it: the same weights as a run started with them.
    shutil.copytree(tmp_path / "run", tmp_path / "copy")
    extended = run(replace(settings, epochs=3))
    fresh = run(replace(settings, epochs=3, out_dir=tmp_path / "three"))
    # A copied run folder goes on from where the copy stopped.
    copied = run(replace(settings, epochs=3, out_dir=tmp_path / "copy"))
    assert copied["last"]["train_loss"] == fresh["last"]["train_loss"]
    assert extended["last"] == {**fresh["last"], "seconds": extended["last"]["seconds"]}
    weights = [load_conditioned(tmp_path / d / "last.pt")[0].state_dict() for d in ("run", "three")]
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0])
    with pytest.raises(ValueError, match="trained with other settings"):
        run(replace(settings, epochs=2))  # fewer epochs than it holds
    with pytest.raises(ValueError, match="trained with other settings"):
        run(replace(settings, epochs=4, lr=1e-4))


def test_held_out_categories_choose_the_checkpoint_and_are_never_trained_on(dataset, tmp_path):
    ds = nbv.dataset.open(dataset)
    category = {k: ds.index[k][1] for k in ds.keys()}
    plain = ConditionedSettings(dataset, tmp_path / "plain")
    train_keys, valid_keys = split_models(ds, plain)
    assert train_keys == ds.keys(split="train") and valid_keys == ds.keys(split="valid")
    settings = ConditionedSettings(
        dataset, tmp_path / "run", epochs=1, trajectories=1, steps=2, train_points=64,
        eval_points=64, start_views=(1,), net=TINY, select_categories=("chair", "lamp"),
    )  # fmt: skip
    train_keys, valid_keys = split_models(ds, settings)
    # Both splits of the two categories validate; the other six train, on their train split.
    assert sorted(category[k] for k in valid_keys) == ["chair", "chair", "lamp", "lamp"]
    assert len(train_keys) == 6 and {category[k] for k in train_keys}.isdisjoint({"chair", "lamp"})
    assert set(train_keys) <= set(ds.keys(split="train"))
    run(settings)
    extra = load_conditioned(tmp_path / "run" / "best.pt")[1]
    assert sorted(extra["selection_keys"]) == sorted(valid_keys) and extra["train_models"] == 6
    assert ConditionedPolicy.from_checkpoint(tmp_path / "run" / "best.pt").selected_on == tuple(
        extra["selection_keys"]
    )
    for bad in (("piano",), tuple(plain.categories)):
        with pytest.raises(ValueError, match=r"select_categories=\[.*must be some, not all"):
            replace(settings, select_categories=bad)


@pytest.mark.slow
def test_a_real_training_run_with_map_features(dataset, tmp_path):
    from nbv.eval.config import EvalSettings
    from nbv.eval.curve import _learner
    from nbv.eval.inputs import load_networks
    from nbv.policies.method import MethodContext
    from nbv.policies.registry import METHODS

    settings = ConditionedSettings(
        dataset, tmp_path / "run", epochs=1, trajectories=1, steps=3, train_points=64,
        eval_points=64, start_views=(1,), net=TINY, map_features=True,
    )  # fmt: skip
    assert np.isfinite(run(settings)["last"]["val_spearman"])
    best = tmp_path / "run" / "best.pt"
    assert load_conditioned(best)[0].config.map_features == len(FEATURES)
    assert _learner(tmp_path / "run")[:2] == (
        "vcnbv_map",
        {"checkpoints": {"vcnbv_map": str(best)}},
    )
    eval_settings = EvalSettings(run="e", out_root=tmp_path, methods=("vcnbv_map",),
                                 checkpoints={"vcnbv_map": str(best)})  # fmt: skip
    networks, skipped = load_networks(eval_settings, 33)
    assert not skipped and networks["vcnbv_map"].reads_map
    ds = nbv.dataset.open(dataset)
    ctx = MethodContext(networks, None, ds.intrinsics, 0.01, 10)
    model = ds.model(ds.keys(split="valid")[0])
    for viewspace in ("original", "permuted"):
        policy = METHODS["vcnbv_map"].build(ctx, np.random.default_rng(0))
        episode = run_episode(model, viewspace, 1, policy)
        assert len(set(episode.views)) == 10
        assert len(policy.timings["map"]) == 9


def test_shipped_weights_load_and_replace_a_missing_checkpoint(tmp_path, dataset):
    from nbv.assets.weights import is_shipped, shipped_weights
    from nbv.eval.config import EvalSettings
    from nbv.eval.inputs import with_shipped_weights

    # The developer tool that ships weights.
    tool = Path(__file__).resolve().parents[1] / "scripts" / "ship_weights.py"
    ship = runpy.run_path(str(tool))["ship"]
    # Shipping keeps the weights to bfloat16 and records where they came from.
    torch.manual_seed(1)
    net = ViewConditionedNet(TINY)
    save_conditioned(tmp_path / "best.pt", net, {"eval_points": 64, "optimizer": {"state": {}}})
    provenance = ship(tmp_path / "best.pt", tmp_path / "shipped.pt", "python -m x", dataset)
    loaded, extra = load_conditioned(tmp_path / "shipped.pt")
    assert extra["shipped"] == provenance and "optimizer" not in extra
    assert len(provenance["dataset_identity"]) == 16
    for name, value in net.state_dict().items():
        torch.testing.assert_close(loaded.state_dict()[name], value.bfloat16().float())
    # The package's own vcnbv weights play an episode; they stand in for a missing checkpoint.
    path = shipped_weights("vcnbv")
    assert path is not None and is_shipped(path)
    policy = ConditionedPolicy.from_checkpoint(path)
    ds = nbv.dataset.open(dataset)
    episode = run_episode(ds.model(ds.keys(split="valid")[0]), "permuted", 3, policy)
    assert len(set(episode.views)) == 10
    # The shipped vcnbv_map weights read map features and play with a map.
    mapped = ConditionedPolicy.from_checkpoint(shipped_weights("vcnbv_map"))
    assert mapped.reads_map and not policy.reads_map
    mapped = mapped.fresh(InfoGainPolicy(InfoGainSettings(), ds.intrinsics))
    episode = run_episode(ds.model(ds.keys(split="valid")[0]), "permuted", 3, mapped)
    assert len(set(episode.views)) == 10
    missing = str(tmp_path / "no.pt")
    checkpoints = {
        name: missing for name in ("vcnbv", "vcnbv_map", "pcnbv", "pcnbv_sph", "pcnbv_sph_vig")
    }
    settings = EvalSettings(run="e", out_root=tmp_path, checkpoints=checkpoints)
    replaced = with_shipped_weights(settings).checkpoints
    assert replaced["vcnbv"] == str(path)
    for method in ("pcnbv", "pcnbv_sph", "pcnbv_sph_vig", "vcnbv_map"):  # shipped ones replace
        assert replaced[method] == str(shipped_weights(method) or missing)
    kept = EvalSettings(
        run="e", out_root=tmp_path, checkpoints={**replaced, "vcnbv": str(tmp_path / "shipped.pt")}
    )
    assert with_shipped_weights(kept).checkpoints["vcnbv"] == str(tmp_path / "shipped.pt")


def test_learning_curve_table_and_plot(tmp_path):
    from nbv.eval.curve import _auc_by_episode, _write

    episodes = [
        {"method": "random", "viewspace": "original", "key": "a", "start": 1, "auc": 0.5},
        {"method": "random", "viewspace": "original", "key": "a", "start": 1, "auc": 0.7},
        {"method": "spread", "viewspace": "original", "key": "a", "start": 1, "auc": 0.65},
    ]
    assert _auc_by_episode(episodes, "random", "original") == {("a", 1): pytest.approx(0.6)}
    assert _auc_by_episode(episodes, "random", "permuted") == {}
    row = {"method": "vcnbv", "epoch": 2, "validation": "0.700 / 0.690", "auc_permuted": 0.73,
           "minus_spread_original": "+0.01", "minus_spread_permuted": "-0.00"}  # fmt: skip
    rows = [{**row, "models": m, "auc_original": 0.72 + m / 1000} for m in (8, 16, 32)]
    lines = {
        f"{m}_{vs}": 0.7 for m in ("random", "spread", "oracle") for vs in ("original", "permuted")
    }
    _write(tmp_path, rows, lines)
    table = (tmp_path / "curve.md").read_text()
    assert table.count("\n| ") == 3 and "| 16 | 2 | 0.700 / 0.690 | 0.736 / 0.730 |" in table
    assert "val AUC orig / perm" in table
    assert (tmp_path / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # A curve of ig_learned's scorer runs names its validation score.
    _write(tmp_path, [{**r, "method": "ig_learned", "validation": "0.869 (ig 0.841)"}
                      for r in rows], lines)  # fmt: skip
    table = (tmp_path / "curve.md").read_text()
    assert "val share of the best gain" in table and "| 8 | 2 | 0.869 (ig 0.841) |" in table
