"""The Blender driver: a stream of meshes rendered by ``blender_scripts/render_depth.py`` in
one subprocess, or in several at once."""

from __future__ import annotations

import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Generator, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nbv.geometry.camera import Intrinsics, opencv_to_blender
from nbv.render.job import DEVICES, RenderError, RenderJob, check_mesh

#: The Blender script, run as a subprocess (it imports bpy, never nbv).
BLENDER_SCRIPT = Path(__file__).resolve().parents[2] / "blender_scripts" / "render_depth.py"
#: Blender versions the script supports: (lowest, first unsupported). 3.4 is Debian 12's package,
#: the oldest tested; 5.0 is the newest bpy wheel for Python 3.11. The script refuses others.
SUPPORTED_VERSIONS = ((3, 4, 0), (5, 1, 0))
#: The same range in words, for messages: "3.4.0 <= version < 5.1.0".
SUPPORTED_TEXT = " <= version < ".join(".".join(map(str, v)) for v in SUPPORTED_VERSIONS)


_STDERR_TAIL_LINES = 20
#: Renderer processes are bound to CPUs where the system allows it (Linux).
_CAN_PIN = hasattr(os, "sched_getaffinity") and hasattr(os, "sched_setaffinity")
#: A RAM-backed folder where Linux has one (see :func:`scratch_folder`).
RAM_FOLDER = Path("/dev/shm")


#: How much lower a Blender process's priority is than this process's. The caller works on each
#: finished mesh while the next renders; at the same priority, two renderer processes on 2
#: cores left the dataset generator's records a minute behind when the last mesh was rendered.
RENDERER_NICE = 10


def _renderer_env(cpus: list[int] | None) -> dict[str, str]:
    """This process's environment, with the priority (and the CPUs) the Blender script sets
    itself."""
    env = {**os.environ, "NBV_BLENDER_NICE": str(RENDERER_NICE)}
    if cpus is not None:
        env["NBV_BLENDER_CPUS"] = ",".join(map(str, cpus))
    return env


def job_spec(intrinsics: Intrinsics, threads: int, device: str) -> dict:
    """The settings of a job file shared by every mesh (the script's docstring lists the keys)."""
    return {
        **intrinsics.as_dict(),
        "threads": int(threads),
        "device": device,
        "blender_versions": [list(v) for v in SUPPORTED_VERSIONS],
    }


#: A scratch folder left by a dead process is removed once nothing in it changed for this long:
#: a process of another PID namespace sharing the folder may look dead and still render.
ORPHAN_AGE_S = 3600.0


def scratch_folder(workdir: Path, image_bytes: int, ram: Path = RAM_FOLDER) -> Path:
    """A new folder for the renderer's per-view EXR: in ``ram`` when it is a writable folder
    with room for 16 images of ``image_bytes``, else in ``workdir``. Its name holds this
    process's id; folders in ``ram`` of processes that died without cleaning up are removed
    first (:func:`remove_orphans`).

    Every view is written and read back once, so a folder on disk pays the kernel's write-back
    of a 4.9 MB file a view: 13 ms a 640 x 480 view on 2 cores, a tenth of the render.
    """
    prefix = f"nbv-exr-{os.getpid()}-"
    try:
        room = os.statvfs(ram)
        if os.access(ram, os.W_OK) and room.f_bavail * room.f_frsize >= 16 * image_bytes:
            remove_orphans(ram)
            return Path(tempfile.mkdtemp(prefix=prefix, dir=ram))
    except OSError:  # no such folder (not Linux), or not writable after all
        pass
    return Path(tempfile.mkdtemp(prefix=prefix, dir=workdir))


def remove_orphans(folder: Path, min_age_s: float = ORPHAN_AGE_S) -> list[Path]:
    """Remove the scratch folders ``nbv-exr-<pid>-*`` in ``folder`` whose process is gone (a
    generator killed outright cannot clean up; in ``/dev/shm`` each holds up to one view's EXR
    of memory) and in which nothing changed for ``min_age_s`` seconds. Folders of live
    processes, of other users and of unknown form are left alone.

    Returns:
        The folders removed.
    """
    now = time.time()
    removed = []
    for path in folder.glob("nbv-exr-*-*"):
        pid = path.name.split("-")[2]
        if not pid.isdigit() or _alive(int(pid)):
            continue
        try:
            newest = max(p.lstat().st_mtime for p in (path, *path.rglob("*")))
            if now - newest < min_age_s:
                continue
            shutil.rmtree(path)
        except OSError:  # another user's, or gone meanwhile
            continue
        removed.append(path)
    return removed


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (another user's included)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def check_options(
    threads: int,
    device: str = "CPU",
    blender: str | None = None,
    processes: int = 1,
    chunk: int = 0,
) -> None:
    """Raise ValueError for a bad renderer option, FileNotFoundError for a missing binary."""
    if not isinstance(threads, int | np.integer) or threads < 0:
        raise ValueError(f"threads must be an integer >= 0 (0 = all cores), got {threads!r}")
    if isinstance(processes, bool) or not isinstance(processes, int | np.integer) or processes < 1:
        raise ValueError(f"processes must be an integer >= 1, got {processes!r}")
    if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 0:
        raise ValueError(f"chunk must be an integer >= 0 (0 = no limit), got {chunk!r}")
    if device not in DEVICES:
        raise ValueError(f"device must be one of {DEVICES}, got {device!r}")
    if blender is not None and shutil.which(blender) is None:
        raise FileNotFoundError(f"Blender executable {blender!r} not found")


def blender_command(blender: str | None, job_file: Path) -> list[str]:
    """The command that renders ``job_file``: with this Python's bpy module, or a binary."""
    if blender is None:
        return [sys.executable, str(BLENDER_SCRIPT), "--job", str(job_file)]
    # --python-exit-code: a Python error in the script must not end as a clean exit.
    return [blender, "-b", "--factory-startup", "--python-exit-code", "1", "-P",
            str(BLENDER_SCRIPT), "--", "--job", str(job_file)]  # fmt: skip


def exit_reason(status: int) -> str:
    """A process's exit status in words ("exit status 1", "killed by signal 9 (SIGKILL)")."""
    if status < 0:
        try:
            return f"killed by signal {-status} ({signal.Signals(-status).name})"
        except ValueError:
            return f"killed by signal {-status}"
    return f"exit status {status}"


def _log_tail(log: Path, offset: int, lines: int = _STDERR_TAIL_LINES) -> str:
    with open(log, "rb") as f:
        f.seek(offset)
        text = f.read().decode("utf-8", errors="replace")
    return "\n".join(text.splitlines()[-lines:])


@dataclass(frozen=True)
class StagedJob:
    """A job's files in the run folder: the script reads ``mesh`` and ``poses``, writes ``out``."""

    key: str
    mesh: Path
    poses: Path
    out: Path

    def entry(self) -> dict:
        return {"key": self.key, "mesh": str(self.mesh), "poses": str(self.poses),
                "out": str(self.out)}  # fmt: skip

    def remove(self) -> None:
        for path in (self.mesh, self.poses, self.out):
            path.unlink(missing_ok=True)


def stage_job(job: RenderJob, index: int, run_dir: Path) -> StagedJob:
    """Check a job and write its mesh and Blender-convention poses into run_dir."""
    if not isinstance(job.key, str) or not job.key.strip() or len(job.key.splitlines()) != 1:
        raise ValueError(f"key must be a non-empty one-line string, got {job.key!r}")
    vertices, faces, poses = (np.asarray(a) for a in (job.vertices, job.faces, job.poses))
    check_mesh(vertices, faces, poses)
    if not (np.all(np.isfinite(vertices)) and np.all(np.isfinite(poses))):
        raise ValueError("vertices and poses must be finite")
    pending = StagedJob(
        job.key, run_dir / f"{index:06d}_mesh.npz", run_dir / f"{index:06d}_poses.npy",
        run_dir / f"{index:06d}_depth.npy",
    )  # fmt: skip
    np.savez(pending.mesh, vertices=vertices.astype(np.float64), faces=faces.astype(np.int64))
    np.save(pending.poses, opencv_to_blender(poses))
    return pending


def render_blender(
    jobs: Iterable[RenderJob],
    intrinsics: Intrinsics,
    workdir: Path,
    blender: str | None = None,
    threads: int = 0,
    device: str = "CPU",
    processes: int = 1,
    chunk: int = 0,
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    """Render meshes with Blender Cycles in one subprocess (or ``processes`` at once), yielding
    each as soon as it is done.

    ``blender_scripts/render_depth.py`` runs in each process and reads its meshes one at a time
    from its stdin: a process is handed the next job (staged into a fresh folder under
    ``workdir``: the mesh as .npz, the poses in Blender's camera convention) as it finishes one,
    so the processes share the work however long each mesh takes, and ``jobs`` is read only as
    fast as they render. If a process dies, the mesh it was rendering gets a
    :class:`RenderError` (exit status and the tail of Blender's output) and a new process renders
    the rest. Blender's output goes to ``blender.log`` in that folder; the folder is removed at
    the end unless something failed, when the log is kept and named in the errors.

    Args:
        jobs: meshes with keys and OpenCV camera-to-world poses; keys must be unique. Read
            lazily (a generator may prepare each mesh when it is asked for it), from the
            processes' threads when ``processes > 1``.
        intrinsics: the camera, shared by every view.
        workdir: folder for temporary files (created if missing).
        blender: path of a Blender executable (:data:`SUPPORTED_VERSIONS`; the script refuses
            others); None runs the script with this Python's ``bpy`` module.
        threads: CPU threads for Cycles in each process; 0 = all cores.
        device: "CPU", "GPU" (fail without one) or "AUTO" (GPU when present).
        processes: Blender processes rendering at once, each bound to its share of the CPUs
            (:func:`cpu_shares`). The depth is the same bit for bit; on 2 cores two processes
            of one thread rendered 17 % faster than one of two threads (65 against 79 ms a
            view, 2026-12-03), as a view's scene update and EXR round trip run on one thread.
        chunk: meshes a process renders before a new one takes over (0 = no limit): bounds
            what a long run leaves in one Blender's memory.

    Yields:
        ``(key, depth)`` with (V, H, W) float32 planar depth, ``inf`` for background, or
        ``(key, RenderError)``: an invalid job as soon as it is read, the others in job order
        with one process, in the order they finish with several.

    Raises:
        ValueError: bad ``threads``/``device``/``processes``/``chunk``; FileNotFoundError:
            ``blender`` not found.
    """
    check_options(threads, device, blender, processes, chunk)
    if not BLENDER_SCRIPT.is_file():
        raise FileNotFoundError(f"{BLENDER_SCRIPT} is missing: nbv must run from a checkout")
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    source = _JobSource(jobs)
    settings = (intrinsics, workdir, blender, threads, device)
    if processes == 1:
        return _render_blender(source, *settings, chunk=chunk)
    pins = cpu_shares(sorted(os.sched_getaffinity(0)), processes) if _CAN_PIN else None
    return _merged([_render_blender(source, *settings, pins[i] if pins else None, chunk)
                    for i in range(processes)])  # fmt: skip


def cpu_shares(cpus: list[int], processes: int) -> list[list[int]]:
    """The CPUs each of ``processes`` renderer processes is bound to: every ``processes``-th of
    ``cpus``, or one CPU each in turn when there are more processes than CPUs."""
    if processes <= len(cpus):
        return [cpus[i::processes] for i in range(processes)]
    return [[cpus[i % len(cpus)]] for i in range(processes)]


class _JobSource:
    """The jobs of one :func:`render_blender` call, handed out one at a time to any number of
    streams (threads), each key once."""

    def __init__(self, jobs: Iterable[RenderJob]) -> None:
        self._jobs = enumerate(jobs)
        self._lock = threading.Lock()
        self._seen: set = set()

    def take(self) -> tuple[int, str, RenderJob | None, str] | None:
        """``(index, key, job, "")`` of the next job, ``(index, key, None, why)`` for one that
        cannot be rendered, or None when there are no more."""
        with self._lock:
            taken = next(self._jobs, None)
            if taken is None:
                return None
            index, job = taken
            key = getattr(job, "key", f"#{index}")
            try:
                if key in self._seen:
                    return index, str(key), None, "duplicate key"
                self._seen.add(key)
            except TypeError as exc:  # an unhashable key; stage_job says what a key must be
                return index, repr(key), None, str(exc)
            return index, key, job, ""


#: Jobs a process holds beyond the one it renders, so that it never waits for the next.
_AHEAD = 1


def _merged(streams: list[Iterator]) -> Iterator:
    """The items of ``streams``, each drained by its own thread, in the order they come; an
    exception of a stream is raised here. Leaving early lets each stream finish the item it
    is on, then closes it (which stops its Blender process).

    At most two items a stream wait for the consumer: a stream whose consumer lags (a slow
    record of each depth, a fast GPU render) stops asking for meshes instead of piling up
    depth images (81 MB a model of 66 views) in memory."""
    items: queue.Queue = queue.Queue(maxsize=2 * len(streams))
    stop = threading.Event()

    def put(item: tuple) -> bool:
        """Queue ``item`` once there is room; False when the consumer has left instead."""
        while not stop.is_set():
            try:
                items.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def drain(stream: Iterator) -> None:
        try:
            for item in stream:
                if not put(("item", item)) or stop.is_set():
                    break
        except BaseException as exc:  # handed to the consumer, raised there
            put(("error", exc))
        finally:
            stream.close()
            put(("end", None))

    workers = [threading.Thread(target=drain, args=(s,), daemon=True) for s in streams]
    for worker in workers:
        worker.start()
    try:
        open_streams = len(workers)
        while open_streams:
            kind, value = items.get()
            if kind == "end":
                open_streams -= 1
            elif kind == "error":
                raise value
            else:
                yield value
    finally:
        stop.set()
        for worker in workers:
            worker.join()


class _Process:
    """One Blender process of a stream: the jobs given to it and not reported yet, in order."""

    def __init__(self, command: list[str], log: Path, cpus: list[int] | None) -> None:
        with open(log, "ab") as log_file:
            self.offset = log_file.tell()
            self.popen = subprocess.Popen(
                command,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=log_file,
                env=_renderer_env(cpus),
                text=True,
                errors="replace",
            )
        self.given: list[StagedJob] = []
        self.count = 0

    def give(self, job: StagedJob) -> None:
        """Send a job; a process that has died keeps it (it fails when its output ends)."""
        self.given.append(job)
        self.count += 1
        try:
            assert self.popen.stdin is not None
            self.popen.stdin.write(json.dumps(job.entry()) + "\n")
            self.popen.stdin.flush()
        except (BrokenPipeError, ValueError):  # died, or its stdin already closed
            pass

    def close_input(self) -> None:
        """No more jobs: the process exits once it has rendered those it holds."""
        if self.popen.stdin is not None and not self.popen.stdin.closed:
            try:
                self.popen.stdin.close()
            except BrokenPipeError:
                pass

    def kill(self) -> None:
        if self.popen.poll() is None:
            self.popen.kill()
        self.popen.wait()
        self.close_input()


class _Feed:
    """The jobs of one stream: staged from ``source`` as its processes need them, those a process
    died holding first; ``failed`` once a job of the stream failed (its log is then kept)."""

    def __init__(self, source: _JobSource, run_dir: Path, chunk: int) -> None:
        self.source, self.run_dir, self.chunk = source, run_dir, chunk
        self.retry: list[StagedJob] = []  # given to a process that died before rendering them
        self.exhausted = False
        self.failed = False

    def next_job(self) -> Generator[tuple[str, RenderError], None, StagedJob | None]:
        """Yields the jobs that cannot be rendered; returns the next staged one, or None."""
        if self.retry:
            return self.retry.pop(0)
        while not self.exhausted:
            taken = self.source.take()
            if taken is None:
                self.exhausted = True
                break
            index, key, job, why = taken
            if job is not None:
                try:
                    return stage_job(job, index, self.run_dir)
                except (ValueError, TypeError, AttributeError) as exc:
                    why = str(exc)
            yield key, RenderError(f"{key!r}: {why}")
        return None

    def fill(self, process: _Process) -> Generator[tuple[str, RenderError], None, None]:
        """Give the process jobs up to :data:`_AHEAD` beyond the one it renders; close its input
        when there are no more, or when it has had ``chunk``."""
        chunk = self.chunk
        while len(process.given) <= _AHEAD and not (chunk and process.count >= chunk):
            job = yield from self.next_job()
            if job is None:
                break
            process.give(job)
        if (chunk and process.count >= chunk) or (self.exhausted and not self.retry):
            process.close_input()


def _results(
    process: _Process, log: Path, feed: _Feed
) -> Generator[tuple[str, np.ndarray | RenderError], None, str | None]:
    """The jobs a process renders, as it reports each (its other output goes to ``log``), the
    process fed as it goes; returns the reason Blender could not start, or None."""
    fatal = None
    assert process.popen.stdout is not None
    for line in process.popen.stdout:
        if line.startswith("NBV-FATAL "):
            fatal = line[len("NBV-FATAL ") :].strip()
            continue
        if not line.startswith(("NBV-DONE ", "NBV-FAIL ")) or not process.given:
            with open(log, "a") as log_file:
                log_file.write(line)
            continue
        job = process.given[0]
        tag, rest = line.rstrip("\n").split(" ", 1)
        if rest != job.key and not rest.startswith(job.key + " "):
            raise RenderError(f"Blender reported {rest!r} while {job.key!r} was expected")
        if tag == "NBV-DONE":
            result: np.ndarray | RenderError = np.load(job.out)
        else:
            feed.failed = True
            result = RenderError(f"{job.key!r}: {rest[len(job.key) :].strip()}")
        job.remove()
        process.given.pop(0)
        yield job.key, result
        yield from feed.fill(process)
    return fatal


def _clean_run_dir(run_dir: Path, log: Path, failed: bool) -> None:
    """Remove a stream's folder, or everything in it but the log when a job failed."""
    if not failed:
        shutil.rmtree(run_dir, ignore_errors=True)
        return
    for path in run_dir.iterdir():
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        elif path != log:
            path.unlink()


def _render_blender(
    source: _JobSource,
    intrinsics: Intrinsics,
    workdir: Path,
    blender: str | None,
    threads: int,
    device: str,
    cpus: list[int] | None = None,
    chunk: int = 0,
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    """One stream: Blender processes, one after another, rendering jobs taken from ``source``."""
    run_dir = Path(tempfile.mkdtemp(prefix="blender-", dir=workdir))
    log = run_dir / "blender.log"
    feed = _Feed(source, run_dir, chunk)
    process: _Process | None = None
    scratch: Path | None = None
    try:
        scratch = scratch_folder(run_dir, 16 * intrinsics.width * intrinsics.height)
        spec = job_spec(intrinsics, threads, device) | {"scratch": str(scratch), "jobs": "stdin"}
        job_file = run_dir / "job.json"
        job_file.write_text(json.dumps(spec))
        run = 0
        while True:
            first = yield from feed.next_job()
            if first is None:
                break
            with open(log, "a") as log_file:
                log_file.write(f"=== run {run} ===\n")
            process = _Process(blender_command(blender, job_file), log, cpus)
            process.give(first)
            yield from feed.fill(process)
            fatal = yield from _results(process, log, feed)
            status = process.popen.wait()
            process.close_input()
            left, offset = process.given, process.offset
            process = None
            if not left:
                continue
            feed.failed = True
            if fatal is not None:
                yield from _fail_all(left, feed, f"Blender could not start: {fatal}")
                break
            job = left.pop(0)
            job.remove()
            yield (
                job.key,
                RenderError(
                    f"{job.key!r}: Blender died ({exit_reason(status)}) while rendering it; "
                    f"log {log}, last lines:\n{_log_tail(log, offset)}"
                ),
            )
            feed.retry[:0] = left
            run += 1
    finally:
        if process is not None:
            process.kill()
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)
        _clean_run_dir(run_dir, log, feed.failed)


def _fail_all(given: list[StagedJob], feed: _Feed, why: str) -> Iterator[tuple[str, RenderError]]:
    """Fail every job of a stream whose Blender cannot start: those it was given, then every
    other the stream can take (each process would fail the same way)."""
    for job in given + feed.retry:
        job.remove()
        yield job.key, RenderError(f"{job.key!r}: {why}")
    feed.retry.clear()
    while True:
        job = yield from feed.next_job()
        if job is None:
            return
        job.remove()
        yield job.key, RenderError(f"{job.key!r}: {why}")
