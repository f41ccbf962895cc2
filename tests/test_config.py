"""The configs: every primary config composes with every option of every group into valid
settings (and, for training, a network config); a value of a shared group is written once;
refused configs name the key; a refused run through the real command leaves no folder; the job
log gets the INFO messages."""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

import nbv.bench.config
import nbv.dataset.config
import nbv.eval.config
import nbv.eval.curve
import nbv.eval.ranking
import nbv.export.config
import nbv.plan.config
import nbv.plan.example
import train.conditioned
import train.conditioned_config
import train.config
import train.scorer
import train.summary
from nbv.assets.weights import shipped_weights
from nbv.config.schema import ConfigError, describe
from nbv.dataset.samples import SampleSettings
from nbv.models.config import PCNBVConfig
from nbv.models.view_conditioned import ConditionedConfig

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"
#: Primary config -> the config module of its entry point (importing it registers the schema in
#: hydra's ConfigStore; its ``ENTRY`` builds the settings).
ENTRY_POINTS = {
    "dataset": nbv.dataset.config,
    "train": train.config,
    "eval": nbv.eval.config,
    "ranking": nbv.eval.ranking,
    "curve": nbv.eval.curve,
    "bench": nbv.bench.config,
    "plan": nbv.plan.config,
    "plan_example": nbv.plan.example,
    "export": nbv.export.config,
    "train_conditioned": train.conditioned,
    "train_scorer": train.scorer,
    "train_summary": train.summary,
}


#: Inputs that exist, for the entry points that check theirs while building their settings.
INPUTS = Path(tempfile.mkdtemp(prefix="nbv-test-config-"))
atexit.register(shutil.rmtree, INPUTS, True)
(INPUTS / "tetra.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n")
#: The settings an entry point cannot run without (its input), given to every composition.
REQUIRED = {
    "plan": [f"mesh={INPUTS / 'tetra.obj'}"],
    "plan_example": ["out=example.obj"],
    "export": [f"data_dir={INPUTS}"],
    "curve": [f"runs=[{INPUTS}]"],
    "train_summary": [f"folder={INPUTS}"],
}


def composed(name: str, overrides: list[str] = (), hydra: bool = False):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        overrides = [*REQUIRED.get(name, []), *overrides]
        return compose(name, overrides=overrides, return_hydra_config=hydra)


def build(name: str, cfg) -> list:
    """Every settings object the entry point builds from ``cfg``."""
    module = ENTRY_POINTS[name]
    settings = module.ENTRY.build(cfg)
    if name == "dataset":
        return [settings, settings.sample_settings()]
    if name == "train":
        n_views = train.config.validation_views(settings.dataset)
        return [settings, PCNBVConfig(n_views=n_views, **settings.model.net)]
    return [settings]


def group_options(name: str) -> list[str]:
    """An override for every option in ``conf/<group>/`` of every group the config uses,
    but the one it uses by default (``camera@prepare.camera=small``, ``hydra/launcher=slurm``)."""
    choices = composed(name, hydra=True).hydra.runtime.choices
    out = []
    for key, chosen in choices.items():
        folder = CONF / key.split("@")[0]
        if folder.is_dir():  # hydra's own groups (hydra/env, hydra/sweeper, ...) are not here
            out += [f"{key}={p.stem}" for p in sorted(folder.glob("*.yaml")) if p.stem != chosen]
    return out


CASES = [(name, None) for name in ENTRY_POINTS] + [
    (name, option) for name in ENTRY_POINTS for option in group_options(name)
]


@pytest.mark.parametrize("name, option", CASES, ids=[f"{n}-{o or 'defaults'}" for n, o in CASES])
@pytest.mark.slow
def test_every_config_composes_with_every_group_option(name, option):
    cfg = composed(name, [option] if option else [], hydra=True)
    # The hydra parts the config sets resolve too (run and sweep folders, the launcher).
    parts = ("run", "job", "launcher")  # sweep.subdir needs a job number: a multirun's
    hydra_cfg = {k: OmegaConf.to_container(cfg.hydra[k], resolve=True) for k in parts}
    assert hydra_cfg["job"]["name"] == name and hydra_cfg["run"]["dir"] and cfg.hydra.sweep.dir
    settings, *others = build(name, cfg)
    assert type(settings).__name__ in (
        "Settings", "TrainSettings", "EvalSettings", "BenchSettings", "PlanSettings",
        "ExportSettings", "ConditionedSettings", "ScorerSettings", "SummarySettings",
        "RankingSettings", "CurveSettings", "ExampleSettings",
    )  # fmt: skip
    for other in others:  # the samples (None when disabled), the network config
        assert other is None or isinstance(other, SampleSettings | PCNBVConfig)


@pytest.mark.slow
def test_every_option_of_every_group_folder_is_covered():
    covered = set()
    for name in ENTRY_POINTS:
        choices = composed(name, hydra=True).hydra.runtime.choices
        covered |= {(key.split("@")[0], str(chosen)) for key, chosen in choices.items()}
    covered |= {(o.split("=")[0].split("@")[0], o.split("=")[1]) for _, o in CASES if o}
    on_disk = {(str(p.parent.relative_to(CONF)), p.stem) for p in CONF.rglob("*/*.yaml")}
    assert on_disk <= covered, f"group options no case composes: {sorted(on_disk - covered)}"


def test_training_builds_the_network_config_of_every_model():
    for model in sorted(p.stem for p in (CONF / "model").glob("*.yaml")):
        settings, net = build("train", composed("train", [f"model={model}"]))
        assert isinstance(net, PCNBVConfig) and net.n_views == 33
        assert settings.model.name == model and settings.model.input in ("points", "signature")
    tiny = build("train", composed("train", ["model=tiny"]))[0].model
    assert tiny.net["k"] == 4 and tiny.net["conv_channels"] == [32]
    assert "normalize_input" not in tiny.net  # not set in conf/model/: PCNBVConfig's default


def test_the_schemas_hold_the_fields_of_the_settings_they_feed():
    net_keys = {f for f in train.config.NetConfig.__dataclass_fields__}
    assert net_keys == set(PCNBVConfig.__dataclass_fields__) - {"n_views"}
    samples = set(composed("dataset").samples) - {"enabled"}
    assert samples == set(SampleSettings.__dataclass_fields__) - {"seed"}
    widths = set(train.conditioned_config.NetFields.__dataclass_fields__)
    assert widths == set(ConditionedConfig.__dataclass_fields__) - {"map_features"}


def test_the_conditioned_networks_widths_are_settings():
    assert build("train_conditioned", composed("train_conditioned"))[0].net == ConditionedConfig()
    wide = ["net.point_channels=[128,256]", "net.head_channels=[256,128]"]
    net = build("train_conditioned", composed("train_conditioned", wide))[0].net
    assert net == ConditionedConfig(point_channels=(128, 256), head_channels=(256, 128))


@pytest.mark.slow
def test_shared_groups_write_a_value_once():
    def everything(overrides):
        ds, samples = build("dataset", composed("dataset", overrides))
        tr, _ = build("train", composed("train", overrides))
        ev = build("eval", composed("eval", overrides))[0]
        paths_only = [o for o in overrides if o.startswith("paths.")]  # the bench has no protocol
        bench = build("bench", composed("bench", paths_only))[0]
        return ds, tr, ev, bench

    ds, tr, ev, bench = everything([])
    protocol = composed("eval").protocol
    assert tr.start_views == ev.start_views == tuple(protocol.start_views)
    assert ev.n_views == protocol.n_views == 10
    assert ds.eps == ev.prepare.eps == protocol.eps
    assert ds.n_gt == ev.prepare.n_gt and ds.points_per_view == ev.prepare.points_per_view
    assert ds.intrinsics.width == ev.prepare.camera.width
    assert ds.intrinsics.fx == ev.prepare.camera.fx
    assert ds.out_dir == tr.dataset == ev.data_dir == bench.dataset
    assert tr.out_dir == Path("outputs/train/pcnbv_coverage_fold0")
    # One override of the shared value moves every key that uses it.
    ds, tr, ev, bench = everything(
        ["protocol.eps=0.01", "protocol.start_views=[1,24]", "paths.dataset=/d", "paths.outputs=/o"]
    )
    assert ds.eps == ev.prepare.eps == 0.01
    assert tr.start_views == ev.start_views == (1, 24)
    assert ds.out_dir == tr.dataset == ev.data_dir == bench.dataset == Path("/d")
    assert tr.out_dir == Path("/o/train/pcnbv_coverage_fold0") and ev.out_dir.parent == Path(
        "/o/eval"
    )
    assert ev.checkpoints["pcnbv"] == "/o/train/pcnbv_coverage_fold0/best.pt"
    # The documented keys still win over the group.
    assert build("dataset", composed("dataset", ["eps=0.02"]))[0].eps == 0.02
    assert build("eval", composed("eval", ["start_views=[10]"]))[0].start_views == (10,)


@pytest.mark.parametrize(
    "name, override, message",
    [
        ("dataset", "seed=abc", "seed='abc': must be an integer"),
        ("dataset", "camera.width=1.5", "camera.width=1.5: must be an integer"),
        ("dataset", "eps=far", "eps='far': must be a number"),
        ("dataset", "colour=red", "colour: unknown key; allowed: source, root"),
        ("dataset", "renderer.speed=3", "renderer.speed: unknown key; allowed: backend"),
        ("train", "score=loud", "Could not find 'score/loud'; Available options in 'score': "
                                "coverage, vig"),
        ("train", "model.net.k=many", "model.net.k='many': must be an integer"),
        ("eval", "setcover.dilate=maybe", "setcover.dilate='maybe': must be true or false"),
        ("eval", "start_views=abc", "start_views='abc': must be a list"),
        # The keys renamed by issue 55 name their new key.
        ("eval", "hull.dilate=true", "hull: renamed setcover"),
        ("plan", "ig.resolution=0.01", "ig: renamed infogain"),
        ("bench", "network=sometimes", "network='sometimes': must be true or false"),
        ("train_conditioned", "net.view_channels=wide", "net.view_channels='wide': must be a "
                                                        "list"),
    ],
)  # fmt: skip
def test_hydra_refuses_unknown_keys_and_wrong_types_naming_the_key(name, override, message):
    with pytest.raises(Exception) as err:
        composed(name, [override])
    assert message in describe(err.value)
    assert "invalid literal" not in describe(err.value)


@pytest.mark.parametrize(
    "name, override, message",
    [
        ("dataset", "+colour=red", "colour: unknown key; allowed: source, root"),
        ("dataset", "+samples.colour=red", "samples.colour: unknown key; allowed: enabled"),
        ("dataset", "shard=3", "shard=3: must be in 0..0"),
        ("dataset", "samples.random_step_prob=2", "samples.random_step_prob=2.0"),
        ("dataset", "renderer.noise.dropout_start=95", "renderer.noise.dropout_start=95.0"),
        ("train", "select=best", "select='best': must be one of valid, last"),
        ("eval", "disturb.noise=[0.01,-1]", "disturb.noise=[0.01, -1.0]: must be distinct"),
        ("eval", "random_repeats=0", "random_repeats=0: must be an integer >= 1"),
        ("train", "+model.net.width=3", "model.net.width: unknown key; allowed: k, growth"),
        ("train", "fold=9", "fold=9: must be an integer in 0..7"),
        (
            "eval",
            "setcover.simulation=guess",
            "setcover.simulation='guess': must be one of analytic",
        ),
        ("eval", "+setcover.radius=2", "setcover.radius: unknown key; allowed: n_samp, simulation"),
        ("bench", "checkpoint=/nowhere/best.pt", "checkpoint='/nowhere/best.pt': no such file"),
        ("train_conditioned", "net.head_channels=[0]", "net.head_channels=[0]: must be a non-"),
        ("train_conditioned", "epochs=0", "epochs=0: must be an integer >= 1"),
    ],
)
@pytest.mark.slow
def test_settings_refuse_what_composes_but_cannot_be_used(name, override, message):
    with pytest.raises(ConfigError) as err:
        build(name, composed(name, [override]))
    assert message in str(err.value)


@pytest.mark.slow
def test_a_start_view_outside_the_viewspace_says_how_many_views_it_has(tmp_path):
    for vs in ("original", "permuted"):
        with pytest.raises(ConfigError) as err:
            build("eval", composed("eval", ["start_views=[1,40]", f"viewspace={vs}"]))
        assert (
            str(err.value) == f"start_views=[40]: the viewspace '{vs}' has 33 views (indices 0..32)"
        )
    with pytest.raises(ConfigError, match=r"start_views=\[-1\]: the viewspace 'original'"):
        build("eval", composed("eval", ["start_views=[-1]"]))
    # Training: the dataset's original viewspace when its shards say, else PC-NBV's 33 views.
    with pytest.raises(ConfigError, match=r"start_views=\[33\]: the viewspace 'original' has 33"):
        build("train", composed("train", ["start_views=[33]", f"dataset={tmp_path}"]))
    with h5py.File(tmp_path / "shard-00000-of-00001.h5", "w") as handle:
        handle["viewspaces/original"] = np.zeros((12, 3))
    assert build("train", composed("train", ["start_views=[11]", f"dataset={tmp_path}"]))
    with pytest.raises(ConfigError) as err:
        build("train", composed("train", ["start_views=[1,12]", f"dataset={tmp_path}"]))
    assert (
        str(err.value) == "start_views=[12]: the viewspace 'original' has 12 views (indices 0..11)"
    )


def test_bench_checkpoint_defaults_to_fold_0_when_it_exists_else_the_shipped_one(tmp_path):
    fold0 = tmp_path / "best.pt"
    missing = build("bench", composed("bench", [f"paths.checkpoints.pcnbv={fold0}"]))[0]
    assert missing.checkpoint == shipped_weights("pcnbv") and missing.network and missing.render
    fold0.write_bytes(b"weights")
    found = build("bench", composed("bench", [f"paths.checkpoints.pcnbv={fold0}"]))[0]
    assert found.checkpoint == fold0
    given = build("bench", composed("bench", [f"checkpoint={fold0}", "network=false",
                                              "render=false", "json=rows.json"]))[0]  # fmt: skip
    assert given.checkpoint == fold0 and not given.network and not given.render
    assert given.json == Path("rows.json")


def cli(tmp_path: Path, module: str, *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``python -m <module> args`` in ``tmp_path``: every relative default lands there."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run(
        [sys.executable, "-m", module, *args],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip


@pytest.mark.parametrize(
    "module, args, line",
    [
        # Refused while hydra composes: before hydra makes any folder.
        ("nbv.dataset", ["seed=abc"], "nbv.dataset: seed='abc': must be an integer"),
        ("nbv.eval", ["colour=red"], "nbv.eval: colour: unknown key; allowed: run, out_root"),
        # Refused by the settings: hydra's run folder (and its empty parents) removed again.
        ("nbv.dataset", ["shard=3"], "nbv.dataset: shard=3: must be in 0..0"),
        ("train", ["fold=9"], "train: fold=9: must be an integer in 0..7"),
        ("nbv.eval", ["start_views=[40]"],
         "nbv.eval: start_views=[40]: the viewspace 'original' has 33 views (indices 0..32)"),
        ("nbv.bench", ["checkpoint=nowhere.pt"], "nbv.bench: checkpoint='nowhere.pt': no such"),
        ("nbv.eval.ranking", ["methods=[oracle]"],
         "nbv.eval.ranking: methods ['oracle'] have no per-view scores; allowed: random"),
        ("nbv.eval.curve", ["runs=[nowhere]"],
         "nbv.eval.curve: checkpoint nowhere/best.pt does not exist or is not a file"),
        ("nbv.plan", ["mesh=nowhere.obj"], "nbv.plan: mesh='nowhere.obj': no such file"),
        ("nbv.plan.example", ["out=x.txt"], "nbv.plan.example: out='x.txt': must be a mesh"),
        # Refused by the run itself before it wrote anything (run.json does not count).
        ("train", ["dataset=nowhere"], "train: nowhere: no such dataset file or folder"),
        ("train.summary", ["folder=nowhere"],
         "train.summary: no finished training runs (with heldout.json) under nowhere"),
    ],
)  # fmt: skip
@pytest.mark.slow
def test_a_refused_run_says_why_in_one_line_and_leaves_no_folder(tmp_path, module, args, line):
    done = cli(tmp_path, module, *args)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith(line), done.stderr
    assert not list(tmp_path.iterdir())


@pytest.mark.slow
def test_a_refused_run_keeps_a_run_folder_that_held_something(tmp_path):
    keep = tmp_path / "keep"
    keep.mkdir()
    (keep / "notes.txt").write_text("mine")
    done = cli(tmp_path, "nbv.dataset", "shard=3", f"hydra.run.dir={keep}")
    assert done.returncode == 2
    assert (keep / "notes.txt").read_text() == "mine"
    assert "shard=3: must be in 0..0" in (keep / "dataset.log").read_text()


@pytest.mark.slow
def test_the_job_log_gets_the_info_messages_and_stdout_stays_clean(tmp_path):
    done = cli(
        tmp_path, "nbv.dataset", "camera=small", "renderer.backend=raycast", "limit=1",
        "synthetic.counts={train: 1, valid: 0, test: 0, unseen: 0}", "n_gt=512",
        "points_per_view=32", "samples.enabled=false", "progress=false", "out_dir=data",
        "hydra.run.dir=run",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    log = (tmp_path / "run" / "dataset.log").read_text()
    assert "[nbv.dataset.generator][INFO]" in log and "1/1 models (1 made now" in log
    assert "1/1 models" in done.stderr and done.stdout == ""
    assert (tmp_path / "run" / ".hydra" / "config.yaml").exists()


def test_a_saved_setting_under_a_renamed_key_names_the_new_key():
    from nbv.scan.settings import ScanSettings
    from nbv.utils.fields import ConfigError
    from nbv.utils.settings_values import replaced

    # A planner.json saved before issue 55 holds hull: and ig:.
    for old, new in (("hull", "setcover"), ("ig", "infogain")):
        with pytest.raises(ConfigError, match=f"^{old}: renamed {new}$"):
            replaced(ScanSettings(), {old: {}})
    with pytest.raises(ConfigError, match="colour: unknown key; allowed: "):
        replaced(ScanSettings(), {"colour": "red"})
