"""Training: real steps of a tiny PCNBV on a tiny synthetic dataset, resumption, bad input, the
baselines a network's ranking is compared with, and the fitting check."""

from __future__ import annotations

import csv
import json
import runpy
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from datagen import make_tiny_dataset, make_train_dataset
from tiny_nets import TINY_NET

import nbv.dataset
from nbv.dataset.samples import SampleSet, SampleSettings, load_samples, model_samples
from nbv.models.checkpoints import CheckpointError, load_checkpoint
from nbv.models.precision import resolve_precision
from nbv.policies.network import NetworkPolicy
from train.config import ModelSettings, ScoreSettings, TrainConfigError, TrainSettings
from train.fitcheck import first_models, fit_check
from train.folds import split_samples
from train.loop import run
from train.metrics import best_view_hits, spearman, spearman_by_stage
from train.ranking_baselines import (
    baseline_spearman,
    fit_ridge,
    fit_view_ridge,
    nearest_visited_angles,
    normalised_targets,
    ridge_features,
    ridge_scores,
)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory) -> Path:
    return make_train_dataset(tmp_path_factory.mktemp("train") / "data")


def tiny_settings(
    dataset: Path,
    out: Path,
    score: str = "coverage",
    input: str = "points",
    net: dict = TINY_NET,
    **kw,
) -> TrainSettings:
    """The tiny network's settings (``score``, ``input``, ``net``: the groups' keys)."""
    base = dict(
        dataset=dataset, out_dir=out, fold=3, epochs=2, batch_size=8, train_points=32,
        eval_points=64, eval_every=1, start_views=(1, 30), progress=False,
        score=ScoreSettings(score), model=ModelSettings("tiny", input, net),
    )  # fmt: skip
    base.update(kw)
    return TrainSettings(**base)


#: The developer tool that ships weights (scripts/ship_weights.py).
ship = runpy.run_path(str(ROOT / "scripts" / "ship_weights.py"))["ship"]


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_spearman_by_model_ranks_each_models_samples_alone(tmp_path):
    from train.metrics import spearman_by_model
    from train.run_log import append_csv_rows

    state = np.zeros((3, 4), bool)
    target = np.array([[1.0, 2, 3, 4], [1, 2, 3, 4], [4, 3, 2, 1]])
    pred = np.array([[1.0, 2, 3, 4], [4, 3, 2, 1], [4, 3, 2, 1]])
    rows = spearman_by_model(pred, target, state, np.array(["b", "a", "b"]))
    assert rows == [
        {"model": "b", "samples": 2, "spearman": pytest.approx(1.0)},
        {"model": "a", "samples": 1, "spearman": pytest.approx(-1.0)},
    ]
    path = tmp_path / "s.csv"
    append_csv_rows(path, [{"epoch": 1, **r} for r in rows])
    append_csv_rows(path, [{"epoch": 2, **rows[0]}])
    append_csv_rows(path, [{"epoch": 2, **rows[1]}])  # a resumed epoch 2 replaces the first one
    assert [(r["epoch"], r["model"]) for r in read_csv(path)] == [("1", "b"), ("1", "a"),
                                                                   ("2", "a")]  # fmt: skip


def test_metrics_on_known_values():
    state = np.array([[True, False, False, False]])
    target = np.array([[9.0, 0.1, 0.5, 0.3]])
    assert spearman(np.array([[0, 1.0, 3.0, 2.0]]), target, state) == pytest.approx(1.0)
    assert spearman(np.array([[0, 3.0, 1.0, 2.0]]), target, state) == pytest.approx(-1.0)
    assert best_view_hits(np.array([[99, 0, 5, 1.0]]), target, state) == 1.0
    assert best_view_hits(np.array([[99, 5, 0, 1.0]]), target, state) == 0.0


@pytest.mark.slow
def test_training_runs_checkpoints_and_resumes(tiny_dataset, tmp_path):
    settings = tiny_settings(tiny_dataset, tmp_path / "a")
    result = run(settings)
    rows = read_csv(tmp_path / "a" / "metrics.csv")
    by_model = read_csv(tmp_path / "a" / "val_spearman_by_model.csv")
    assert {r["epoch"] for r in by_model} == {"1", "2"}  # every epoch, every valid model
    assert sum(int(r["samples"]) for r in by_model if r["epoch"] == "1") == len(
        split_samples(load_samples(tiny_dataset, "coverage"), settings)[1]
    )
    assert [int(r["epoch"]) for r in rows] == [1, 2]
    stages = ("spearman", "spearman_early", "spearman_late")
    for column in ("train_loss", "val_loss", "val_best_view_hits", "val_auc") + tuple(
        f"{split}_{stage}" for split in ("val", "train") for stage in stages
    ):
        assert np.isfinite(float(rows[-1][column])), column
    # The baselines, once per run on the validation samples, and as constant columns.
    baselines = json.loads((tmp_path / "a" / "baselines.json").read_text())
    assert baselines["val_samples"] == sum(int(r["samples"]) for r in by_model if r["epoch"] == "1")
    for method in ("ridge", "spread"):
        for stage in stages:
            assert np.isfinite(baselines[method][stage])
            column = f"{method}_val_{stage}"
            assert [float(r[column]) for r in rows] == [baselines[method][stage]] * 2
    heldout = result["heldout_auc"]
    assert 0 < heldout["random"] < heldout["oracle"] <= 1 and heldout["spread"] <= heldout["oracle"]
    model, extra = load_checkpoint(tmp_path / "a" / "best.pt", n_views=33)
    assert extra["held_out"] == "chair" and extra["input"] == "points"
    # best.pt was chosen on the valid models of the other seven categories; the held-out
    # category is scored once, with that checkpoint, on all of its models.
    ds = nbv.dataset.open(tiny_dataset)
    assert sorted(ds.index[k][1] for k in extra["selection_keys"]) == sorted(
        c for c in settings.categories if c != "chair"
    )
    assert all(ds.index[k][2] == "valid" for k in extra["selection_keys"])
    scored = json.loads((tmp_path / "a" / "heldout.json").read_text())
    chair = ds.keys(category="chair")
    assert scored["episodes"] == [[k, s] for k in chair for s in settings.start_views]
    assert scored["random_repeats"] == 10
    assert scored["checkpoint"]["epoch"] == extra["epoch"]
    assert set(scored["auc"]) == {"network", "random", "spread", "oracle"}
    assert extra["settings"]["fold"] == 3 and len(extra["dataset_identity"]) == 16
    assert list((tmp_path / "a" / "tb").iterdir())
    # Resuming to 3 epochs equals training 3 epochs straight.
    run(replace(settings, epochs=3))
    straight = tmp_path / "b"
    run(replace(settings, epochs=3, out_dir=straight))
    resumed_rows, straight_rows = (
        read_csv(tmp_path / "a" / "metrics.csv"),
        read_csv(straight / "metrics.csv"),
    )
    assert [r["epoch"] for r in resumed_rows] == ["1", "2", "3"]
    assert resumed_rows[-1]["train_loss"] == straight_rows[-1]["train_loss"]
    a, _ = load_checkpoint(tmp_path / "a" / "last.pt")
    b, _ = load_checkpoint(straight / "last.pt")
    for (name, pa), pb in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        assert torch.equal(pa, pb), name


@pytest.mark.slow
def test_a_changed_setting_stops_a_resume(tiny_dataset, tmp_path):
    settings = tiny_settings(tiny_dataset, tmp_path, epochs=1)
    run(settings)
    for change, key in [
        (dict(lr=2e-3), "lr"), (dict(seed=1), "seed"), (dict(train_points=16), "train_points"),
        (dict(batch_size=4), "batch_size"), (dict(precision="bf16"), "precision"),
        (dict(start_views=(1, 3)), "start_views"), (dict(l2=0.0), "l2"),
        (dict(l2_scope="encoder"), "l2_scope"),
    ]:  # fmt: skip
        with pytest.raises(TrainConfigError, match=rf"{key} \(.*resume=false"):
            run(replace(settings, epochs=2, **change))
    # Regenerated samples (other bytes) stop it too.
    samples = next(tiny_dataset.glob("samples-*.h5"))
    backup = samples.read_bytes()
    try:
        import h5py

        with h5py.File(samples, "a") as handle:
            handle.attrs["touched"] = 1
        with pytest.raises(TrainConfigError, match="samples_identity"):
            run(replace(settings, epochs=2))
    finally:
        samples.write_bytes(backup)
    # Training on (more epochs) with the same settings is a resumption, not a change.
    run(replace(settings, epochs=2))
    # resume=false starts afresh: the result equals a run in a new folder.
    run(replace(settings, lr=2e-3, resume=False))
    run(replace(settings, lr=2e-3, out_dir=tmp_path / "fresh"))
    assert [r["epoch"] for r in read_csv(tmp_path / "metrics.csv")] == ["1"]
    a, _ = load_checkpoint(tmp_path / "last.pt")
    b, _ = load_checkpoint(tmp_path / "fresh" / "last.pt")
    for (name, pa), pb in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        assert torch.equal(pa, pb), name


@pytest.mark.slow
def test_select_last_keeps_the_last_epoch(tiny_dataset, tmp_path):
    run(tiny_settings(tiny_dataset, tmp_path, epochs=2, select="last", eval_every=5))
    _, extra = load_checkpoint(tmp_path / "best.pt")
    assert extra["epoch"] == 1 and extra["select"] == "last" and extra["selection_keys"] == []


def _samples(rows: list[tuple[str, str]]) -> SampleSet:
    n = len(rows)
    return SampleSet(
        points=np.zeros((n, 4, 3)), signature=np.zeros((n, 4, 3)),
        view_state=np.zeros((n, 5), bool), target=np.zeros((n, 5)), value=np.zeros(n),
        trajectory=np.zeros(n, int), step=np.arange(n),
        key=np.array([f"{c}/{s}{i}" for i, (c, s) in enumerate(rows)]),
        category=np.array([c for c, _ in rows]), split=np.array([s for _, s in rows]),
    )  # fmt: skip


def test_fold_filter_keeps_held_out_and_unseen_categories_out(tmp_path):
    rows = [
        (c, s) for c in ("chair", "car", "lamp", "bus", "bed") for s in ("train", "valid", "test")
    ]
    train, val = split_samples(_samples(rows), tiny_settings(tmp_path, tmp_path, fold=3))
    # Fold 3 holds out chair; bus and bed are unseen categories (not training ones).
    pairs = sorted(zip(train.category, train.split, strict=True))
    assert pairs == [("car", "train"), ("lamp", "train")]
    pairs = sorted(zip(val.category, val.split, strict=True))
    assert pairs == [("car", "valid"), ("lamp", "valid")]
    no_valid = [r for r in rows if r[1] != "valid"]
    with pytest.raises(ValueError, match="select=last"):
        split_samples(_samples(no_valid), tiny_settings(tmp_path, tmp_path, fold=3))
    train, val = split_samples(
        _samples(no_valid), tiny_settings(tmp_path, tmp_path, fold=3, select="last")
    )
    assert len(train) == 2 and len(val) == 0


def test_fold_minus_one_holds_no_category_out(tmp_path):
    rows = [(c, s) for c in ("chair", "car", "bus") for s in ("train", "valid", "test")]
    train, val = split_samples(_samples(rows), tiny_settings(tmp_path, tmp_path, fold=-1))
    assert sorted(zip(train.category, train.split, strict=True)) == [
        ("car", "train"), ("chair", "train")
    ]  # fmt: skip
    assert sorted(val.category) == ["car", "chair"]  # bus: an unseen category, never


def test_training_on_every_category_writes_no_heldout_score(tiny_dataset, tmp_path):
    result = run(tiny_settings(tiny_dataset, tmp_path, fold=-1, epochs=1))
    _, extra = load_checkpoint(tmp_path / "best.pt")
    assert extra["held_out"] is None and result["heldout_auc"] == {}
    assert result["selected_epoch"] == 1 and not (tmp_path / "heldout.json").exists()
    assert extra["selection_keys"]  # chosen on the valid split of all the categories


def test_a_pcnbv_checkpoint_ships_in_bfloat16_with_its_provenance(tiny_dataset, tmp_path):
    run(tiny_settings(tiny_dataset, tmp_path / "run", fold=-1, epochs=1))
    provenance = ship(tmp_path / "run" / "best.pt", tmp_path / "pcnbv.pt", "python -m x",
                      tiny_dataset)  # fmt: skip
    net, extra = load_checkpoint(tmp_path / "run" / "best.pt")
    shipped, shipped_extra = load_checkpoint(tmp_path / "pcnbv.pt")
    assert shipped_extra["shipped"] == provenance and "optimizer" not in shipped_extra
    assert shipped_extra["held_out"] is None and shipped_extra["epoch"] == extra["epoch"]
    for name, value in net.state_dict().items():
        if value.is_floating_point():
            torch.testing.assert_close(shipped.state_dict()[name], value.bfloat16().float())
    (tmp_path / "notes.pt").write_text("not a checkpoint")
    with pytest.raises(CheckpointError, match="notes.pt: not a checkpoint"):
        ship(tmp_path / "notes.pt", tmp_path / "x.pt", "python -m x", tiny_dataset)


def test_signature_model_trains(tiny_dataset, tmp_path):
    result = run(tiny_settings(tiny_dataset, tmp_path, input="signature", epochs=1))
    assert np.isfinite(result["best_val_auc"])
    _, extra = load_checkpoint(tmp_path / "best.pt")
    assert extra["input"] == "signature" and extra["lmax"] == 2
    # precision=auto is stored resolved: the arithmetic the network was trained in.
    assert extra["precision"] == resolve_precision("auto", "cpu") in ("fp32", "bf16")


@pytest.mark.slow
def test_bf16_training_is_reproducible_and_recorded(tiny_dataset, tmp_path):
    # Forced bf16 (emulated where the CPU lacks it): two runs give the same weights, and the
    # checkpoint records the precision the evaluator will use.
    for out in ("a", "b"):
        run(tiny_settings(tiny_dataset, tmp_path / out, epochs=1, precision="bf16"))
    a, extra = load_checkpoint(tmp_path / "a" / "last.pt")
    b, _ = load_checkpoint(tmp_path / "b" / "last.pt")
    assert extra["precision"] == "bf16"
    for (name, pa), pb in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        assert torch.equal(pa, pb), name


@pytest.mark.slow
def test_training_loss_drops_and_bf16_picks_as_fp32(tiny_dataset, tmp_path):
    run(tiny_settings(tiny_dataset, tmp_path, epochs=6, lr=3e-3, eval_every=6))
    losses = [float(r["train_loss"]) for r in read_csv(tmp_path / "metrics.csv")]
    assert losses[-1] < 0.7 * losses[0]
    # The trained checkpoint in bf16 (emulated where the CPU lacks it) picks the fp32 view
    # wherever fp32's best two views are not a near tie that bf16's 8-bit mantissa cannot order.
    fp32 = NetworkPolicy.from_checkpoint(tmp_path / "best.pt", precision="fp32")
    bf16 = NetworkPolicy.from_checkpoint(tmp_path / "best.pt", precision="bf16")
    samples = load_samples(tiny_dataset, "coverage")
    agree = clear = 0
    for i in range(0, len(samples), 3):
        cloud, state = samples.points[i, :64], samples.view_state[i].astype(bool)
        with torch.no_grad():
            x = torch.from_numpy(fp32.features(cloud).astype(np.float32))[None]
            scores = fp32.model(x, torch.from_numpy(state).float()[None])[0].numpy()
        top = np.sort(np.where(state, -np.inf, scores))[-2:]
        if top[1] - top[0] > 0.02 * max(np.abs(scores).max(), 1e-6):
            clear += 1
            agree += fp32.decide(cloud, state) == bf16.decide(cloud, state)
    assert clear >= 20 and agree == clear


@pytest.mark.parametrize(
    "bad, message",
    [
        (dict(fold=8), "fold=8"),
        (dict(fold=-2), "fold=-2.*or -1"),
        (dict(score="loud"), r"score.name='loud': must be one of coverage, vig"),
        (dict(input="cloud"), r"model.input='cloud': must be one of points, signature"),
        (dict(device="tpu"), "device"),
        (dict(precision="fp16"), "precision"),
        (dict(l2_scope="head"), r"l2_scope='head': must be one of all, encoder"),
        (dict(l2=-1e-4), "l2=-0.0001: must be a number >= 0"),
        (dict(lr_decay=0.0), r"lr_decay=0.0: must be a number in \(0, 1\]"),
        (dict(lr_decay=1.5), "lr_decay=1.5"),
        (dict(lr_step_epochs=0), "lr_step_epochs=0: must be an integer >= 1"),
    ],
)
def test_bad_settings_are_refused(tmp_path, bad, message):
    with pytest.raises(TrainConfigError, match=message):
        tiny_settings(tmp_path, tmp_path, **bad)


def test_the_authors_schedule_and_penalty_are_allowed(tmp_path):
    # Adam at 1e-4 decayed by 0.95 every epoch, the penalty on the encoder alone.
    settings = tiny_settings(tmp_path, tmp_path, lr=1e-4, lr_decay=0.95, lr_step_epochs=1,
                             l2_scope="encoder")  # fmt: skip
    assert (settings.lr_decay, settings.lr_step_epochs, settings.l2_scope) == (0.95, 1, "encoder")
    assert TrainSettings(dataset=tmp_path, out_dir=tmp_path).l2_scope == "all"


def test_the_training_loss_adds_the_penalty_of_its_scope(tmp_path):
    from nbv.models.config import PCNBVConfig
    from nbv.models.pcnbv import PCNBV
    from train.loop import loss_fn

    torch.manual_seed(0)
    net = PCNBV(PCNBVConfig(n_views=33, **TINY_NET))
    pred, target, state = torch.rand(3, 33), torch.rand(3, 33), torch.zeros(3, 33)
    settings = tiny_settings(tmp_path, tmp_path, l2=0.5, loss="squared")
    plain = float(((pred - target) ** 2).sum(dim=1).mean())
    head = sum(float((p.detach() ** 2).sum()) for n, p in net.named_parameters()
               if n.startswith("head.") and p.ndim > 1)  # fmt: skip
    every = loss_fn(net, pred, target, state, settings).item()
    encoder = loss_fn(net, pred, target, state, replace(settings, l2_scope="encoder")).item()
    assert every - encoder == pytest.approx(0.5 * head, rel=1e-4)
    assert float(loss_fn(net, pred, target, state, replace(settings, l2=0.0))) == pytest.approx(
        plain
    )


@pytest.mark.slow
def test_missing_samples_and_bad_checkpoints_stop_before_training(tiny_dataset, tmp_path):
    with pytest.raises(ValueError, match="no vig samples|samples"):
        run(tiny_settings(tiny_dataset, tmp_path / "v", score="vig"))
    out = tmp_path / "corrupt"
    out.mkdir()
    (out / "last.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="last.pt"):
        run(tiny_settings(tiny_dataset, out))
    other = tmp_path / "other"
    run(tiny_settings(tiny_dataset, other, epochs=1))
    with pytest.raises(TrainConfigError, match="net"):
        run(tiny_settings(tiny_dataset, other, epochs=2, net={**TINY_NET, "fc_channels": [16]}))


@pytest.mark.slow
def test_cli_trains_and_reports_bad_input(tiny_dataset, tmp_path):
    base = [
        sys.executable,
        "-m",
        "train",
        f"dataset={tiny_dataset}",
        "model=tiny",
        "progress=false",
        f"out_dir={tmp_path / 'cli'}",  # hydra's run folder too: nothing lands in the checkout
    ]
    done = subprocess.run(
        base + ["fold=2", "epochs=1", "batch_size=8", "train_points=32", "eval_points=64",
                "start_views=[1]"],
        cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "cli" / "best.pt").exists()
    # A sweep without out_dir trains in its own job folder: two sweeps never share a run.
    sweep = base[:3] + ["-m"] + [a for a in base[3:] if not a.startswith("out_dir=")] + [
        "fold=2", "epochs=1", "batch_size=8", "train_points=32", "eval_points=64",
        "start_views=[1]", f"hydra.sweep.dir={tmp_path / 'sweep'}",
    ]  # fmt: skip
    done = subprocess.run(sweep, cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "sweep" / "tiny_coverage_fold2" / "heldout.json").exists()
    bad_fold = subprocess.run(base + ["fold=9"], cwd=ROOT, capture_output=True, text=True)
    assert bad_fold.returncode == 2 and "fold=9" in bad_fold.stderr
    bad_score = subprocess.run(base + ["score=loud"], cwd=ROOT, capture_output=True, text=True)
    assert bad_score.returncode != 0 and "coverage" in bad_score.stderr
    no_data = subprocess.run(
        base + [f"dataset={tmp_path / 'nowhere'}"], cwd=ROOT, capture_output=True, text=True
    )
    assert no_data.returncode == 2 and "make dataset" in no_data.stderr


def _weights(path: Path) -> list[torch.Tensor]:
    return list(load_checkpoint(path)[0].state_dict().values())


@pytest.mark.slow
def test_loader_workers_give_the_same_weights_for_any_count(tiny_dataset, tmp_path):
    # Batches built ahead by threads, each from its own generator: 1 and 3 workers train alike;
    # the losses and augmentation run through them as well.
    for workers in (1, 3):
        settings = tiny_settings(tiny_dataset, tmp_path / f"w{workers}", epochs=1,
                                 loader_workers=workers, loss="listwise")  # fmt: skip
        run(settings)
    for a, b in zip(_weights(tmp_path / "w1" / "last.pt"), _weights(tmp_path / "w3" / "last.pt"),
                    strict=True):  # fmt: skip
        assert torch.equal(a, b)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device here")
def test_training_on_cuda_with_autocast_and_pinned_batches(tiny_dataset, tmp_path):
    result = run(tiny_settings(tiny_dataset, tmp_path, epochs=1, device="cuda", loader_workers=2,
                               precision="auto"))  # fmt: skip
    assert np.isfinite(result["best_val_auc"])
    _, extra = load_checkpoint(tmp_path / "best.pt")
    assert extra["precision"] in ("fp32", "bf16")


def test_spearman_by_stage_splits_early_and_late_steps():
    # Steps 0 and 1 are early, 2 and later late; each stage is the mean over its samples.
    state = np.zeros((4, 4), bool)
    target = np.array([[1.0, 2, 3, 4]] * 4)
    pred = np.array([[1.0, 2, 3, 4], [1, 2, 4, 3], [4, 3, 2, 1], [1, 2, 3, 4]])
    out = spearman_by_stage(pred, target, state, np.array([0, 1, 2, 5]))
    assert out == {
        "spearman": pytest.approx((1 + 0.8 - 1 + 1) / 4),
        "spearman_early": pytest.approx(0.9),
        "spearman_late": pytest.approx(0.0),
    }
    late_only = spearman_by_stage(pred[2:], target[2:], state[2:], np.array([2, 3]))
    assert np.isnan(late_only["spearman_early"]) and late_only["spearman_late"] == 0.0


def test_nearest_visited_angles_by_hand():
    directions = np.array([[2.0, 0, 0], [0, 1, 0], [0, 0, 3], [1, 1, 0]])
    state = np.array([[1, 0, 0, 0], [1, 1, 0, 0], [0, 0, 0, 0]], bool)
    angles = nearest_visited_angles(directions, state)
    right, diagonal = np.pi / 2, np.pi / 4
    expected = [[0, right, right, diagonal], [0, 0, right, diagonal], [np.pi] * 4]
    np.testing.assert_allclose(angles, expected, atol=1e-7)


def test_normalised_targets_divide_by_the_samples_largest_gain():
    out = normalised_targets(np.array([[0.0, 2, 1], [0, 0, 0]], np.float32))
    np.testing.assert_array_equal(out, [[0, 1, 0.5], [0, 0, 0]])


def test_ridge_recovers_a_linear_target_and_shrinks_by_hand():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(50, 4))
    w = np.array([0.5, -2.0, 0.0, 3.0])
    np.testing.assert_allclose(fit_ridge(x, x @ w, 0.0), w, atol=1e-12)
    # One feature: w = sum(x y) / (sum(x^2) + alpha) = (2 + 8) / (1 + 4 + 1).
    assert fit_ridge(np.array([[1.0], [2.0]]), np.array([2.0, 4.0]), 1.0) == pytest.approx([5 / 3])
    with pytest.raises(ValueError, match="alpha=-1"):
        fit_ridge(x, x @ w, -1)


def test_per_view_ridges_recover_each_views_own_linear_model():
    rng = np.random.default_rng(1)
    v = 4
    state = rng.random((60, v)) < 0.4
    state[np.arange(60), rng.integers(0, v, 60)] = True  # at least one visited view
    angles = nearest_visited_angles(rng.normal(size=(v, 3)), state)
    features = ridge_features(state, angles, rng.integers(0, 10, 60))
    assert features.shape == (60, v, v + 3)
    np.testing.assert_array_equal(
        features[:, 2, v:], np.c_[angles[:, 2], features[:, 0, v + 1], np.ones(60)]
    )
    weights = rng.normal(size=(v, v + 3))
    weights[np.arange(v), np.arange(v)] = 0.0  # a view's own bit is 0 wherever it is a candidate
    target = np.where(state, 0.0, ridge_scores(features, weights))
    np.testing.assert_allclose(fit_view_ridge(features, target, state, 0.0), weights, atol=1e-9)


def _stage_samples(state: np.ndarray, target: np.ndarray, step: np.ndarray) -> SampleSet:
    n = len(step)
    return SampleSet(
        points=np.zeros((n, 4, 3)), signature=np.zeros((n, 4, 3)), view_state=state,
        target=target, value=np.zeros(n), trajectory=np.zeros(n, int), step=step,
        key=np.full(n, "m"), category=np.full(n, "chair"), split=np.full(n, "train"),
    )  # fmt: skip


def test_baselines_score_the_ridge_and_the_spread_angle_on_the_validation_samples():
    # View 0 is never visited and always gains most (1); every other open view v gains
    # c_v (1 + 0.02 step): a per-view linear model of the step ranks them all exactly, while
    # the angle to the visited views knows nothing of c.
    rng = np.random.default_rng(2)
    directions = rng.normal(size=(6, 3))
    c = np.array([1.0, 0.5, 0.2, 0.8, 0.3, 0.6])

    def samples(n: int) -> SampleSet:
        state = rng.random((n, 6)) < 0.4
        state[:, 0] = False
        state[np.arange(n), rng.integers(1, 6, n)] = True
        step = rng.integers(0, 10, n)
        target = np.where(state, 0.0, c * (1 + 0.02 * step[:, None]))
        target[:, 0] = 1.0
        return _stage_samples(state, target, step)

    train, val = samples(200), samples(80)
    out = baseline_spearman(train, val, directions, alpha=0.0)
    assert out["ridge"] == {k: pytest.approx(1.0) for k in out["ridge"]}
    angles = nearest_visited_angles(directions, val.view_state)
    assert out["spread"] == spearman_by_stage(angles, val.target, val.view_state, val.step)
    assert out["spread"]["spearman"] < 0.9


def _few_models(dataset: Path, count: int) -> SampleSet:
    """The coverage samples of the first ``count`` training models of ``dataset``, 4 trajectories
    of 10 steps each (the default dataset's)."""
    ds = nbv.dataset.open(dataset)
    parts = []
    for key in ds.keys(split="train")[:count]:
        drawn = SampleSettings(n_points=64, lmax=2, scores=("coverage",))
        arrays = model_samples(ds.model(key, ("original",)), "coverage", drawn)
        n = len(arrays["step"])
        arrays.update(key=np.full(n, key), category=np.full(n, ds.index[key][1]),
                      split=np.full(n, "train"))  # fmt: skip
        parts.append(arrays)
    return SampleSet(**{k: np.concatenate([p[k] for p in parts]) for k in parts[0]})


def test_first_models_keeps_every_sample_of_the_first_models_of_a_split():
    rows = [("chair", "valid"), ("chair", "train"), ("car", "train"), ("car", "train")]
    samples = _samples(rows)
    samples.key[3] = samples.key[2]  # two samples of one model
    picked = first_models(samples, 2)
    assert picked.key.tolist() == samples.key[1:].tolist()
    with pytest.raises(ValueError, match="3 train models wanted, the samples hold 2"):
        first_models(samples, 3)


#: A small PCNBV-sph for the fitting check: the tiny network's point encoder with a wider head
#: (the tiny head of 32 channels fits no loss's rankings of 80 samples to 0.85).
FIT_NET = {**TINY_NET, "conv_channels": [256], "fc_channels": [256, 128]}


@pytest.mark.slow
def test_the_network_overfits_a_few_models_with_the_default_loss(tiny_dataset, tmp_path):
    # The fitting check: 80 samples of 2 models, 80 epochs of real training steps with the
    # default loss, rate and penalty. The default loss ranks their views (Spearman >= 0.85 on
    # the samples it trained on; 0.93 measured); the paper's squared error on the raw gains,
    # whose late steps weigh almost nothing, does not (0.6 measured).
    samples = _few_models(tiny_dataset, 2)
    assert len(samples) == 80 and set(samples.step) == set(range(10))
    settings = tiny_settings(tiny_dataset, tmp_path, input="signature", net=FIT_NET, epochs=80,
                             threads=1, precision="fp32")  # fmt: skip
    default = fit_check(samples, settings)
    assert [r["epoch"] for r in default] == list(range(1, 81))
    assert default[-1]["train_spearman"] >= 0.85
    assert min(default[-1]["train_spearman_early"], default[-1]["train_spearman_late"]) >= 0.8
    assert settings.loss != "squared"
    squared = fit_check(samples, replace(settings, loss="squared"))
    assert squared[-1]["train_spearman"] < 0.75


@pytest.mark.slow
def test_a_training_run_is_a_learning_curve_point(tiny_dataset, tmp_path):
    """nbv.eval.curve reads a `python -m train` run: the method its input and score play as, and
    its training models (one per training category, less the held-out chair of fold 3)."""
    from nbv.eval.curve import _learner

    run(tiny_settings(tiny_dataset, tmp_path / "cov", epochs=1))
    run(tiny_settings(tiny_dataset, tmp_path / "sph", epochs=1, input="signature"))
    method, kw, row = _learner(tmp_path / "cov")
    assert method == "pcnbv"
    assert kw == {"checkpoints": {"pcnbv": str(tmp_path / "cov" / "best.pt")}}
    assert (row["models"], row["epoch"]) == (7, 1)
    chosen = read_csv(tmp_path / "cov" / "metrics.csv")[0]
    assert row["validation"] == (
        f"{float(chosen['val_auc']):.3f} ({float(chosen['val_spearman']):+.3f})"
    )
    assert _learner(tmp_path / "sph")[0] == "pcnbv_sph"


@pytest.mark.slow
def test_a_training_run_plays_its_learning_curve(tiny_dataset, tmp_path):
    """nbv.eval.curve end to end on a `python -m train` run: the run's own checkpoint plays the
    unseen models (it used to be refused: the run's checkpoints were passed twice)."""
    from nbv.eval.curve import curve

    run(tiny_settings(tiny_dataset, tmp_path / "cov", epochs=1))
    unseen = make_tiny_dataset(tmp_path / "unseen", models=1)
    (row,) = curve([tmp_path / "cov"], tmp_path / "curve", unseen)
    assert (row["method"], row["models"], row["epoch"]) == ("pcnbv", 7, 1)
    played = json.loads((tmp_path / "curve" / "eval_cov" / "results.json").read_text())
    assert played["settings"]["checkpoints"]["pcnbv"] == str(tmp_path / "cov" / "best.pt")
    assert "| 7 | 1 |" in (tmp_path / "curve" / "curve.md").read_text()
