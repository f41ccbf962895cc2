"""Training: real steps of a tiny PCNBV on a tiny synthetic dataset, resumption, bad input."""

from __future__ import annotations

import csv
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from datagen import TINY_NET, make_train_dataset

from nbv.models.checkpoints import CheckpointError, load_checkpoint
from nbv.models.precision import resolve_precision
from train.config import TrainConfigError, TrainSettings
from train.loop import run
from train.metrics import best_view_hits, spearman

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory) -> Path:
    return make_train_dataset(tmp_path_factory.mktemp("train") / "data")


def tiny_settings(dataset: Path, out: Path, **kw) -> TrainSettings:
    base = dict(
        dataset=dataset, out_dir=out, fold=3, net=TINY_NET, epochs=2, batch_size=8,
        train_points=32, eval_points=64, eval_every=1, start_views=(1, 30), progress=False,
    )  # fmt: skip
    base.update(kw)
    return TrainSettings(**base)


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_metrics_on_known_values():
    state = np.array([[True, False, False, False]])
    target = np.array([[9.0, 0.1, 0.5, 0.3]])
    assert spearman(np.array([[0, 1.0, 3.0, 2.0]]), target, state) == pytest.approx(1.0)
    assert spearman(np.array([[0, 3.0, 1.0, 2.0]]), target, state) == pytest.approx(-1.0)
    assert best_view_hits(np.array([[99, 0, 5, 1.0]]), target, state) == 1.0
    assert best_view_hits(np.array([[99, 5, 0, 1.0]]), target, state) == 0.0


def test_training_runs_checkpoints_and_resumes(tiny_dataset, tmp_path):
    settings = tiny_settings(tiny_dataset, tmp_path / "a")
    result = run(settings)
    rows = read_csv(tmp_path / "a" / "metrics.csv")
    assert [int(r["epoch"]) for r in rows] == [1, 2]
    for column in ("train_loss", "val_loss", "val_spearman", "val_best_view_hits", "val_auc"):
        assert np.isfinite(float(rows[-1][column]))
    assert 0 < result["random_auc"] < result["oracle_auc"] <= 1
    model, extra = load_checkpoint(tmp_path / "a" / "best.pt", n_views=33)
    assert extra["held_out"] == "chair" and extra["input"] == "points"
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


def test_signature_model_trains(tiny_dataset, tmp_path):
    result = run(tiny_settings(tiny_dataset, tmp_path, input="signature", epochs=1))
    assert np.isfinite(result["best_auc"])
    _, extra = load_checkpoint(tmp_path / "best.pt")
    assert extra["input"] == "signature" and extra["lmax"] == 2
    # precision=auto is stored resolved: the arithmetic the network was trained in.
    assert extra["precision"] == resolve_precision("auto", "cpu") in ("fp32", "bf16")


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


def test_training_loss_drops(tiny_dataset, tmp_path):
    run(tiny_settings(tiny_dataset, tmp_path, epochs=6, lr=3e-3, eval_every=6))
    losses = [float(r["train_loss"]) for r in read_csv(tmp_path / "metrics.csv")]
    assert losses[-1] < 0.7 * losses[0]


@pytest.mark.parametrize(
    "bad, message",
    [
        (dict(fold=8), "fold=8"),
        (dict(score="loud"), "score"),
        (dict(device="tpu"), "device"),
        (dict(precision="fp16"), "precision"),
    ],
)
def test_bad_settings_are_refused(tmp_path, bad, message):
    with pytest.raises(TrainConfigError, match=message):
        tiny_settings(tmp_path, tmp_path, **bad)


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
    with pytest.raises(CheckpointError, match="another network"):
        run(tiny_settings(tiny_dataset, other, epochs=2, net={**TINY_NET, "fc_channels": [16]}))


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
    bad_fold = subprocess.run(base + ["fold=9"], cwd=ROOT, capture_output=True, text=True)
    assert bad_fold.returncode == 2 and "fold=9" in bad_fold.stderr
    bad_score = subprocess.run(base + ["score=loud"], cwd=ROOT, capture_output=True, text=True)
    assert bad_score.returncode != 0 and "coverage" in bad_score.stderr
    no_data = subprocess.run(
        base + [f"dataset={tmp_path / 'nowhere'}"], cwd=ROOT, capture_output=True, text=True
    )
    assert no_data.returncode == 2 and "make dataset" in no_data.stderr
