"""Faults that strike a running command: a kill at a seeded point, a second process on the same
output, a disk that fills, and the three cases of issue 54 as a user ran them.

Every command here runs for real, as its own process (``python -m ...``), on small real inputs.
A killed run is run again and must give what an uninterrupted run gives; a second process on an
output a live one holds is refused in one line naming it; a write that fails for space stops the
command in one line and the same command, run again with room, finishes identically.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from datagen import make_train_dataset
from scipy.io import loadmat
from tiny_nets import save_tiny_checkpoint

from nbv.utils.lock import OutputBusy, lock_path, one_writer

ROOT = Path(__file__).resolve().parents[1]
SHARD = "shard-00000-of-00001.h5"
#: Three unseen synthetic models, ray cast with the small camera (tests/datagen.py's).
DATASET = ["synthetic.counts.train=0", "synthetic.counts.valid=0", "synthetic.counts.test=0",
           "synthetic.counts.unseen=1", "limit=3", "camera=small", "n_gt=1000",
           "points_per_view=50", "renderer.backend=raycast",
           "progress=false", "samples.scores=[]"]  # fmt: skip
TRAIN = ["model=tiny", "fold=3", "batch_size=8", "train_points=32", "eval_points=64",
         "start_views=[1,30]", "progress=false", "threads=1"]  # fmt: skip
EVAL = ["methods=[random,spread,hull_sco]", "viewspace=[original,permuted]",
        "start_views=[1,24]", "disturb.checks=[]", "plots=false", "progress=false",
        "workers=1"]  # fmt: skip


def command(module: str, *args: str) -> list[str]:
    return [sys.executable, "-m", module, *args]


def env() -> dict[str, str]:
    out = dict(os.environ, PYTHONPATH=str(ROOT))
    out.pop("HYDRA_FULL_ERROR", None)
    return out


def run(args: list[str], cwd: Path, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=cwd, env=env(), capture_output=True, text=True,
                          timeout=600, **kw)  # fmt: skip


def one_line(done: subprocess.CompletedProcess[str], prog: str) -> str:
    """The refusal: the last line of stderr, which must start with ``prog:``; no traceback."""
    assert "Traceback" not in done.stderr, done.stderr
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith(f"{prog}: "), done.stderr
    return line


# -- The lock ---------------------------------------------------------------------------------


def test_one_writer_refuses_a_second_holder_and_lets_go(tmp_path):
    out = tmp_path / "run"
    with one_writer(out, "training run folder") as lock:
        assert lock == lock_path(out) and lock.exists()
        record = json.loads(lock.read_text())
        assert record["pid"] == os.getpid()
        busy = rf"training run folder is being written by another process \(pid {os.getpid()} on "
        with pytest.raises(OutputBusy, match=busy):
            with one_writer(out, "training run folder"):
                pass
    assert not lock.exists() and not out.exists()  # the folder made for the lock went too
    with one_writer(out, "training run folder"):  # free again
        pass


@pytest.mark.slow
def test_a_killed_holder_leaves_no_stuck_lock(tmp_path):
    out = tmp_path / "shard.h5"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import time; from nbv.utils.lock import one_writer\n"
                f"with one_writer({str(out)!r}, 'dataset shard'):\n"
                "    print('held', flush=True); time.sleep(600)"],
        env=env(), stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OutputBusy, match=f"pid {holder.pid} "):
            with one_writer(out, "dataset shard"):
                pass
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    assert lock_path(out).exists()  # the dead holder could not remove its file...
    with one_writer(out, "dataset shard"):  # ...and it does not matter
        pass


# -- Two processes on one output: exactly one runs ----------------------------------------------


@pytest.mark.slow
def test_two_dataset_processes_on_one_shard_exactly_one_runs(tmp_path):
    """Issue 54's case: two `python -m nbv.dataset` on one out_dir (a requeued SLURM task whose
    first copy still runs). Many models, so that the first still runs when the second starts."""
    many = [a for a in DATASET if not a.startswith(("limit=", "synthetic.counts.unseen"))]
    args = command("nbv.dataset", f"out_dir={tmp_path / 'data'}", *many,
                   "synthetic.counts.unseen=5")  # fmt: skip
    first = subprocess.Popen(args, cwd=tmp_path, env=env(), stderr=subprocess.PIPE, text=True)
    lock = lock_path(tmp_path / "data" / SHARD)
    deadline = time.time() + 120
    while not lock.exists():
        assert first.poll() is None and time.time() < deadline, "the first never took its lock"
        time.sleep(0.02)
    second = run(args, tmp_path)
    assert first.wait(timeout=600) == 0, first.stderr.read()
    assert second.returncode == 2
    line = one_line(second, "nbv.dataset")
    assert f"pid {first.pid} " in line and "being written by another process" in line
    with h5py.File(tmp_path / "data" / SHARD) as f:
        assert len(f["models"]) == 40


@pytest.mark.slow
@pytest.mark.parametrize("which", ["train", "nbv.eval", "nbv.export"])
def test_a_second_process_on_a_held_output_is_refused(which, tmp_path, train_data, eval_run):
    """Each writer refuses an output that a live process holds (this test's process, holding the
    lock as a first copy would), in one line naming it, and writes nothing there."""
    out = tmp_path / "out"
    args = {
        "train": command("train", f"dataset={train_data}", f"out_dir={out}", *TRAIN,
                         "epochs=1"),
        "nbv.eval": command("nbv.eval", f"data_dir={eval_run['data']}", "run=out",
                            f"out_root={tmp_path}", *EVAL),
        "nbv.export": command("nbv.export", f"eval_run={eval_run['run']}", f"out_dir={out}",
                              "progress=false"),
    }[which]  # fmt: skip
    with one_writer(out, "output"):
        done = run(args, tmp_path)
    assert done.returncode == 2, done.stderr
    assert f"pid {os.getpid()} " in one_line(done, which)
    written = [p for p in out.rglob("*") if p.is_file()] if out.exists() else []
    assert all(".hydra" in p.parts or p.suffix == ".log" or p.name == "run.json"
               for p in written), written  # fmt: skip


# -- Kills at seeded points, then a rerun --------------------------------------------------------


@pytest.fixture(scope="module")
def train_data(tmp_path_factory) -> Path:
    return make_train_dataset(tmp_path_factory.mktemp("train") / "data")


@pytest.fixture(scope="module")
def eval_run(tmp_path_factory) -> dict[str, Path]:
    """A dataset of 3 models with full-resolution views, and a finished evaluation of it."""
    tmp = tmp_path_factory.mktemp("evalrun")
    data = tmp / "data"
    done = run(command("nbv.dataset", f"out_dir={data}", *DATASET, "keep_depth=true"), tmp)
    assert done.returncode == 0, done.stderr
    done = run(command("nbv.eval", f"data_dir={data}", "run=run", f"out_root={tmp}", *EVAL), tmp)
    assert done.returncode == 0, done.stderr
    return {"data": data, "run": tmp / "run"}


def _kill_when(args: list[str], cwd: Path, ready, sig: int, delay: float) -> None:
    """Start ``args``; once ``ready()`` is true wait ``delay`` seconds and send ``sig`` to its
    process group (its workers die with it). The run must still be going when it is killed."""
    proc = subprocess.Popen(args, cwd=cwd, env=env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, start_new_session=True)  # fmt: skip
    deadline = time.time() + 300
    while not ready():
        assert proc.poll() is None, f"ended before the kill point: {proc.stderr.read()[-2000:]}"
        assert time.time() < deadline
        time.sleep(0.01)
    time.sleep(delay)
    assert proc.poll() is None, "ended before the kill"
    os.killpg(proc.pid, sig)
    proc.wait()


def _arrays(path: Path) -> dict[str, np.ndarray]:
    arrays = {}
    with h5py.File(path) as f:
        f.visititems(
            lambda n, o: arrays.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset) else None
        )
    return arrays


def _same_arrays(a_path: Path, b_path: Path) -> None:
    """The two HDF5 files hold the same datasets with the same arrays."""
    a, b = _arrays(a_path), _arrays(b_path)
    assert sorted(a) == sorted(b)
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


SIGNALS = [signal.SIGTERM, signal.SIGKILL]


@pytest.mark.slow
@pytest.mark.parametrize("sig", SIGNALS, ids=["SIGTERM", "SIGKILL"])
def test_dataset_killed_at_a_seeded_point_then_rerun_is_identical(sig, tmp_path):
    rng = np.random.default_rng([54, sig])
    clean, killed = tmp_path / "clean", tmp_path / "killed"
    base = [a for a in DATASET if not a.startswith("limit=")] + ["limit=6"]
    assert run(command("nbv.dataset", f"out_dir={clean}", *base), tmp_path).returncode == 0
    parts = killed / ".parts-shard-00000-of-00001"
    after = int(rng.integers(1, 4))  # the kill comes after this many finished models
    args = command("nbv.dataset", f"out_dir={killed}", *base)
    _kill_when(args, tmp_path, lambda: len(list(parts.glob("*.h5"))) >= after, sig,
               float(rng.uniform(0, 0.2)))  # fmt: skip
    assert not (killed / SHARD).exists()
    again = run(args, tmp_path)
    assert again.returncode == 0, again.stderr
    _same_arrays(killed / SHARD, clean / SHARD)


def _metrics(run_dir: Path) -> list[dict]:
    """metrics.csv without its timing columns."""
    import csv

    with open(run_dir / "metrics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return [{k: v for k, v in r.items() if k not in ("samples_per_s", "load_fraction")}
            for r in rows]  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("sig", SIGNALS, ids=["SIGTERM", "SIGKILL"])
def test_training_killed_at_a_seeded_point_then_rerun_is_identical(sig, tmp_path, train_data):
    import torch

    rng = np.random.default_rng([54, 1, sig])
    epochs = ["epochs=4", "eval_every=1"]
    clean, killed = tmp_path / "clean", tmp_path / "killed"
    done = run(command("train", f"dataset={train_data}", f"out_dir={clean}", *TRAIN, *epochs),
               tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    after = int(rng.integers(1, 3))  # killed once this many epochs are recorded
    args = command("train", f"dataset={train_data}", f"out_dir={killed}", *TRAIN, *epochs)

    def epochs_done() -> bool:
        try:
            return len(_metrics(killed)) >= after
        except (FileNotFoundError, KeyError):
            return False

    _kill_when(args, tmp_path, epochs_done, sig, float(rng.uniform(0, 0.3)))
    again = run(args, tmp_path)
    assert again.returncode == 0, again.stderr
    assert _metrics(killed) == _metrics(clean)
    for name in ("last.pt", "best.pt"):
        a = torch.load(killed / name, weights_only=True)["state_dict"]
        b = torch.load(clean / name, weights_only=True)["state_dict"]
        assert a.keys() == b.keys()
        for key in a:
            assert torch.equal(a[key], b[key]), (name, key)


def _episodes(run_dir: Path) -> list[dict]:
    """results.json's episodes without their timings."""
    data = json.loads((run_dir / "results.json").read_text())
    return [{k: v for k, v in e.items() if k not in ("timings", "decision_times")}
            for e in data["episodes"]]  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("sig", SIGNALS, ids=["SIGTERM", "SIGKILL"])
def test_evaluation_killed_at_a_seeded_point_then_rerun_is_identical(sig, tmp_path, eval_run):
    rng = np.random.default_rng([54, 2, sig])
    log = tmp_path / "killed" / "episodes.jsonl"
    after = int(rng.integers(1, 3))  # killed once this many models are logged
    args = command("nbv.eval", f"data_dir={eval_run['data']}", "run=killed",
                   f"out_root={tmp_path}", *EVAL)  # fmt: skip

    def models_done() -> bool:
        return log.exists() and log.read_text().count('"done"') >= after

    _kill_when(args, tmp_path, models_done, sig, float(rng.uniform(0, 0.1)))
    again = run(args, tmp_path)
    assert again.returncode == 0, again.stderr
    assert _episodes(tmp_path / "killed") == _episodes(eval_run["run"])


@pytest.mark.slow
@pytest.mark.parametrize("sig", SIGNALS, ids=["SIGTERM", "SIGKILL"])
def test_export_killed_at_a_seeded_point_then_rerun_is_identical(sig, tmp_path, eval_run):
    rng = np.random.default_rng([54, 3, sig])
    clean, killed = tmp_path / "clean", tmp_path / "killed"
    base = [f"eval_run={eval_run['run']}", "progress=false"]
    assert run(command("nbv.export", f"out_dir={clean}", *base), tmp_path).returncode == 0
    after = int(rng.integers(1, 20))  # killed once this many files are written
    args = command("nbv.export", f"out_dir={killed}", *base)

    def files_written() -> bool:
        return killed.exists() and sum(1 for p in killed.rglob("*") if p.is_file()) >= after

    _kill_when(args, tmp_path, files_written, sig, 0.0)
    again = run(args, tmp_path)
    assert again.returncode == 0, again.stderr
    files = {p.relative_to(clean) for p in clean.rglob("*") if p.is_file() and p.suffix != ".log"}
    assert files == {p.relative_to(killed) for p in killed.rglob("*")
                     if p.is_file() and p.suffix != ".log"}  # fmt: skip
    for name in files:
        if name.suffix == ".mat":  # its header holds the time it was written
            a, b = loadmat(clean / name), loadmat(killed / name)
            keys = {k for k in a if not k.startswith("__")}
            assert keys == {k for k in b if not k.startswith("__")}
            for k in keys:
                np.testing.assert_array_equal(a[k], b[k], err_msg=str(name))
        elif name.name != "manifest.json":
            assert (clean / name).read_bytes() == (killed / name).read_bytes(), name


# -- A full disk -------------------------------------------------------------------------------


def _file_size_limit(limit: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        # Without this the system ends the process at the limit; with it, the write fails with
        # EFBIG, as a full disk's fails with ENOSPC.
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    return apply


@pytest.mark.slow
def test_a_dataset_stopped_by_a_full_disk_continues_identically(tmp_path):
    """A file-size limit stands in for a full disk: each model's part fits, the assembled shard
    does not. One line naming the file and the system's error; the same command run again with
    room finishes, and the shard equals an uninterrupted run's."""
    from nbv.config.cli import NO_SPACE_STATUS

    clean, full = tmp_path / "clean", tmp_path / "full"
    assert run(command("nbv.dataset", f"out_dir={clean}", *DATASET), tmp_path).returncode == 0
    part = max(p.stat().st_size for p in (clean / SHARD,))  # the shard: all three models
    args = command("nbv.dataset", f"out_dir={full}", *DATASET)
    stopped = run(args, tmp_path, preexec_fn=_file_size_limit(part // 2))
    assert stopped.returncode == NO_SPACE_STATUS, stopped.stderr
    line = one_line(stopped, "nbv.dataset")
    assert SHARD in line and "File too large" in line
    assert not (full / SHARD).exists() and not list(full.rglob("*.tmp"))
    assert len(list((full / ".parts-shard-00000-of-00001").glob("*.h5"))) == 3  # kept
    again = run(args, tmp_path)
    assert again.returncode == 0, again.stderr
    _same_arrays(full / SHARD, clean / SHARD)


# -- Issue 54's three cases, as a user ran them --------------------------------------------------


@pytest.mark.slow
def test_the_three_cases_of_issue_54_end_in_one_line(tmp_path, train_data, eval_run):
    # 1. train on a dataset whose samples file was cut short.
    cut = tmp_path / "cut"
    cut.mkdir()
    for f in train_data.iterdir():
        data = f.read_bytes()
        (cut / f.name).write_bytes(data[: len(data) // 3] if f.name.startswith("samples") else data)
    done = run(command("train", f"dataset={cut}", f"out_dir={tmp_path / 'run'}", *TRAIN), tmp_path)
    assert done.returncode == 2
    assert "samples-shard-00000-of-00001.h5" in one_line(done, "train")
    assert not (tmp_path / "run").exists()
    # 2. eval with the only method asked for on a checkpoint cut short.
    ckpt = save_tiny_checkpoint(tmp_path / "pcnbv.pt")
    ckpt.write_bytes(ckpt.read_bytes()[:1000])
    args = command("nbv.eval", f"data_dir={eval_run['data']}", "run=e", f"out_root={tmp_path}",
                   "methods=[pcnbv]", f"checkpoints.pcnbv={ckpt}", *EVAL[1:])  # fmt: skip
    done = run(args, tmp_path)
    assert done.returncode == 2
    assert "pcnbv.pt" in one_line(done, "nbv.eval")
    assert not (tmp_path / "e").exists()
    # 3. two dataset processes on one out_dir: test_two_dataset_processes_on_one_shard_...


@pytest.fixture
def small_disk(tmp_path):
    """A 300 KB tmpfs (a disk that fills), remountable larger; skipped where mounting is not
    allowed (it needs root)."""
    folder = tmp_path / "disk"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(folder)],
                             capture_output=True, text=True)  # fmt: skip
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.strip()}")
    yield folder
    subprocess.run(["umount", str(folder)], check=True)


@pytest.mark.slow
def test_a_dataset_on_a_full_disk_stops_in_one_line_and_continues_identically(tmp_path, small_disk):
    """A real ENOSPC: the tmpfs holds two models' parts, not the third; made larger, the same
    command finishes with the arrays of a run that had room all along."""
    from nbv.config.cli import NO_SPACE_STATUS

    clean = tmp_path / "clean"
    assert run(command("nbv.dataset", f"out_dir={clean}", *DATASET), tmp_path).returncode == 0
    args = command("nbv.dataset", f"out_dir={small_disk / 'data'}", *DATASET)
    stopped = run(args, tmp_path)
    assert stopped.returncode == NO_SPACE_STATUS, stopped.stderr
    line = one_line(stopped, "nbv.dataset")
    assert "No space left on device" in line and str(small_disk) in line
    assert not list(small_disk.rglob("*.tmp"))
    subprocess.run(["mount", "-o", "remount,size=4m", str(small_disk)], check=True)
    again = run(args, tmp_path)
    assert again.returncode == 0, again.stderr
    _same_arrays(small_disk / "data" / SHARD, clean / SHARD)
