"""The training sweep as a SLURM job array on the real single-node cluster, then its summary."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from datagen import make_train_dataset

from train.summary import find_runs, summarise

pytestmark = pytest.mark.slurm

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_two_job_sweep_on_slurm_then_summary(slurm_cluster, tmp_path):
    data = make_train_dataset(tmp_path / "data")
    sweep = tmp_path / "sweep"
    slurm_cluster.run(
        sys.executable, "-m", "train", "-m",
        f"hydra.searchpath=[file://{REPO / 'tests' / 'slurm' / 'conf'}]",
        "hydra/launcher=slurm_test", f"hydra.sweep.dir={sweep}",
        f"dataset={data}", "model=tiny", "fold=1,6", "epochs=1", "batch_size=8",
        "train_points=32", "eval_points=64", "start_views=[1,30]", "progress=false",
        f"out_dir={tmp_path}/runs/${{model.name}}_${{score.name}}_fold${{fold}}",
        cwd=REPO, timeout=900,
    )  # fmt: skip
    jobs = sorted(p.name for p in (sweep / ".submitit").iterdir() if p.is_dir())
    assert len({name.split("_")[0] for name in jobs}) == 1, f"not one SLURM array: {jobs}"
    runs = find_runs(sweep)
    assert [r.name for r in runs] == ["tiny_coverage_fold1", "tiny_coverage_fold6"]
    assert all((r / "best.pt").exists() for r in runs)
    groups = summarise(sweep, tmp_path / "summary")
    assert len(groups) == 1 and [r["fold"] for r in groups[0]["runs"]] == [1, 6]
    table = (tmp_path / "summary" / "cv_table.md").read_text()
    assert "fold 1 (cabinet)" in table and "fold 6 (table)" in table and "network - spread" in table
    assert (tmp_path / "summary" / "cv_coverage_by_view.png").stat().st_size > 10_000
