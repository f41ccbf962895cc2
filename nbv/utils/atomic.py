"""Crash-safe writes: a file is complete under its name, or absent.

Everything is written to a temporary file in the same folder, flushed to disk, then renamed over
the final name (``os.replace`` is atomic on one file system). A crash or a kill leaves at most a
temporary file, never a half-written result under the final name.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from nbv.utils.artefacts import out_of_space, space_error


def fsync_replace(tmp: str | os.PathLike[str], final: str | os.PathLike[str]) -> None:
    """Flush the finished file ``tmp`` to disk and rename it to ``final`` atomically."""
    with open(tmp, "rb") as handle:
        os.fsync(handle.fileno())
    os.replace(tmp, final)


def temporary_name(path: str | os.PathLike[str]) -> Path:
    """The temporary file of ``path``: ``<name>.tmp`` in the same folder."""
    path = Path(path)
    return path.with_name(path.name + ".tmp")


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path to write ``path`` through; on success it replaces ``path``.

    Missing parent folders are created. When the body raises, the temporary file is removed and
    ``path`` keeps what it held before.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_name(path)
    try:
        yield tmp
        fsync_replace(tmp, path)
    except BaseException as err:
        tmp.unlink(missing_ok=True)
        if out_of_space(err):  # name the file: a library's own error may not
            raise space_error(err, path) from err
        raise


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` whole or not at all."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as handle:
            handle.write(text)


def append_durably(path: str | os.PathLike[str], text: str) -> None:
    """Append ``text`` to ``path`` and flush it to disk before returning (a durable log: a kill
    or a full disk can tear at most the last line, which the log's reader drops)."""
    try:
        with open(path, "a") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
    except OSError as err:
        if out_of_space(err):
            raise space_error(err, path) from err
        raise


def save_figure(figure, path: str | os.PathLike[str], **options) -> None:
    """``figure.savefig`` (a matplotlib figure) to ``path`` whole or not at all; the format is
    the path's suffix. ``options`` go to ``savefig``."""
    path = Path(path)
    with atomic_path(path) as tmp:
        figure.savefig(tmp, format=path.suffix.lstrip(".") or "png", **options)
