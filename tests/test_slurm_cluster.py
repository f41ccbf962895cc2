"""Jobs through the real single-node SLURM of tests/slurm/start.sh (fixture ``slurm_cluster``)."""

import json
import os
import re
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slurm

REPO = Path(__file__).resolve().parents[1]
HELLO_APP = REPO / "tests" / "slurm" / "hello_app.py"


def _listeners(port: int) -> list[str]:
    """Local addresses (hex, as in /proc/net/tcp*) of the sockets listening on ``port``."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not Path(table).exists():
            continue
        for line in Path(table).read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            address, port_hex = local.split(":")
            if state == "0A" and int(port_hex, 16) == port:  # 0A = LISTEN
                found.append(address)
    return found


def test_daemons_listen_on_loopback_only(slurm_cluster):
    """slurmctld and slurmd listen on their configured ports at 127.0.0.1 and nowhere else."""
    conf = dict(
        line.split("=", 1)
        for line in slurm_cluster.conf.read_text().splitlines()
        if "=" in line and not line.startswith("#")
    )
    for key in ("SlurmctldPort", "SlurmdPort"):
        assert _listeners(int(conf[key])) == ["0100007F"], key  # 127.0.0.1, little-endian hex


def test_node_matches_machine(slurm_cluster):
    """start.sh gives the one node this machine's usable CPUs and total memory, on loopback."""
    out = slurm_cluster.run("scontrol", "-o", "show", "node").stdout.strip()
    fields = dict(item.split("=", 1) for item in out.split() if "=" in item)
    mem_kib = int(re.search(r"^MemTotal:\s+(\d+) kB", Path("/proc/meminfo").read_text(), re.M)[1])
    assert len(out.splitlines()) == 1
    assert int(fields["CPUTot"]) == len(os.sched_getaffinity(0))
    assert int(fields["RealMemory"]) == mem_kib // 1024
    assert fields["NodeAddr"] == "127.0.0.1"


@pytest.mark.slow
def test_sbatch_array_runs_both_tasks(slurm_cluster, tmp_path):
    """`sbatch --array=0-1 --wait` runs tasks 0 and 1 of one array, each seeing the task count."""
    script = tmp_path / "task.sh"
    script.write_text(
        "#!/bin/bash\n"
        'echo "$SLURM_ARRAY_TASK_ID $SLURM_ARRAY_TASK_COUNT $SLURM_ARRAY_JOB_ID"'
        ' > "$OUT/task_$SLURM_ARRAY_TASK_ID.txt"\n'
    )
    proc = slurm_cluster.run(
        "sbatch",
        "--parsable",
        "--array=0-1",
        "--wait",
        f"--output={tmp_path}/%A_%a.log",
        f"--export=ALL,OUT={tmp_path}",
        script,
        timeout=120,
    )
    array_id = proc.stdout.strip().split(";")[0]
    for task in (0, 1):
        assert (tmp_path / f"task_{task}.txt").read_text() == f"{task} 2 {array_id}\n"
    assert sorted(p.name for p in tmp_path.glob("*.log")) == [
        f"{array_id}_0.log",
        f"{array_id}_1.log",
    ]


@pytest.mark.slow
def test_hydra_multirun_is_one_array(slurm_cluster, tmp_path):
    """A hydra sweep x=0,1 through conf/hydra/launcher/slurm.yaml (shrunk by slurm_test) runs as
    tasks 0 and 1 of one SLURM array, in sweep order, with the launcher's resources."""
    sweep = tmp_path / "multirun"
    slurm_cluster.run(
        sys.executable,
        HELLO_APP,
        "-m",
        "hydra/launcher=slurm_test",
        f"hydra.searchpath=[file://{REPO / 'conf'}]",
        f"hydra.sweep.dir={sweep}",
        "x=0,1",
        cwd=tmp_path,
        timeout=300,
    )
    results = [json.loads((sweep / str(i) / "result.json").read_text()) for i in (0, 1)]
    array_id = results[0]["array_job_id"]
    assert array_id is not None
    assert [r["x"] for r in results] == [0, 1]
    assert [r["array_job_id"] for r in results] == [array_id, array_id]
    assert [r["array_task_id"] for r in results] == ["0", "1"]

    # submitit names each task's folder <array id>_<task> and submits one script for the array.
    folders = sorted(p.name for p in (sweep / ".submitit").iterdir() if p.is_dir())
    assert folders == sorted([array_id, f"{array_id}_0", f"{array_id}_1"])
    for task in (0, 1):
        log = (
            sweep / ".submitit" / f"{array_id}_{task}" / f"{array_id}_{task}_0_log.out"
        ).read_text()
        assert f"job_id={array_id}_{task}," in log
    sbatch_lines = set(
        (sweep / ".submitit" / array_id / f"{array_id}_submission.sh").read_text().split("\n")
    )
    assert {
        "#SBATCH --array=0-1%2",
        "#SBATCH --cpus-per-task=1",
        "#SBATCH --mem=1GB",
        "#SBATCH --time=5",
        "#SBATCH --nodes=1",
        "#SBATCH --ntasks-per-node=1",
    } <= sbatch_lines
