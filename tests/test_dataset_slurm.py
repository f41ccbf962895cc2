"""`python -m nbv.dataset` as 2-shard SLURM array jobs on the real single-node cluster.

Both ways of the README: hydra multirun with the submitit launcher (Blender, tiny images) and the
plain sbatch script (ray casting, and a Blender binary given as BLENDER=). Each shard file must
hold the same arrays as a local run.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from needs import require_binary

from nbv.dataset.generator import generate
from nbv.dataset.generator_settings import GeneratorSettings, Renderer, Synthetic
from nbv.geometry.camera import Intrinsics

pytestmark = [pytest.mark.slurm, pytest.mark.blender]

REPO = Path(__file__).resolve().parents[1]
COMMON = [
    "synthetic.counts={train:1,valid:0,test:0,unseen:0}",  # no spaces: EXTRA splits on them
    "limit=1",
    "camera.width=40",
    "camera.height=30",
    "camera.focal=30",
    "n_gt=1024",
    "points_per_view=32",
    "samples.enabled=false",
    "progress=false",
]


def local_run(out: Path, backend: str, blender: str | None = None) -> None:
    """The same two shards made in this process (``blender``: a binary, None = the bpy wheel)."""
    for shard in range(2):
        generate(
            GeneratorSettings(
                out_dir=out,
                synthetic=Synthetic(counts={"train": 1, "valid": 0, "test": 0, "unseen": 0}),
                limit=1,
                shard=shard,
                num_shards=2,
                intrinsics=Intrinsics.centred(40, 30, 30.0),
                n_gt=1024,
                points_per_view=32,
                renderer=Renderer(backend=backend, blender=blender),
                progress=False,
            )
        )


def assert_same_arrays(a: Path, b: Path) -> None:
    names = sorted(p.name for p in a.glob("shard-*.h5"))
    assert names == ["shard-00000-of-00002.h5", "shard-00001-of-00002.h5"]
    assert names == sorted(p.name for p in b.glob("shard-*.h5"))
    for name in names:
        arrays = []
        for folder in (a, b):
            found: dict[str, np.ndarray] = {}
            with h5py.File(folder / name, "r") as f:
                f.visititems(
                    lambda key, obj, found=found: (
                        found.__setitem__(key, obj[()]) if isinstance(obj, h5py.Dataset) else None
                    )
                )
            arrays.append(found)
        assert sorted(arrays[0]) == sorted(arrays[1])
        assert any(k.endswith("gt_points") for k in arrays[0])
        for key in arrays[0]:
            np.testing.assert_array_equal(arrays[0][key], arrays[1][key], err_msg=f"{name} {key}")


@pytest.mark.slow
def test_hydra_submitit_array_matches_local_run(slurm_cluster, tmp_path):
    out = tmp_path / "slurm"
    slurm_cluster.run(
        sys.executable,
        "-m",
        "nbv.dataset",
        "-m",
        f"hydra.searchpath=[file://{REPO / 'tests' / 'slurm' / 'conf'}]",
        "hydra/launcher=slurm_test",
        f"hydra.sweep.dir={tmp_path / 'sweep'}",
        "num_shards=2",
        "shard=0,1",
        f"out_dir={out}",
        *COMMON,
        cwd=REPO,
        timeout=600,
    )
    submitit = sorted(p.name for p in (tmp_path / "sweep" / ".submitit").iterdir() if p.is_dir())
    array_ids = {name.split("_")[0] for name in submitit}
    assert len(array_ids) == 1, f"expected one SLURM array, got {submitit}"
    local = tmp_path / "local"
    local_run(local, "blender")
    assert_same_arrays(out, local)


def sbatch_array(tmp_path: Path, *overrides: str, **env: str) -> Path:
    """Run scripts/slurm_dataset.sbatch as a 2-task array; returns its OUT_DIR."""
    out = tmp_path / "slurm"
    env = dict(os.environ, OUT_DIR=str(out), PYTHON=sys.executable, EXTRA=" ".join(COMMON), **env)
    subprocess.run(
        [
            "sbatch", "--wait", "--array=0-1", "--cpus-per-task=1", "--mem=1G",
            f"--output={tmp_path}/task-%a.out", str(REPO / "scripts" / "slurm_dataset.sbatch"),
            *overrides,
        ],
        # Submitted from tmp_path: the tasks' hydra folders go there, not into the checkout.
        cwd=tmp_path, env=env, check=True, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    (hydra_dir,) = (tmp_path / "outputs" / "dataset").glob("slurm-*")
    assert sorted(p.name for p in hydra_dir.iterdir()) == ["shard0", "shard1"]
    return out


@pytest.mark.slow
def test_sbatch_script_array_matches_local_run(slurm_cluster, tmp_path):
    out = sbatch_array(tmp_path, "renderer.backend=raycast")
    local = tmp_path / "local"
    local_run(local, "raycast")
    assert_same_arrays(out, local)


@pytest.mark.slow
def test_sbatch_script_with_a_blender_binary(slurm_cluster, tmp_path):
    """``BLENDER=/usr/bin/blender sbatch ...``: each task checks the binary first (its log says
    which Blender), then renders with it; the shards equal a local run with the same binary."""
    binary = require_binary()
    out = sbatch_array(tmp_path, BLENDER=binary)
    for shard in (0, 1):
        log = (tmp_path / f"task-{shard}.out").read_text()
        assert f"renderer.blender={binary}" in log
        assert f"preflight: Blender '{binary}' is Blender " in log, log
    local = tmp_path / "local"
    local_run(local, "blender", blender=binary)
    assert_same_arrays(out, local)
