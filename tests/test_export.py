"""``python -m nbv.export``: PC-NBV's layout, read back and rescored from the files alone.

Two small real evaluations (three meshes ray cast at 64 x 48, random with two seeds, spread and
the oracle): one of a dataset that kept every view point (``points_per_view=0``), one that kept
50 points a view. The files read back give the stored arrays exactly, and the coverage and AUC
recomputed from the exported files alone (a KD-tree nearest-neighbour test of the ground truth
against the merged selected views, eps from the manifest) equal the evaluator's: exactly for the
full views, and from the exported coverage bits for the subsampled ones (whose PCDs can only
cover less).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
from datagen import SMALL_CAMERA, write_meshes
from scipy.spatial import cKDTree

import nbv.dataset
from nbv.eval.config import DisturbSettings, EvalSettings, PrepareSettings
from nbv.eval.evaluate import run as run_eval
from nbv.export.config import ExportSettings
from nbv.export.pcnbv_format import export, read_pcd, write_pcd
from nbv.export.sources import ExportError, from_dataset, from_eval_run

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("random", "spread", "oracle")
STARTS = (1, 24)


def evaluate(tmp: Path, points_per_view: int, viewspaces: tuple[str, ...]) -> Path:
    """A finished evaluation run of the three meshes of tests/datagen.py; returns its folder."""
    prepare = PrepareSettings(
        dir=tmp / "prepared", camera=SMALL_CAMERA, n_gt=1000, points_per_view=points_per_view
    )
    settings = EvalSettings(
        run="run", out_root=tmp, methods=METHODS, datasets=("meshes",),
        mesh_dir=write_meshes(tmp / "meshes", bad=False), prepare=prepare,
        viewspaces=viewspaces, start_views=STARTS, disturb=DisturbSettings(checks=()),
        random_repeats=2, plots=False, progress=False, workers=1,
    )  # fmt: skip
    return run_eval(settings)


@pytest.fixture(scope="module")
def full_run(tmp_path_factory) -> Path:
    return evaluate(tmp_path_factory.mktemp("full"), 0, ("original", "permuted"))


@pytest.fixture(scope="module")
def sub_run(tmp_path_factory) -> Path:
    return evaluate(tmp_path_factory.mktemp("sub"), 50, ("original",))


def cli(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run(
        [sys.executable, "-m", "nbv.export", *args],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip


def undisturbed(run: Path) -> list[dict]:
    return [e for e in json.loads((run / "results.json").read_text())["episodes"]
            if e["check"] is None]  # fmt: skip


def pcd(path: Path) -> np.ndarray:
    """A PCD file's points through Open3D alone, as float32."""
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        return np.asarray(o3d.io.read_point_cloud(str(path), format="pcd").points, np.float32)


def rescore(out: Path, episode: dict, eps: float) -> tuple[list[float], float]:
    """Coverage after each view and the AUC of an exported episode, from the export's files only:
    the selected views' PCDs merged, a KD-tree, and the ground truth's nearest distances."""
    folder = out / "meshes" / episode["viewspace"]
    models = (out / "meshes" / "models.txt").read_text().split()
    exp = json.loads((out / "manifest.json").read_text())["experiments"]
    i = exp[f"meshes/{episode['viewspace']}"].index(episode["start"])
    starts = np.loadtxt(folder / "start" / f"test_init_{i}.txt", dtype=int)
    assert starts[models.index(episode["key"])] == episode["start"]
    method = episode["method"] + (f"_repeat{episode['repeat']}" if episode["repeat"] else "")
    selected = folder / "results" / method / str(i) / f"{episode['key']}_selected_views.txt"
    views = np.loadtxt(selected, dtype=int, ndmin=1)
    assert views.tolist() == episode["views"]
    gt = pcd(out / "meshes" / "gt" / f"{episode['key']}.pcd").astype(np.float64)
    coverage, merged = [], np.zeros((0, 3))
    for v in views:
        merged = np.concatenate([merged, pcd(folder / "pcd" / episode["key"] / f"{v}.pcd")])
        dist = cKDTree(merged).query(gt, k=1)[0] if len(merged) else np.full(len(gt), np.inf)
        coverage.append(np.count_nonzero(dist < eps) / len(gt))
    c = np.array(coverage)
    return coverage, float((c[:-1].sum() + 0.5 * c[-1]) / len(c))


def test_export_of_an_evaluation_reads_back_exactly_and_rescores_to_our_auc(full_run, tmp_path):
    done = cli(tmp_path, f"eval_run={full_run}", "out_dir=export", "progress=false")
    assert done.returncode == 0, done.stderr
    out = tmp_path / "export"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["coverage_from_pcd_is_exact"] is True
    info = manifest["datasets"]["meshes"]
    assert info["points_per_view"] == [0] and info["viewspaces"] == ["original", "permuted"]
    assert manifest["experiments"] == {"meshes/original": [1, 24], "meshes/permuted": [1, 24]}
    ds = nbv.dataset.open(info["path"])
    assert (out / "meshes" / "models.txt").read_text().split() == info["models"]
    assert sorted(info["models"]) == sorted(ds)
    for key in info["models"]:
        model = ds.model(key)
        np.testing.assert_array_equal(pcd(out / "meshes" / "gt" / f"{key}.pcd"), model.gt_points)
        for vs in ("original", "permuted"):
            view, folder = model.views[vs], out / "meshes" / vs
            for v in range(len(view.poses)):
                got = read_pcd(folder / "pcd" / key / f"{v}.pcd")
                assert got.dtype == np.float32
                np.testing.assert_array_equal(got, view.view_points(v))
            np.testing.assert_array_equal(np.load(folder / "coverage" / f"{key}.npy"),
                                          view.coverage)  # fmt: skip
            np.testing.assert_array_equal(np.loadtxt(folder / "viewspace.txt"), ds.viewspaces[vs])
    episodes = undisturbed(full_run)
    # 3 models x 2 viewspaces x 2 start views x (random twice, spread, oracle).
    assert len(episodes) == len(manifest["episodes"]) == 3 * 2 * 2 * 4
    for episode in episodes:
        coverage, auc = rescore(out, episode, info["eps"])
        assert coverage == episode["coverage"], episode
        assert auc == pytest.approx(episode["auc"], rel=0, abs=1e-15)


def test_subsampled_views_cover_less_and_the_exported_bits_give_our_auc(sub_run, tmp_path):
    sources, selections = from_eval_run(sub_run, methods=("oracle", "random"))
    out = tmp_path / "export"
    manifest = export(out, sources, selections)
    assert manifest["coverage_from_pcd_is_exact"] is False
    assert manifest["datasets"]["meshes"]["points_per_view"] == [50]
    assert sorted(p.name for p in (out / "meshes" / "original" / "results").iterdir()) == [
        "oracle", "random", "random_repeat1"]  # fmt: skip
    ds = sources[0].dataset
    eps = manifest["datasets"]["meshes"]["eps"]
    n_gt = manifest["datasets"]["meshes"]["n_gt"]
    episodes = [e for e in undisturbed(sub_run) if e["method"] in ("oracle", "random")]
    assert len(episodes) == len(manifest["episodes"]) == 3 * 2 * 3
    fewer = 0
    for episode in episodes:
        key, views = episode["key"], episode["views"]
        view = ds.model(key).views["original"]
        for v in views:
            got = read_pcd(out / "meshes" / "original" / "pcd" / key / f"{v}.pcd")
            np.testing.assert_array_equal(got, view.view_points(v))
        from_points, _ = rescore(out, episode, eps)
        bits = np.unpackbits(np.load(out / "meshes" / "original" / "coverage" / f"{key}.npy"),
                             axis=1, count=n_gt).astype(bool)  # fmt: skip
        from_bits = [np.count_nonzero(bits[views[: i + 1]].any(axis=0)) / n_gt
                     for i in range(len(views))]  # fmt: skip
        assert from_bits == episode["coverage"]
        assert all(p <= b for p, b in zip(from_points, from_bits, strict=True))
        fewer += from_points[-1] < from_bits[-1]
    assert fewer > 0  # 50 points a view do miss ground truth the full views cover


def test_a_dataset_exports_alone_in_ascii_and_reads_back_exactly(full_run, tmp_path):
    data = json.loads((full_run / "results.json").read_text())["datasets"][0]["path"]
    sources = from_dataset(Path(data), viewspaces=("permuted",), limit=1)
    out = tmp_path / "export"
    manifest = export(out, sources, ascii=True)
    assert manifest["episodes"] == [] and manifest["experiments"] == {}
    key = sources[0].keys[0]
    assert (out / "dataset" / "models.txt").read_text() == f"{key}\n"
    assert not (out / "dataset" / "original").exists()
    assert not (out / "dataset" / "permuted" / "results").exists()
    header = (out / "dataset" / "gt" / f"{key}.pcd").read_bytes()[:400]
    assert b"DATA ascii" in header and b"SIZE 4 4 4" in header
    model = sources[0].dataset.model(key)
    np.testing.assert_array_equal(read_pcd(out / "dataset" / "gt" / f"{key}.pcd"),
                                  model.gt_points)  # fmt: skip
    view = model.views["permuted"]
    for v in range(len(view.poses)):
        got = read_pcd(out / "dataset" / "permuted" / "pcd" / key / f"{v}.pcd")
        np.testing.assert_array_equal(got, view.view_points(v))
    readme = (out / "README.md").read_text()
    assert "pcd/<model>/<v>.pcd" in readme and "coverage_from_pcd_is_exact" in readme


def test_an_empty_view_is_a_header_only_pcd_read_back_as_no_points(tmp_path):
    write_pcd(tmp_path / "empty.pcd", np.zeros((0, 3), np.float32))
    assert read_pcd(tmp_path / "empty.pcd").shape == (0, 3)
    assert pcd(tmp_path / "empty.pcd").shape == (0, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.pcd"]


def test_bad_sources_are_refused_by_file_before_anything_is_written(full_run, tmp_path):
    (tmp_path / "unfinished").mkdir()
    (tmp_path / "unfinished" / "episodes.jsonl").write_text("{}\n")
    (tmp_path / "torn").mkdir()
    (tmp_path / "torn" / "results.json").write_text('{"datasets": [')
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "results.json").write_text('{"rows": []}')
    cases = [
        (lambda: from_eval_run(tmp_path / "nowhere"), "eval_run='" + str(tmp_path / "nowhere")
         + "': no such folder"),
        (lambda: from_eval_run(tmp_path / "unfinished"),
         f"{tmp_path / 'unfinished' / 'results.json'}: no such file; export needs a finished"),
        (lambda: from_eval_run(tmp_path / "torn"),
         f"{tmp_path / 'torn' / 'results.json'}: not JSON"),
        (lambda: from_eval_run(tmp_path / "other"),
         f"{tmp_path / 'other' / 'results.json'}: no ['datasets', 'episodes']"),
        (lambda: from_eval_run(full_run, methods=("hull_sco",)),
         f"methods: ['hull_sco'] not in {full_run / 'results.json'}; there: ['random', 'spread', "
         "'oracle']"),
        (lambda: from_eval_run(full_run, viewspaces=("sideways",)),
         "viewspace: ['sideways'] not in"),
        (lambda: from_dataset(tmp_path / "nowhere"), "no such dataset file or folder"),
    ]  # fmt: skip
    for call, message in cases:
        with pytest.raises(ExportError) as err:
            call()
        assert message in str(err.value)
    with pytest.raises(ValueError, match="eval_run and data_dir: both given; give exactly one"):
        ExportSettings(out_dir=tmp_path, eval_run=full_run, data_dir=tmp_path)
    with pytest.raises(ValueError, match="limit=0: must be null or an integer >= 1"):
        ExportSettings(out_dir=tmp_path, eval_run=full_run, limit=0)


@pytest.mark.parametrize(
    ("args", "line"),
    [
        ([], "nbv.export: eval_run and data_dir: neither given; give exactly one"),
        (["eval_run=nowhere"], "nbv.export: eval_run='nowhere': no such folder"),
        (["colour=red"], "nbv.export: colour: unknown key; allowed: eval_run, data_dir"),
    ],
)
def test_a_refused_export_says_why_in_one_line_and_leaves_no_folder(tmp_path, args, line):
    done = cli(tmp_path, *args, "out_dir=export")
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith(line), done.stderr
    assert list(tmp_path.iterdir()) == []


def test_an_export_is_not_written_over_another(full_run, tmp_path):
    data = json.loads((full_run / "results.json").read_text())["datasets"][0]["path"]
    first = cli(tmp_path, f"data_dir={data}", "limit=1", "out_dir=export", "progress=false")
    assert first.returncode == 0, first.stderr
    before = {p: p.read_bytes() for p in (tmp_path / "export").rglob("*") if p.is_file()}
    again = cli(tmp_path, f"data_dir={data}", "limit=2", "out_dir=export", "progress=false")
    assert again.returncode == 2
    assert again.stderr.strip().splitlines()[-1] == (
        "nbv.export: out_dir='export': holds an earlier export (manifest.json); give another "
        "out_dir or remove that one"
    )
    after = {p: p.read_bytes() for p in (tmp_path / "export").rglob("*") if p.is_file()}
    log = tmp_path / "export" / "export.log"
    assert after.keys() == before.keys() and log in after and len(before) > 30
    assert all(after[p] == before[p] for p in before if p != log)
    assert b"holds an earlier export" in after[log]  # the job log keeps the refusal
