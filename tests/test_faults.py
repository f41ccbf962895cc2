"""The fault-injection suite: every artefact the toolkit reads, spoiled in many ways, through every
command that reads it. Each case must end in one line on stderr naming the file, exit status 2,
no traceback and nothing written.

The artefacts are real small outputs made here (a dataset shard and its samples file, a PCNBV
checkpoint, a training run folder, the learned information-gain score, an evaluation run, a
saved planner); :mod:`faults` spoils copies of them and runs the commands in this process.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from datagen import SMALL_CAMERA, make_tiny_dataset, make_train_dataset, write_meshes
from faults import (
    Fault,
    first_float_tensor,
    foreign_hdf5,
    garbage,
    h5_attr,
    h5_drop,
    h5_poison,
    h5_reshape,
    json_edit,
    replaced_by,
    run_command,
    text,
    torch_edit,
    tree,
    truncations,
)
from tiny_nets import save_tiny_checkpoint

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_SCORER = ROOT / "nbv" / "assets" / "weights" / "ig_learned.json"
SHARD = "shard-00000-of-00001.h5"
SAMPLES = "samples-shard-00000-of-00001.h5"

#: The tiny network's training settings, as command-line overrides.
TRAIN = ["model=tiny", "fold=3", "batch_size=8", "train_points=32", "eval_points=64",
         "start_views=[1,30]", "progress=false"]  # fmt: skip
#: A small evaluation: one method, one viewspace, one start view, no checks.
EVAL = ["viewspace=[original]", "start_views=[1]", "disturb.checks=[]", "plots=false",
        "progress=false", "workers=1"]  # fmt: skip


@pytest.fixture(scope="module")
def real(tmp_path_factory) -> dict[str, Path]:
    """Real small artefacts, made once."""

    from nbv.eval.config import DisturbSettings, EvalSettings, PrepareSettings
    from nbv.eval.evaluate import run as run_eval

    root = tmp_path_factory.mktemp("real")
    made = {
        "tiny": make_tiny_dataset(root / "tiny"),
        "train_data": make_train_dataset(root / "train_data"),
        "checkpoint": save_tiny_checkpoint(root / "pcnbv.pt", "points"),
    }
    trained = run_command(
        "train",
        [f"dataset={made['train_data']}", f"out_dir={root / 'cv' / 'run'}", *TRAIN, "epochs=1"],
        root,
    )
    assert trained.status == 0, trained.stderr
    made["cv"] = root / "cv"
    made["scorer"] = SHIPPED_SCORER
    made["viewspace"] = ROOT / "data" / "viewspaces" / "original_33.txt"
    made["mesh"] = write_meshes(root / "one_mesh", bad=False) / "box.ply"
    made["full_views"] = make_tiny_dataset(root / "full_views", models=1, keep_depth=True)
    completion = [*COMPLETION, "epochs=1", f"data_dir={root / 'cdata'}",
                  f"out_dir={root / 'crun'}"]  # fmt: skip
    trained = run_command("train.completion", completion, root)
    assert trained.status == 0, trained.stderr
    made["completion_data"], made["completion_run"] = root / "cdata", root / "crun"
    made["eval_run"] = run_eval(
        EvalSettings(
            run="run",
            out_root=root / "evals",
            methods=("random", "spread"),
            datasets=("meshes",),
            mesh_dir=write_meshes(root / "meshes", bad=False),
            prepare=PrepareSettings(
                dir=root / "prepared", camera=SMALL_CAMERA, n_gt=1000, points_per_view=50
            ),
            viewspaces=("original",),
            start_views=(1,),
            disturb=DisturbSettings(checks=()),
            plots=False,
            progress=False,
            workers=1,
        )  # fmt: skip
    )
    return made


#: Shipped files of other kinds, put where an artefact belongs.
SHIPPED_CHECKPOINT = ROOT / "nbv" / "assets" / "weights" / "pcnbv.pt"


def shard_faults() -> list[Fault]:
    return [
        *truncations(),
        garbage(),
        replaced_by("checkpoint", SHIPPED_CHECKPOINT),
        foreign_hdf5(),
        h5_drop("viewspaces"),
        h5_drop("schema_version"),
        h5_attr("schema_version", 99),
        h5_drop("gt_points"),
        h5_drop("coverage"),
        h5_drop("offsets"),
        h5_poison("gt_points"),
        h5_poison("poses", np.inf),
        h5_reshape("gt_points"),
        h5_reshape("coverage"),
        h5_reshape("offsets"),
    ]


def samples_faults() -> list[Fault]:
    return [
        *truncations(),
        replaced_by("JSON file", SHIPPED_SCORER),
        foreign_hdf5(),
        h5_drop("target"),
        h5_poison("target"),
        h5_reshape("target"),
        h5_drop("view_state"),
        h5_poison("points", np.inf),
    ]


def _tensor(state: dict):
    return first_float_tensor(state)


def checkpoint_faults() -> list[Fault]:
    def wrong_shape(p: dict) -> None:
        name = next(k for k, v in p["state_dict"].items() if v.is_floating_point())
        p["state_dict"][name] = p["state_dict"][name][:1]

    return [
        *truncations(),
        garbage(),
        foreign_hdf5(),
        replaced_by("JSON file", SHIPPED_SCORER),
        torch_edit("format tag changed", lambda p: p.__setitem__("format", "other")),
        torch_edit("version 99", lambda p: p.__setitem__("version", 99)),
        torch_edit("no weights", lambda p: p.pop("state_dict")),
        torch_edit("a weight missing", lambda p: p["state_dict"].popitem()),
        torch_edit("NaN in a weight", lambda p: _tensor(p["state_dict"]).fill_(float("nan"))),
        torch_edit("a weight of the wrong shape", wrong_shape),
        torch_edit("config with an unknown key", lambda p: p["config"].__setitem__("wings", 2)),
    ]


def json_faults(key: str) -> list[Fault]:
    return [
        *truncations()[:3],
        text("not JSON", "{'a': 1"),
        text("a list, not an object", "[1, 2, 3]"),
        json_edit(f"{key} missing", lambda d: d.pop(key)),
    ]


def scorer_faults() -> list[Fault]:
    def nan(d: dict) -> None:
        d["layers"][0]["weight"][0][0] = float("nan")

    return [
        *json_faults("layers"),
        json_edit("NaN in a weight", nan),
        json_edit("a bias one short", lambda d: d["layers"][0]["bias"].pop()),
        json_edit("format changed", lambda d: d.__setitem__("format", "other")),
    ]


def csv_faults() -> list[Fault]:
    def not_a_number(path: Path) -> None:
        head, *rows = path.read_text().splitlines()
        path.write_text("\n".join([head, "one," + rows[0].split(",", 1)[1], *rows[1:]]) + "\n")

    return [
        text("zero bytes", ""),
        text("another header", "a,b,c\n1,2,3\n"),
        Fault("an epoch that is no number", not_a_number),
    ]


@dataclass(frozen=True)
class Command:
    """A command that reads an artefact: ``source`` names the real artefact copied into the
    working folder (as ``copy``), ``target`` the file spoiled there, ``args`` the command line
    given the working folder and the real artefacts."""

    module: str
    source: str
    copy: str
    target: str
    args: Callable[[Path, dict], list[str]]


def _eval(*extra: str) -> Callable[[Path, dict], list[str]]:
    def args(work: Path, real: dict) -> list[str]:
        data = work / "data" if (work / "data").exists() else real["tiny"]
        return [f"data_dir={data}", "run=r", f"out_root={work / 'evals'}", *EVAL,
                *(e.format(work=work) for e in extra)]  # fmt: skip

    return args


def _train(*extra: str) -> Callable[[Path, dict], list[str]]:
    def args(work: Path, real: dict) -> list[str]:
        data = work / "data" if (work / "data").exists() else real["train_data"]
        out = work / "cv" / "run" if (work / "cv").exists() else work / "run"
        return [f"dataset={data}", f"out_dir={out}", *TRAIN, *extra]

    return args


#: The completion network's tiny training (tests/test_completion.py's sizes).
COMPLETION = ["train_models=1", "valid_models=1", "n_random=1", "shards=1", "points_per_view=32",
              "n_gt=64", "n_input=32", "n_coarse=16", "samples_per_epoch=8", "batch_size=4",
              "val_per_model=1", "progress=false"]  # fmt: skip


def _completion(epochs: int) -> Callable[[Path, dict], list[str]]:
    def args(work: Path, real: dict) -> list[str]:
        data = work / "cdata" if (work / "cdata").exists() else real["completion_data"]
        out = work / "crun" if (work / "crun").exists() else work / "crun_new"
        return [*COMPLETION, f"epochs={epochs}", f"data_dir={data}", f"out_dir={out}"]

    return args


def _ranking(*extra: str) -> Callable[[Path, dict], list[str]]:
    def args(work: Path, real: dict) -> list[str]:
        data = work / "data" if (work / "data").exists() else real["tiny"]
        return [f"data_dir={data}", f"out={work / 'rank'}", "limit=1",
                *(e.format(work=work) for e in extra)]  # fmt: skip

    return args


def _plan(*extra: str) -> Callable[[Path, dict], list[str]]:
    def args(work: Path, real: dict) -> list[str]:
        return [f"mesh={real['mesh']}", "camera=small", f"out_dir={work / 'plan'}",
                *(e.format(work=work) for e in extra)]  # fmt: skip

    return args


def _summary(work: Path, real: dict) -> list[str]:
    return [f"folder={work / 'cv'}"]


def _export(work: Path, real: dict) -> list[str]:
    return [f"eval_run={work / 'run'}", f"out_dir={work / 'export'}", "progress=false"]


COMMANDS = {
    "eval reads a shard": Command("nbv.eval", "tiny", "data", f"data/{SHARD}",
                                  _eval("methods=[random]")),
    "train reads a shard": Command("train", "train_data", "data", f"data/{SHARD}",
                                   _train("epochs=1")),
    "train reads samples": Command("train", "train_data", "data", f"data/{SAMPLES}",
                                   _train("epochs=1")),
    "eval reads a checkpoint": Command("nbv.eval", "checkpoint", "pcnbv.pt", "pcnbv.pt",
                                       _eval("methods=[pcnbv]",
                                             "checkpoints.pcnbv={work}/pcnbv.pt")),
    "train resumes last.pt": Command("train", "cv", "cv", "cv/run/last.pt", _train("epochs=2")),
    "train resumes metrics.csv": Command("train", "cv", "cv", "cv/run/metrics.csv",
                                         _train("epochs=2")),
    "summary reads heldout.json": Command("train.summary", "cv", "cv", "cv/run/heldout.json",
                                          _summary),
    "summary reads settings.json": Command("train.summary", "cv", "cv", "cv/run/settings.json",
                                           _summary),
    "eval reads the learned score": Command("nbv.eval", "scorer", "scorer.json", "scorer.json",
                                            _eval("methods=[ig_learned]",
                                                  "ig_scorer={work}/scorer.json")),
    "export reads results.json": Command("nbv.export", "eval_run", "run", "run/results.json",
                                         _export),
    "export reads a shard": Command("nbv.export", "full_views", "data", f"data/{SHARD}",
                                    lambda w, r: [f"data_dir={w / 'data'}",
                                                  f"out_dir={w / 'export'}", "progress=false"]),
    "ranking reads a shard": Command("nbv.eval.ranking", "tiny", "data", f"data/{SHARD}",
                                     _ranking("methods=[spread]")),
    "ranking reads a checkpoint": Command("nbv.eval.ranking", "checkpoint", "pcnbv.pt",
                                          "pcnbv.pt", _ranking("methods=[pcnbv]",
                                                               "checkpoints.pcnbv={work}/pcnbv.pt")),
    "plan reads a checkpoint": Command("nbv.plan", "checkpoint", "pcnbv.pt", "pcnbv.pt",
                                       _plan("method=pcnbv", "checkpoint={work}/pcnbv.pt")),
    "plan reads a viewspace file": Command("nbv.plan", "viewspace", "views.txt", "views.txt",
                                           _plan("method=spread", "viewspace.kind=file",
                                                 "viewspace.file={work}/views.txt")),
    "completion training reads its data": Command("train.completion", "completion_data", "cdata",
                                                  "cdata/shard-00000-of-00001.h5",
                                                  _completion(1)),
    "completion training resumes last.pt": Command("train.completion", "completion_run", "crun",
                                                   "crun/last.pt", _completion(2)),
}  # fmt: skip

#: What each command is given, spoiled.
CORPUS = {
    "eval reads a shard": shard_faults(),
    "train reads a shard": [f for f in shard_faults() if "coverage" not in f.name],
    "train reads samples": samples_faults(),
    "eval reads a checkpoint": checkpoint_faults(),
    "train resumes last.pt": [*truncations()[:3], foreign_hdf5(),
                              torch_edit("no weights", lambda p: p.pop("state_dict", None))],
    "train resumes metrics.csv": csv_faults(),
    "summary reads heldout.json": json_faults("auc"),
    "summary reads settings.json": json_faults("fold"),
    "eval reads the learned score": scorer_faults(),
    "export reads results.json": [*json_faults("episodes"),
                                  json_edit("an episode without views",
                                            lambda d: d["episodes"][0].pop("views"))],
    "export reads a shard": [f for f in shard_faults() if "coverage" not in f.name],
    "ranking reads a shard": shard_faults(),
    "ranking reads a checkpoint": checkpoint_faults(),
    "plan reads a checkpoint": checkpoint_faults(),
    # A text file cut at a line's end is a valid shorter file: only cuts mid-line are faults.
    "plan reads a viewspace file": [*truncations()[:2], garbage(), text("NaN", "nan 0 1\n0 1 0\n"),
                                    text("two columns", "0 1\n1 0\n"),
                                    text("a view twice", "0 0 1\n0 0 2\n")],
    "completion training reads its data": [*truncations(), foreign_hdf5(),
                                           h5_drop("gt"), h5_reshape("gt"), h5_poison("gt"),
                                           h5_drop("counts")],
    "completion training resumes last.pt": [*truncations()[:3], foreign_hdf5(),
                                            torch_edit("no identity",
                                                       lambda p: p.pop("identity"))],
}  # fmt: skip

CASES = [(name, fault) for name, faults in CORPUS.items() for fault in faults]


def _working_copy(real: dict, command: Command, work: Path) -> Path:
    src = real[command.source]
    dst = work / command.copy
    if src.is_dir():
        shutil.copytree(src, dst)
    else:
        shutil.copyfile(src, dst)
    return work / command.target


def _kept(files: dict[str, bytes]) -> dict[str, bytes]:
    """The files a refused run must leave as they were: all but hydra's record of the last
    command (``.hydra/``), the job log (it gets the refusal's line) and ``run.json`` (where the
    run folder is), which a training run writes before its checks when its run folder is the
    output."""
    hydra = (".log", "run.json")
    return {name: data for name, data in files.items()
            if "/.hydra/" not in f"/{name}" and not name.endswith(hydra)}  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("name", list(COMMANDS))
def test_each_command_runs_on_the_intact_artefact(real, tmp_path, name):
    """The control: the same command on the unspoiled copy runs (so a refusal below is the
    fault's doing)."""
    command = COMMANDS[name]
    _working_copy(real, command, tmp_path)
    outcome = run_command(command.module, command.args(tmp_path, real), tmp_path)
    assert outcome.status == 0, outcome.stderr[-3000:]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "fault"), CASES, ids=[f"{n}: {f.name}" for n, f in CASES])
def test_a_spoiled_artefact_is_refused_in_one_line(real, tmp_path, name, fault):
    command = COMMANDS[name]
    target = _working_copy(real, command, tmp_path)
    fault.apply(target)
    before = tree(tmp_path)
    outcome = run_command(command.module, command.args(tmp_path, real), tmp_path)
    assert "Traceback" not in outcome.stderr, outcome.stderr[-3000:]
    assert outcome.status == 2, (outcome.status, outcome.stderr[-3000:])
    line = outcome.refusal
    assert line.startswith(f"{command.module}: "), outcome.stderr[-3000:]
    assert target.name in line, line
    assert _kept(tree(tmp_path)) == _kept(before), "the refused run wrote or changed files"


# -- A saved planner (the library's Planner.load) ----------------------------------------------


@pytest.fixture(scope="module")
def saved_planner(tmp_path_factory) -> Path:
    """A planner on two table-top views of a cabinet, saved (planner.json and its captures)."""
    from nbv.assets.synthetic.catalogue import make_model
    from nbv.geometry.camera import Intrinsics
    from nbv.render.scene import SceneSettings, table_scene
    from nbv.scan import Planner

    camera = Intrinsics.centred(160, 120, 119.0)
    vertices, faces = make_model("cabinet", np.random.default_rng(1))
    vertices = vertices[:, [0, 2, 1]] * np.array([1.0, -1.0, 1.0])
    views = table_scene(vertices, faces, camera, SceneSettings(views=2), seed=0)
    planner = Planner(method="spread", viewspace={"kind": "hemisphere", "n": 12, "up": "z",
                                                  "radius": 0.45}, n_views=4)  # fmt: skip
    for depth, pose in zip(views.depth, views.poses, strict=True):
        planner.add_view(depth, pose, camera, max_range=1.2)
    return planner.save(tmp_path_factory.mktemp("planner") / "scan")


PLANNER_FAULTS = [
    *truncations()[:3],
    text("not JSON", "{'settings'"),
    text("a list", "[]"),
    json_edit("no settings", lambda d: d.pop("settings")),
    json_edit("no camera", lambda d: d.pop("camera")),
    json_edit("a setting out of range", lambda d: d["settings"].__setitem__("n_views", -3)),
    json_edit("an unknown setting", lambda d: d["settings"].__setitem__("wings", 2)),
]


@pytest.mark.slow
@pytest.mark.parametrize("fault", PLANNER_FAULTS, ids=[f.name for f in PLANNER_FAULTS])
def test_a_spoiled_planner_state_is_refused_naming_it(saved_planner, tmp_path, fault):
    from nbv.scan import Planner
    from nbv.scan.capture import CaptureError

    folder = shutil.copytree(saved_planner, tmp_path / "scan")
    assert Planner.load(folder).captures  # the intact copy loads
    fault.apply(folder / "planner.json")
    with pytest.raises(CaptureError) as refused:
        Planner.load(folder)
    message = str(refused.value)
    assert "planner.json" in message and "\n" not in message
