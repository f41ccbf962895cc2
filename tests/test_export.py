"""``python -m nbv.export``: PC-NBV's layout, scored from the files alone by PC-NBV's criterion.

The main check is a default-style evaluation (three meshes ray cast at 160 x 120, 16,384
ground-truth points, 2,048 points kept a view, eps = sqrt(5e-5); random with two seeds, spread
and the oracle, two viewspaces, two start views): its export is scored by PC-NBV's published
criterion, written here from its description and nothing else: a ground-truth point (from
``<model_dir>/<class>/<model>/model.mat``, key ``points``) is covered when some point of the
merged PCDs of the episode's views lies at squared distance below 5e-5 (float64,
``dx*dx + dy*dy + dz*dz``; "some point of the merged views" is "some view has a point", so each
view's mask is computed once and the masks OR-ed), and AUC = (c1 + ... + c9 + 0.5 c10) / 10.
That must give the evaluator's coverage curves and AUCs (results.json) to 1e-6; the dataset's
2,048-point views scored the same way give less, so the full views are what makes it agree.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import open3d as o3d
import pytest
from datagen import SMALL_CAMERA, small_settings, write_meshes
from scipy.io import loadmat
from scipy.spatial import cKDTree

import nbv.dataset
from nbv.dataset.generator import generate
from nbv.dataset.generator_settings import GeneratorSettings, Noise, Renderer, Synthetic
from nbv.eval.config import DisturbSettings, EvalSettings, PrepareSettings
from nbv.eval.evaluate import run as run_eval
from nbv.export.config import ExportSettings
from nbv.export.pcnbv_format import check_complete, export, read_pcd, write_pcd
from nbv.export.sources import ExportError, from_dataset, from_eval_run
from nbv.export.views import EMPTY_VIEW, FullViews
from nbv.geometry.camera import Intrinsics

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("random", "spread", "oracle")
STARTS = (1, 24)
#: PC-NBV's threshold on the squared distance, and the eps it means.
PCNBV_SQUARED = 5e-5
EPS = math.sqrt(5e-5)
#: A quarter of PC-NBV's 640 x 480 camera (f = 476 / 4): views of 4,000-9,000 points, so
#: keeping 2,048 of them drops most.
CAMERA = Intrinsics.centred(160, 120, 119.0)


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A finished evaluation of the three meshes of tests/datagen.py; returns its folder."""
    tmp = tmp_path_factory.mktemp("run")
    prepare = PrepareSettings(dir=tmp / "prepared", camera=CAMERA, eps=EPS)  # n_gt, 2048 default
    assert (prepare.n_gt, prepare.points_per_view, prepare.backend) == (16384, 2048, "raycast")
    settings = EvalSettings(
        run="run", out_root=tmp, methods=METHODS, datasets=("meshes",),
        mesh_dir=write_meshes(tmp / "meshes", bad=False), prepare=prepare,
        viewspaces=("original", "permuted"), start_views=STARTS,
        disturb=DisturbSettings(checks=()), random_repeats=2, plots=False, progress=False,
        workers=1,
    )  # fmt: skip
    return run_eval(settings)


@pytest.fixture(scope="module")
def exported(run, tmp_path_factory) -> Path:
    """The run exported by the command line."""
    tmp = tmp_path_factory.mktemp("export")
    done = cli(tmp, f"eval_run={run}", "out_dir=export", "progress=false")
    assert done.returncode == 0, done.stderr
    return tmp / "export"


def cli(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run(
        [sys.executable, "-m", "nbv.export", *args],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip


def undisturbed(run: Path) -> list[dict]:
    return [e for e in json.loads((run / "results.json").read_text())["episodes"]
            if e["check"] is None]  # fmt: skip


# --- PC-NBV's criterion, from its description, on files only -------------------------------


def pcd(path: Path) -> np.ndarray:
    """A PCD file's points as PC-NBV reads them (Open3D), float64."""
    return np.asarray(o3d.io.read_point_cloud(str(path), format="pcd").points)


def pcnbv_covered(merged: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """(n_gt,) bool: some merged point at squared distance < 5e-5 (float64). A KD-tree finds
    every point within a slightly larger radius; the decision is the squared-distance formula."""
    near = cKDTree(merged).query_ball_point(gt, r=math.sqrt(PCNBV_SQUARED) * (1 + 1e-6))
    rows = np.repeat(np.arange(len(gt)), [len(n) for n in near])
    cols = np.concatenate([np.asarray(n, dtype=np.intp) for n in near])
    d = merged[cols] - gt[rows]
    squared = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
    covered = np.zeros(len(gt), dtype=bool)
    covered[rows[squared < PCNBV_SQUARED]] = True
    return covered


def pcnbv_auc(coverage: list[float]) -> float:
    assert len(coverage) == 10  # PC-NBV's episodes: a start view and 9 more
    return (sum(coverage[:9]) + 0.5 * coverage[9]) / 10


def gt_of(folder: Path, key: str) -> np.ndarray:
    """``<model_dir>/<class>/<model>/model.mat``'s points; model_dir is ``<dataset>/gt``."""
    (path,) = (folder / "gt").glob(f"*/{key}/model.mat")
    return loadmat(path)["points"].astype(np.float64)


def rescore(out: Path, dataset: str, vs: str, method: str, experiment: int, key: str,
            clouds=None) -> tuple[int, list[int], list[float]]:  # fmt: skip
    """(start view, views, coverage after each view) of one exported episode, from the files:
    the start file's line of the model, its selected views, their PCDs (or ``clouds(view)``)."""
    models = (out / dataset / "models.txt").read_text().split()
    folder = out / dataset / vs
    start = int((folder / "start" / f"test_init_{experiment}.txt").read_text().split()[
        models.index(key)])  # fmt: skip
    selected = folder / "results" / method / str(experiment) / f"{key}_selected_views.txt"
    views = [int(v) for v in selected.read_text().split()]
    gt = gt_of(out / dataset, key)
    covered, coverage = np.zeros(len(gt), dtype=bool), []
    for v in views:
        # A point is covered by the merged views when one of them covers it (the test is "some
        # point within"), so each view's mask is computed once and OR-ed.
        if clouds is not None:
            mask = pcnbv_covered(clouds(v), gt)
        else:
            mask = view_mask(folder / "pcd" / key / f"{v}.pcd", gt)
        covered |= mask
        coverage.append(np.count_nonzero(covered) / len(gt))
    return start, views, coverage


_MASKS: dict[Path, np.ndarray] = {}


def view_mask(path: Path, gt: np.ndarray) -> np.ndarray:
    """PC-NBV's covered mask of one exported view (memoised: episodes share views)."""
    if path not in _MASKS:
        cloud = pcd(path)
        assert len(cloud) > 0  # an empty cloud would cover everything in PC-NBV's kernel
        _MASKS[path] = pcnbv_covered(cloud, gt)
    return _MASKS[path]


@pytest.mark.slow
def test_pcnbv_criterion_on_the_exported_files_gives_our_coverage_and_auc(run, exported):
    manifest = json.loads((exported / "manifest.json").read_text())
    info = manifest["datasets"]["meshes"]
    assert info["pcnbv_criterion"] is True and info["points_per_view"] == 2048
    assert {n["way"] for views in info["views"].values() for n in views.values()} == {"recast"}
    experiments = manifest["experiments"]
    assert experiments == {"meshes/original": [1, 24], "meshes/permuted": [1, 24]}
    episodes = undisturbed(run)
    # 3 models x 2 viewspaces x 2 start views x (random twice, spread once or more, oracle).
    assert len(episodes) == len(manifest["episodes"]) >= 48
    worst_coverage = worst_auc = 0.0
    for e in episodes:
        method = e["method"] + (f"_repeat{e['repeat']}" if e["repeat"] else "")
        i = experiments[f"meshes/{e['viewspace']}"].index(e["start"])
        start, views, coverage = rescore(exported, "meshes", e["viewspace"], method, i, e["key"])
        assert start == e["start"] and views == e["views"]
        worst_coverage = max(worst_coverage, np.abs(np.subtract(coverage, e["coverage"])).max())
        worst_auc = max(worst_auc, abs(pcnbv_auc(coverage) - e["auc"]))
    print(f"max |coverage - ours| {worst_coverage:.3g}, max |AUC - ours| {worst_auc:.3g}")
    assert worst_coverage <= 1e-6 and worst_auc <= 1e-6


@pytest.mark.slow
def test_the_stored_2048_point_views_would_score_lower(run, exported):
    """Why the export re-casts: the same criterion on the dataset's stored views finds less."""
    ds = nbv.dataset.open(json.loads((run / "results.json").read_text())["datasets"][0]["path"])
    lower, kept_fewer = [], 0
    for e in [e for e in undisturbed(run) if e["method"] == "oracle"]:
        view = ds.model(e["key"]).views[e["viewspace"]]
        for v in e["views"]:
            full = pcd(exported / "meshes" / e["viewspace"] / "pcd" / e["key"] / f"{v}.pcd")
            kept_fewer += len(view.view_points(v)) == 2048 < len(full)
        i = STARTS.index(e["start"])
        stored = lambda v, view=view: view.view_points(v).astype(np.float64)  # noqa: E731
        *_, coverage = rescore(exported, "meshes", e["viewspace"], "oracle", i, e["key"], stored)
        lower.append(e["auc"] - pcnbv_auc(coverage))
    print(f"stored 2048-point views: AUC lower by {min(lower):.4f} to {max(lower):.4f}")
    assert kept_fewer > 0 and min(lower) > 0.01, (kept_fewer, lower)


def test_the_export_layout_reads_back_the_dataset(run, exported):
    manifest = json.loads((exported / "manifest.json").read_text())
    info = manifest["datasets"]["meshes"]
    ds = nbv.dataset.open(info["path"])
    keys = (exported / "meshes" / "models.txt").read_text().split()
    assert keys == info["models"] and sorted(keys) == sorted(ds)
    classes = (exported / "meshes" / "classes.txt").read_text().split()
    assert classes == list(dict.fromkeys(ds.index[k][1] for k in keys))
    for key in keys:
        model = ds.model(key)
        mat = loadmat(exported / "meshes" / "gt" / model.category / key / "model.mat")
        assert mat["points"].dtype == np.float32
        np.testing.assert_array_equal(mat["points"], model.gt_points)
        for vs in ("original", "permuted"):
            folder = exported / "meshes" / vs
            np.testing.assert_array_equal(np.loadtxt(folder / "viewspace.txt"), ds.viewspaces[vs])
            np.testing.assert_array_equal(np.load(folder / "coverage" / f"{key}.npy"),
                                          model.views[vs].coverage)  # fmt: skip
            assert len(list((folder / "pcd" / key).glob("*.pcd"))) == 33
    for vs in ("original", "permuted"):
        for i, start in enumerate(STARTS):
            lines = (exported / "meshes" / vs / "start" / f"test_init_{i}.txt").read_text()
            assert lines == f"{start}\n" * len(keys)
    folders = {e["method"] + (f"_repeat{e['repeat']}" if e["repeat"] else "")
               for e in undisturbed(run)}  # fmt: skip
    assert {"oracle", "random", "random_repeat1", "spread"} <= folders
    results = exported / "meshes" / "original" / "results"
    assert sorted(p.name for p in results.iterdir()) == sorted(folders)
    readme = (exported / "README.md").read_text()
    assert "<class>/<model>/model.mat" in readme and "(1, 1, 1)" in readme


@pytest.mark.slow
def test_a_dataset_that_kept_every_point_exports_its_stored_points_in_ascii(tmp_path):
    summary = generate(small_settings(tmp_path, points_per_view=0, eps=EPS))
    sources = from_dataset(summary.shard_file, viewspaces=("permuted",), limit=2)
    assert sources[0].full.ways == ["stored", "recast"]  # ray cast: recast if stored fails
    manifest = export(tmp_path / "export", sources, ascii=True)
    assert manifest["episodes"] == [] and manifest["experiments"] == {}
    out = tmp_path / "export" / "dataset"
    assert not (out / "original").exists() and not (out / "permuted" / "results").exists()
    for key in sources[0].keys:
        assert manifest["datasets"]["dataset"]["views"][key]["permuted"]["way"] == "stored"
        model = sources[0].dataset.model(key)
        view = model.views["permuted"]
        gt = gt_of(out, key)
        for v in range(len(view.poses)):
            path = out / "permuted" / "pcd" / key / f"{v}.pcd"
            assert b"DATA ascii" in path.read_bytes()[:300]
            got = read_pcd(path)
            np.testing.assert_array_equal(got, view.view_points(v))  # float32 values, exactly
            bits = np.unpackbits(view.coverage[v], count=len(gt)).astype(bool)
            np.testing.assert_array_equal(pcnbv_covered(got, gt), bits)


def test_a_noisy_synthetic_dataset_is_recast_exactly_from_its_seed(tmp_path):
    """The synthetic shape is rebuilt from seed, category and index, and the depth noise drawn
    again over both viewspaces in the generator's order: every view's bits come back."""
    settings = GeneratorSettings(
        out_dir=tmp_path / "data", seed=3,
        synthetic=Synthetic(counts={"train": 0, "valid": 0, "test": 1, "unseen": 0}), limit=2,
        intrinsics=SMALL_CAMERA, n_gt=2000, eps=EPS, points_per_view=50,
        renderer=Renderer(backend="raycast", noise=Noise(enabled=True)), progress=False,
    )  # fmt: skip
    summary = generate(settings)
    sources = from_dataset(summary.shard_file, viewspaces=("permuted",))
    manifest = export(tmp_path / "export", sources)
    out, more = tmp_path / "export" / "dataset", 0
    for key in sources[0].keys:
        assert manifest["datasets"]["dataset"]["views"][key]["permuted"]["way"] == "recast"
        view = sources[0].dataset.model(key).views["permuted"]
        gt = gt_of(out, key)
        for v in range(len(view.poses)):
            cloud = pcd(out / "permuted" / "pcd" / key / f"{v}.pcd")
            kept = len(view.view_points(v))
            assert len(cloud) >= kept and (kept == 50 or len(cloud) == kept)
            more += len(cloud) > kept  # the full view, not the 50 kept
            bits = np.unpackbits(view.coverage[v], count=len(gt)).astype(bool)
            np.testing.assert_array_equal(pcnbv_covered(cloud, gt), bits)
    assert len(sources[0].keys) == 2 and more > 33


def test_a_recast_of_a_changed_mesh_is_refused_naming_it(tmp_path):
    summary = generate(small_settings(tmp_path, eps=EPS))
    (source,) = from_dataset(summary.shard_file)
    ds = source.dataset
    key = next(k for k in source.keys if ds.model(k).source_path.endswith("ball.obj"))
    # Another mesh in the same file: it normalises differently.
    (tmp_path / "meshes" / "ball.obj").write_text("v 0 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ExportError, match=f"model {key!r}: its source .* the mesh changed"):
        export(tmp_path / "export", [replace(source, keys=[key])])


def test_an_empty_view_is_one_far_point_that_covers_nothing(tmp_path):
    summary = generate(small_settings(tmp_path, points_per_view=0, eps=EPS))
    ds = nbv.dataset.open(summary.shard_file)
    model = ds.model(ds.keys()[0])
    view = model.views["original"]
    # View 5 emptied, as a flat object seen edge-on is: no points and no coverage bits.
    n = view.offsets[6] - view.offsets[5]
    points = np.delete(view.points, np.s_[view.offsets[5] : view.offsets[6]], axis=0)
    offsets = np.concatenate([view.offsets[:6], view.offsets[6:] - n])
    coverage = view.coverage.copy()
    coverage[5] = 0
    model.views["original"] = replace(view, points=points, offsets=offsets, coverage=coverage)
    clouds, notes = FullViews(ds).views(model, "original")
    assert notes.way == "stored" and notes.empty == [5] and notes.float64 == []
    np.testing.assert_array_equal(clouds[5], EMPTY_VIEW)
    write_pcd(tmp_path / "5.pcd", clouds[5])
    got = pcd(tmp_path / "5.pcd")
    np.testing.assert_array_equal(got, [[1.0, 1.0, 1.0]])
    assert not pcnbv_covered(got, model.gt_points.astype(np.float64)).any()
    # A view that lost its points but not its bits: the stored way fails, the re-cast gives
    # the view back; with no re-cast it is refused by name.
    coverage[5] = view.coverage[5]
    model.views["original"] = replace(view, points=points, offsets=offsets, coverage=coverage)
    full = FullViews(ds)
    clouds, notes = full.views(model, "original")
    assert notes.way == "recast" and notes.empty == [] and len(clouds[5]) == n
    full.ways = ["stored"]
    with pytest.raises(ExportError, match=r"viewspace original: views \[5\] \(stored\) do not"):
        full.views(model, "original")


def test_pcd_files_read_back_exactly_in_every_format(tmp_path):
    rng = np.random.default_rng(7)
    p64 = rng.normal(size=(100, 3))
    p32 = p64.astype(np.float32)
    for name, points, ascii, header in [
        ("b32", p32, False, b"SIZE 4 4 4\nTYPE F F F"),
        ("a32", p32, True, b"SIZE 4 4 4\nTYPE F F F"),
        ("a64", p64, False, b"SIZE 8 8 8\nTYPE F F F"),  # float64 is always ASCII
    ]:
        write_pcd(tmp_path / f"{name}.pcd", points, ascii)
        raw = (tmp_path / f"{name}.pcd").read_bytes()
        assert header in raw and (b"DATA binary" in raw) == (name == "b32")
        np.testing.assert_array_equal(pcd(tmp_path / f"{name}.pcd"), points)
        np.testing.assert_array_equal(read_pcd(tmp_path / f"{name}.pcd"), points)
    with pytest.raises(ValueError, match="must be float32 or float64, got int64"):
        write_pcd(tmp_path / "i.pcd", np.zeros((2, 3), dtype=np.int64))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a32.pcd", "a64.pcd", "b32.pcd"]


@pytest.mark.slow
def test_subsampled_views_of_a_blender_dataset_are_refused_in_one_line(tmp_path):
    """Neither stored full views nor a reproducible renderer: the line says how to get them."""
    summary = generate(small_settings(tmp_path, eps=EPS))
    blender = tmp_path / "blender.h5"
    shutil.copy(summary.shard_file, blender)
    with h5py.File(blender, "r+") as handle:
        config = json.loads(handle.attrs["config"])
        handle.attrs["config"] = json.dumps(config | {"backend": "blender"})
    done = cli(tmp_path, f"data_dir={blender}", "out_dir=export")
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        f"nbv.export: {blender}: its views keep 50 points each (points_per_view) and were "
        "rendered by blender, so the export cannot write the full views PC-NBV's coverage "
        "needs; make the dataset with points_per_view=0, or with renderer.backend=raycast (the "
        "export re-casts those exactly)"
    )
    assert not (tmp_path / "export").exists()


def test_an_incomplete_set_of_episodes_is_refused_before_writing(run, tmp_path):
    sources, selections = from_eval_run(run, methods=("spread",))
    check_complete(sources, selections)
    gone = (sources[0].keys[1], 24, "permuted", 0)
    dropped = [s for s in selections if (s.key, s.start, s.viewspace, s.repeat) != gone]
    assert len(dropped) == len(selections) - 1
    with pytest.raises(ExportError) as err:
        export(tmp_path / "export", sources, dropped)
    assert str(err.value) == (
        f"meshes/permuted/spread: no episode of {sources[0].keys[1]} from view 24; PC-NBV's "
        "layout needs every model from every start view (choose methods= or viewspace= that "
        "have them)"
    )
    assert not (tmp_path / "export").exists()


def test_bad_sources_are_refused_by_file_before_anything_is_written(run, tmp_path):
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
        (lambda: from_eval_run(run, methods=("hull_sco",)),
         f"methods: ['hull_sco'] not in {run / 'results.json'}; there: ['random', 'spread', "
         "'oracle']"),
        (lambda: from_eval_run(run, viewspaces=("sideways",)),
         "viewspace: ['sideways'] not in"),
        (lambda: from_dataset(tmp_path / "nowhere"), "no such dataset file or folder"),
    ]  # fmt: skip
    for call, message in cases:
        with pytest.raises(ExportError) as err:
            call()
        assert message in str(err.value)
    with pytest.raises(ValueError, match="eval_run and data_dir: both given; give exactly one"):
        ExportSettings(out_dir=tmp_path, eval_run=run, data_dir=tmp_path)
    with pytest.raises(ValueError, match="limit=0: must be null or an integer >= 1"):
        ExportSettings(out_dir=tmp_path, eval_run=run, limit=0)


@pytest.mark.parametrize(
    ("args", "line"),
    [
        ([], "nbv.export: eval_run and data_dir: neither given; give exactly one"),
        (["eval_run=nowhere"], "nbv.export: eval_run='nowhere': no such folder"),
        (["colour=red"], "nbv.export: colour: unknown key; allowed: eval_run, data_dir"),
    ],
)
@pytest.mark.slow
def test_a_refused_export_says_why_in_one_line_and_leaves_no_folder(tmp_path, args, line):
    done = cli(tmp_path, *args, "out_dir=export")
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith(line), done.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_an_export_is_not_written_over_another(run, tmp_path):
    data = json.loads((run / "results.json").read_text())["datasets"][0]["path"]
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
