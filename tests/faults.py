"""Fault injection for the tests: corrupted copies of real artefacts, and the toolkit's commands
run in this process on them.

A :class:`Fault` turns a good file into a bad one in place (cut short, emptied, replaced by
another kind of file, a key or dataset taken out, an attribute or value changed, NaN written
into an array, an array of the wrong shape). :func:`run_command` runs a ``python -m`` entry point
as the shell would, in this process (hydra composes afresh every time), and returns its exit
status and what it printed, so that a corpus of many cases costs seconds, not a Python start-up
each.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import runpy
import shutil
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np


@dataclass(frozen=True)
class Fault:
    """One way to spoil a file: ``name`` says how, ``apply(path)`` does it in place."""

    name: str
    apply: Callable[[Path], None]


def _cut(fraction: float) -> Callable[[Path], None]:
    def apply(path: Path) -> None:
        data = path.read_bytes()
        path.write_bytes(data[: int(len(data) * fraction)])

    return apply


def truncations() -> list[Fault]:
    """The file cut short: emptied, at 1 %, 30 %, 70 % and one byte from its end."""
    faults = [Fault(f"cut at {int(f * 100)} %", _cut(f)) for f in (0.0, 0.01, 0.3, 0.7)]
    faults[0] = Fault("zero bytes", _cut(0.0))

    def last(path: Path) -> None:
        data = path.read_bytes()
        path.write_bytes(data[:-1])

    return [*faults, Fault("one byte short", last)]


def replaced_by(kind: str, other: Path) -> Fault:
    """The file's bytes replaced by ``other``'s (an artefact of another ``kind``)."""
    return Fault(f"a {kind} in its place", lambda path: shutil.copyfile(other, path))


def foreign_hdf5() -> Fault:
    """An HDF5 file of another kind in its place: one dataset, no attributes."""

    def apply(path: Path) -> None:
        path.unlink()
        with h5py.File(path, "w") as f:
            f["numbers"] = np.arange(10)

    return Fault("an HDF5 file of another kind in its place", apply)


def garbage() -> Fault:
    """Seeded random bytes, as long as the file."""

    def apply(path: Path) -> None:
        size = max(path.stat().st_size, 64)
        path.write_bytes(np.random.default_rng(0).bytes(size))

    return Fault("random bytes", apply)


# -- HDF5 ------------------------------------------------------------------------------------


def h5_first(path: Path, suffix: str) -> str:
    """The first object of an HDF5 file whose name ends with ``suffix`` (breadth first)."""
    found: list[str] = []
    with h5py.File(path, "r") as f:
        f.visit(lambda name: found.append(name) if name.endswith(suffix) else None)
    if not found:
        raise KeyError(f"{path}: nothing ends with {suffix!r}")
    return min(found, key=lambda name: (name.count("/"), name))


def h5_drop(suffix: str) -> Fault:
    """The first dataset, group or root attribute named ``suffix`` removed."""

    def apply(path: Path) -> None:
        with h5py.File(path, "a") as f:
            if suffix in f.attrs:
                del f.attrs[suffix]
                return
        name = h5_first(path, suffix)
        with h5py.File(path, "a") as f:
            del f[name]

    return Fault(f"{suffix} missing", apply)


def h5_attr(name: str, value) -> Fault:
    """The root attribute ``name`` set to ``value``."""

    def apply(path: Path) -> None:
        with h5py.File(path, "a") as f:
            f.attrs[name] = value

    return Fault(f"{name} = {value!r}", apply)


def h5_poison(suffix: str, value: float = np.nan) -> Fault:
    """``value`` (NaN unless given) written into the first element of a float dataset."""

    def apply(path: Path) -> None:
        name = h5_first(path, suffix)
        with h5py.File(path, "a") as f:
            data = f[name][()]
            data.reshape(-1)[0] = value
            f[name][...] = data

    return Fault(f"{value} in {suffix}", apply)


def h5_reshape(suffix: str) -> Fault:
    """The first dataset named ``suffix`` replaced by one with its last axis one shorter (or a
    1-D array of 3 values for a 1-D one)."""

    def apply(path: Path) -> None:
        name = h5_first(path, suffix)
        with h5py.File(path, "a") as f:
            data = f[name][()]
            del f[name]
            f[name] = data[..., :-1] if data.ndim > 1 else data[:3]

    return Fault(f"{suffix} of the wrong shape", apply)


# -- JSON, CSV and torch files ----------------------------------------------------------------


def json_edit(name: str, change: Callable[[dict], object]) -> Fault:
    """The JSON file read, ``change`` applied (it edits in place or returns a new value), written
    back (NaN allowed, as Python writes it)."""

    def apply(path: Path) -> None:
        data = json.loads(path.read_text())
        changed = change(data)
        path.write_text(json.dumps(data if changed is None else changed))

    return Fault(name, apply)


def text(name: str, content: str) -> Fault:
    """The file's text replaced by ``content``."""
    return Fault(name, lambda path: path.write_text(content))


def torch_edit(name: str, change: Callable[[dict], object]) -> Fault:
    """A torch payload read, ``change`` applied to it (in place), saved back."""

    def apply(path: Path) -> None:
        import torch

        payload = torch.load(path, weights_only=True)
        change(payload)
        torch.save(payload, path)

    return Fault(name, apply)


def first_float_tensor(state: dict):
    """The first floating-point tensor of a state dict."""
    return next(v for v in state.values() if v.is_floating_point())


# -- Running a command in this process ---------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    """What a command did: its exit status and what it printed."""

    status: int
    stdout: str
    stderr: str

    @property
    def refusal(self) -> str:
        """The last line of stderr (a refusal's one line)."""
        lines = [line for line in self.stderr.splitlines() if line.strip()]
        return lines[-1] if lines else ""


def run_command(module: str, args: list[str], cwd: Path) -> Outcome:
    """``python -m module *args`` in this process, in ``cwd``: the exit status (0 when it
    returns) and its output. An exception that escapes the command is raised here: a traceback
    is a failure."""
    out, err = io.StringIO(), io.StringIO()
    argv, here = sys.argv, Path.cwd()
    status = 0
    sys.argv = [module, *args]
    os.chdir(cwd)
    try:
        with (
            contextlib.redirect_stdout(out),
            contextlib.redirect_stderr(err),
            warnings.catch_warnings(),
        ):
            # Running a module that an earlier case imported: runpy warns that it is in
            # sys.modules already, which is what running it again in one process means.
            warnings.simplefilter("ignore", RuntimeWarning)
            try:
                runpy.run_module(module, run_name="__main__", alter_sys=True)
            except SystemExit as end:
                status = end.code if isinstance(end.code, int) else 1
    finally:
        sys.argv = argv
        os.chdir(here)
    return Outcome(status, out.getvalue(), err.getvalue())


def tree(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder``: relative name -> bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
