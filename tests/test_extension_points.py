"""The four extension points (docs/development.md, "Adding a method / a network / a mesh source /
a metric"): a toy of each, declared in its one place and nowhere else, is found in the outputs:
a toy method's episodes, a toy metric in the report's tables and summary.csv, a toy source in a
prepared evaluation, a toy network trained one step by ``python -m train``'s trainer."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from datagen import SMALL_CAMERA, make_tiny_dataset, make_train_dataset, write_meshes
from evalgen import tiny_settings

import nbv.eval.metrics
from nbv.assets.catalogues import folder_catalogue
from nbv.assets.mesh_sources import MESH_SOURCES, MeshSource
from nbv.eval.config import PrepareSettings
from nbv.eval.evaluate import run
from nbv.models.networks import NETWORKS, Network
from nbv.policies.method import Method
from nbv.policies.registry import METHODS, NETWORK_INPUTS


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> dict[str, Path]:
    """The tiny dataset; no network checkpoint (no network method runs here)."""
    tmp = tmp_path_factory.mktemp("extension")
    return {"data": make_tiny_dataset(tmp / "data"), **dict.fromkeys(NETWORK_INPUTS, tmp / "no.pt")}


def _settings(tiny: dict, out: Path, **kw):
    return tiny_settings(tiny, out, checks=(), viewspaces=("original",), plots=False, **kw)


def _episodes(out: Path) -> list[dict]:
    return json.loads((out / "results.json").read_text())["episodes"]


class FirstUnvisited:
    """The toy method's policy: the lowest-numbered unvisited view."""

    def __init__(self) -> None:
        self.timings, self.notes, self.counts, self.last_gains = {}, [], {}, []

    def __call__(self, state) -> int:
        return int(np.flatnonzero(~state.view_state)[0])


@pytest.mark.slow
def test_a_toy_method_is_one_registry_row_and_runs_in_an_evaluation(tiny, tmp_path, monkeypatch):
    toy = Method(
        "toy_first", "the lowest-numbered unvisited view", lambda ctx, rng: FirstUnvisited()
    )
    monkeypatch.setitem(METHODS, toy.name, toy)
    run(_settings(tiny, tmp_path / "out", methods=("random", toy.name)))
    mine = [e for e in _episodes(tmp_path / "out") if e["method"] == toy.name]
    assert mine and all(len(e["views"]) == 10 for e in mine)
    for e in mine:  # the start view, then 0, 1, 2, ... skipping it
        assert e["views"][1:] == [v for v in range(11) if v != e["views"][0]][:9]
    assert f"| {toy.name} |" in (tmp_path / "out" / "report.md").read_text()


@pytest.mark.slow
def test_a_toy_metric_is_one_declaration_and_reaches_every_table(tiny, tmp_path, monkeypatch):
    def turns(model_metrics, viewspace: str, views: list[int], coverage: list[float]) -> float:
        return float(np.count_nonzero(np.diff(views) < 0))  # views picked below the last one

    toy = nbv.eval.metrics.Metric("toy_turns", "toy turns", 2, True, paired=True, compute=turns)
    monkeypatch.setattr(nbv.eval.metrics, "METRICS", (*nbv.eval.metrics.METRICS, toy))
    run(_settings(tiny, tmp_path / "out", methods=("random", "spread", "oracle")))
    episodes = _episodes(tmp_path / "out")
    for e in episodes:
        assert e["metrics"]["toy_turns"] == np.count_nonzero(np.diff(e["views"]) < 0)
    report = (tmp_path / "out" / "report.md").read_text()
    assert "| path | shortest path | toy turns |" in report  # the table of means
    assert "| F-score 2 eps | path | toy turns |" in report  # the paired tables
    with open(tmp_path / "out" / "summary.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    oracle = [r for r in rows if r["method"] == "oracle" and not r["check"]]
    want = np.mean([e["metrics"]["toy_turns"] for e in episodes if e["method"] == "oracle"])
    assert oracle and float(oracle[0]["toy_turns"]) == pytest.approx(want)


@pytest.mark.slow
def test_a_toy_mesh_source_is_one_row_and_an_evaluation_prepares_it(tiny, tmp_path, monkeypatch):
    folder = write_meshes(tmp_path / "toys", bad=False)
    toy = MeshSource(
        "toys", "the test's own boxes and balls", folder_catalogue,
        installed=lambda: folder, evaluation="toyset",
    )  # fmt: skip
    monkeypatch.setitem(MESH_SOURCES, toy.name, toy)
    prepare = PrepareSettings(dir=tmp_path / "prepared", camera=SMALL_CAMERA, n_gt=1000,
                              points_per_view=50)  # fmt: skip
    run(_settings(tiny, tmp_path / "out", datasets=("toyset",), prepare=prepare,
                  methods=("random",), start_views=(1,)))  # fmt: skip
    episodes = _episodes(tmp_path / "out")
    assert {e["dataset"] for e in episodes} == {"toyset"}
    assert {e["key"] for e in episodes} == {"box", "ball", "parts"}
    shard = next((tmp_path / "prepared").rglob("shard-*.h5"))
    import h5py

    with h5py.File(shard, "r") as handle:
        assert handle.attrs["licence"] == toy.licence
        assert json.loads(handle.attrs["config"])["source"] == "toys"


@dataclass(frozen=True)
class ToyConfig:
    """The toy network's sizes: one output per view."""

    n_views: int = 33
    hidden: int = 8

    def to_dict(self) -> dict:
        return {"n_views": self.n_views, "hidden": self.hidden}

    @classmethod
    def from_dict(cls, d: dict) -> ToyConfig:
        return cls(**d)


class ToyNet(torch.nn.Module):
    """A score per view from the cloud's mean and the view state."""

    def __init__(self, config: ToyConfig) -> None:
        super().__init__()
        self.config = config
        self.cloud = torch.nn.Linear(3, config.hidden)
        self.out = torch.nn.Linear(config.hidden + config.n_views, config.n_views)

    def forward(self, points: torch.Tensor, view_state: torch.Tensor) -> torch.Tensor:
        pooled = torch.relu(self.cloud(points.float())).mean(dim=1)
        return self.out(torch.cat([pooled, view_state.float()], dim=1))


@pytest.mark.slow
def test_a_toy_network_is_one_row_and_the_trainer_trains_it(tmp_path, monkeypatch):
    from nbv.policies.network import NetworkPolicy
    from train.config import ModelSettings, TrainSettings
    from train.loop import run

    toy = Network("toy", "a linear toy", f"{__name__}:ToyConfig", f"{__name__}:ToyNet", "train")
    monkeypatch.setitem(NETWORKS, toy.name, toy)
    settings = TrainSettings(
        dataset=make_train_dataset(tmp_path / "data"), out_dir=tmp_path / "run", fold=3,
        epochs=1, batch_size=8, train_points=32, eval_points=64, start_views=(1, 30),
        progress=False, model=ModelSettings("toy", "points", {}, network="toy"),
    )  # fmt: skip
    result = run(settings)
    assert np.isfinite(result["last"]["train_loss"]) and "val_auc" in result["last"]
    # Its checkpoint names it and loads as it: a policy of the evaluator, deciding.
    policy = NetworkPolicy.from_checkpoint(tmp_path / "run" / "best.pt")
    assert isinstance(policy.model, ToyNet) and policy.model.config == ToyConfig(n_views=33)
    state = np.zeros(33, dtype=bool)
    state[1] = True
    assert 0 <= policy.decide(np.random.default_rng(0).random((100, 3)), state) < 33
    # A network of another trainer is refused by name, with the command that trains it.
    with pytest.raises(ValueError, match="model.network=completion: trained by python -m "
                                         "train.completion"):  # fmt: skip
        ModelSettings("x", "points", {}, network="completion")
