"""One writer at a time per output, with a lock that a killed process cannot leave stuck.

:func:`one_writer` takes an exclusive ``flock`` on a lock file beside the output (a dataset
shard, a training run folder, an evaluation run, an export). The system releases it when the
holder's process ends, however it ends (a kill -9, a node that reboots its job), so a stale lock
file never blocks a rerun: only a live holder does. A second process that asks for the same
output is refused at once with :class:`OutputBusy`, whose one line names the holder (its pid,
host, start time and command line, which the holder writes into the lock file).

``flock`` locks are per open file, so two processes on one machine and, on Linux, two nodes on
NFS v4 or Lustre exclude each other; on a file system without ``flock`` support the lock is
refused with the system's error.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from pathlib import Path


class OutputBusy(ValueError):
    """Another live process is writing the same output; the message names it."""


def _holder(fd: int) -> str:
    """The holder's record in the lock file, as words (or why it cannot be read)."""
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        info = json.loads(os.read(fd, 1 << 16).decode() or "{}")
    except (OSError, ValueError):
        info = {}
    if not info:
        return "a process that has not written its name yet"
    return (f"pid {info.get('pid')} on {info.get('host')}, since {info.get('since')}: "
            f"{info.get('command')}")  # fmt: skip


def lock_path(output: str | os.PathLike[str]) -> Path:
    """The lock file of an output (a file or a folder): ``.<name>.lock`` beside it, so that it
    never shows among the output's own files."""
    output = Path(output).absolute()
    return output.with_name(f".{output.name}.lock")


@contextlib.contextmanager
def one_writer(output: str | os.PathLike[str], what: str) -> Iterator[Path]:
    """Hold the lock of ``output`` (:func:`lock_path`) for the body; ``what`` names the output in
    a refusal ("dataset shard", "training run folder", ...).

    Yields:
        The lock file (removed when the body ends, with its folder when the lock made it and
        nothing else was put there).

    Raises:
        OutputBusy: a live process holds it.
    """
    path = lock_path(output)
    made = not path.parent.exists()
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise OutputBusy(
                f"{output}: this {what} is being written by another process ({holder}); wait "
                f"for it to end or write elsewhere (its lock: {path})"
            ) from None
        # The previous holder removes the file as it lets go: a lock taken on that removed
        # file guards nothing, so take the one now under the name.
        try:
            current = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            current = False
        if current:
            break
        os.close(fd)
    since = time.strftime("%Y-%m-%d %H:%M:%S")
    record = {"pid": os.getpid(), "host": socket.gethostname(), "since": since,
              "command": " ".join(sys.argv)}  # fmt: skip
    with contextlib.suppress(OSError):  # the name is for the refusal's words: a full disk
        os.ftruncate(fd, 0)  # must not keep the lock from being taken
        os.write(fd, json.dumps(record).encode())
    try:
        yield path
    finally:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        os.close(fd)
        if made:  # a folder made only to hold the lock goes with it (a refused run leaves none)
            with contextlib.suppress(OSError):
                path.parent.rmdir()
