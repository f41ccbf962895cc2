"""Reading the toolkit's own files: one refusal for every way a file can be unusable.

An artefact (a dataset shard, a samples file, a checkpoint, a run folder's JSON and CSV files, a
learned score, an evaluation's results) is read inside :func:`reading`; whatever goes wrong
there (the file is cut short, empty, of another kind, lacks a key, holds the wrong type) becomes
one :class:`ArtefactError` whose message is one line: the file, what is wrong, what was expected.
The commands turn that into their one line on stderr and exit status 2 (:mod:`nbv.config.cli`).
:func:`check_array` adds the checks no parser makes: shapes and finite values.

A write that fails for lack of space is :func:`out_of_space`; :mod:`nbv.utils.atomic` names the
file it was writing.
"""

from __future__ import annotations

import csv
import errno
import json
import os
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

#: The errors of a write that ran out of room: no space, over a quota, over the file-size limit.
NO_SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
_NO_SPACE_TEXT = ("No space left on device", "Disk quota exceeded", "File too large")


class ArtefactError(ValueError):
    """A file the toolkit wrote (or should have) that cannot be used.

    Args:
        path: the file.
        problem: what is wrong with it.
        expected: what a good one holds (optional).
    """

    def __init__(self, path: str | os.PathLike[str], problem: str, expected: str = ""):
        self.path = Path(path)
        text = f"{path}: {problem}" + (f"; expected {expected}" if expected else "")
        super().__init__(" ".join(text.split()))


def _first_line(err: BaseException) -> str:
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    return lines[0] if lines else type(err).__name__


@contextmanager
def reading(path: str | os.PathLike[str], what: str, expected: str = "") -> Iterator[None]:
    """Read ``path`` (a ``what``, e.g. "dataset shard") in the body; any failure becomes one
    :class:`ArtefactError` naming the file.

    A ``ValueError`` whose message already names the file passes unchanged (a reader's own,
    more precise refusal); a full disk is not a bad file and passes too.
    """
    try:
        yield
    except ArtefactError:
        raise
    except Exception as err:  # noqa: BLE001 - every way a read can fail ends in one refusal
        if isinstance(err, ValueError) and str(path) in str(err):
            raise
        if isinstance(err, OSError) and out_of_space(err):
            raise
        problem = f"not a usable {what} ({type(err).__name__}: {_first_line(err)})"
        raise ArtefactError(path, problem, expected) from err


def read_json(
    path: str | os.PathLike[str], what: str, keys: Iterable[str] = (), expected: str = ""
) -> dict[str, Any]:
    """The JSON object in ``path``, refused unless it is one with every key of ``keys``.

    Raises:
        ArtefactError: missing, unreadable, not JSON, not an object, a key absent.
    """
    path = Path(path)
    if not path.is_file():
        raise ArtefactError(path, f"no such {what}", expected)
    with reading(path, what, expected):
        data = json.loads(path.read_text())
    if not isinstance(data, dict):
        raise ArtefactError(path, f"a {what} holds a JSON object, not a {type(data).__name__}")
    missing = [key for key in keys if key not in data]
    if missing:
        raise ArtefactError(path, f"{what} without {missing}", expected)
    return data


def read_csv(
    path: str | os.PathLike[str], what: str, numeric: Sequence[str] = ()
) -> list[dict[str, str]]:
    """The rows of a CSV file with a header; every column of ``numeric`` present and each of its
    values a number.

    Raises:
        ArtefactError: missing, empty, a column absent, a value that is no number.
    """
    path = Path(path)
    if not path.is_file():
        raise ArtefactError(path, f"no such {what}")
    with reading(path, what), open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        rows = list(reader)
        header = reader.fieldnames or []
    missing = [c for c in numeric if c not in header]
    if missing:
        raise ArtefactError(
            path, f"{what} without the columns {missing}", f"a header with {list(numeric)}"
        )
    for i, row in enumerate(rows, start=2):
        for column in numeric:
            try:
                float(row[column])
            except (TypeError, ValueError):
                raise ArtefactError(
                    path, f"line {i}, column {column}: {row[column]!r} is no number"
                ) from None
    return rows


def check_array(
    array: np.ndarray,
    path: str | os.PathLike[str],
    name: str,
    shape: Sequence[int | None] | None = None,
    finite: bool = True,
) -> np.ndarray:
    """``array`` (read from ``name`` in ``path``), refused unless it has ``shape`` (None in an
    axis: any length) and, for floats when ``finite``, only finite values.

    Returns:
        ``array`` itself.
    """
    if shape is not None:
        check_shape(array.shape, path, name, shape)
    if finite and np.issubdtype(array.dtype, np.floating) and not np.isfinite(array).all():
        bad = int(np.size(array) - np.isfinite(array).sum())
        raise ArtefactError(path, f"{name} holds {bad} NaN or infinite values")
    return array


def check_shape(
    found: tuple[int, ...], path: str | os.PathLike[str], name: str, shape: Sequence[int | None]
) -> None:
    """Refuse ``found``, the shape of ``name`` in ``path`` (an array's, or a stored dataset's
    read from the file's metadata), unless it is ``shape`` (None in an axis: any length)."""
    fits = len(found) == len(shape) and all(
        n is None or n == s for n, s in zip(shape, found, strict=True)
    )
    if not fits:
        want = "(" + ", ".join("any" if n is None else str(n) for n in shape) + ")"
        raise ArtefactError(path, f"{name} has shape {found}", f"shape {want}")


def out_of_space(err: BaseException) -> bool:
    """True when ``err`` is a write that ran out of room (:data:`NO_SPACE`), as the system or an
    HDF5 library that keeps only the system's message reports it."""
    if isinstance(err, OSError) and err.errno in NO_SPACE:
        return True
    return isinstance(err, OSError | RuntimeError) and any(t in str(err) for t in _NO_SPACE_TEXT)


def space_error(err: BaseException, path: str | os.PathLike[str]) -> OSError:
    """``err`` (a write that ran out of room) as an ``OSError`` naming ``path``, with the
    system's error number and message."""
    number = getattr(err, "errno", None)
    if number not in NO_SPACE:
        text = str(err)
        number = next((n for n, t in zip(NO_SPACE, _NO_SPACE_TEXT, strict=True) if t in text),
                      errno.ENOSPC)  # fmt: skip
    return OSError(number, os.strerror(number), str(path))
