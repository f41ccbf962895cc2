"""The evaluation's episode log: finished models survive a crash or a kill, a rerun skips them.

``<out_dir>/episodes.jsonl`` is written line by line as the evaluation goes:

* line 1: ``{"identity": "<hash>"}``, a hash of everything that decides the episodes (the
  settings except the run name, progress bar, plots, threads and workers; the bytes of the network
  checkpoints that run; the names, sizes and modification times of the dataset files);
* then, for every finished model, its episode records (``EpisodeRecord.to_json``), one a line,
  followed by ``{"done": [dataset, key]}``.

Only the records of a model followed by its ``done`` line count, so a line torn by a kill is
ignored. A log whose identity differs (other settings, a retrained network, a regenerated
dataset) is renamed to ``episodes.jsonl.stale`` and the evaluation starts over. Episodes are
seeded by their names (:func:`nbv.eval.protocol.episode_rng`), so a resumed evaluation holds the
same views and scores as an uninterrupted one; only the measured times differ.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from nbv.eval.config import EvalSettings
from nbv.eval.protocol import EpisodeRecord
from nbv.utils.atomic import append_durably

LOG_NAME = "episodes.jsonl"
#: Settings that do not change any episode.
# How the episodes are run, not what they are (the batched path gives the same episodes).
_NOT_IDENTITY = ("out_dir", "progress", "plots", "threads", "workers", "batched")


def _plain(value):
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def _file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def identity(settings: EvalSettings, checkpoints: list[Path], data_dirs: list[Path]) -> str:
    """A hash of what decides the episodes.

    Args:
        settings: the evaluation settings (in the layout they are stored in:
            :meth:`~nbv.eval.config.EvalSettings.stored`).
        checkpoints: the network checkpoint files that will run (their bytes are hashed).
        data_dirs: the dataset folders evaluated (file names, sizes and mtimes are hashed).

    Returns:
        64 hex digits.
    """
    values = {k: v for k, v in settings.stored().items() if k not in _NOT_IDENTITY}
    files = []
    for folder in data_dirs:
        for path in sorted(Path(folder).glob("*.h5")):
            stat = path.stat()
            files.append([str(path), stat.st_size, stat.st_mtime_ns])
    text = json.dumps(
        [_plain(values), [_file_digest(Path(p)) for p in checkpoints], files], sort_keys=True
    )
    return hashlib.sha256(text.encode()).hexdigest()


class EpisodeLog:
    """Append-only log of finished models (see the module docstring).

    Attributes:
        path: the log file.
        done: ``(dataset, key) -> records`` of the models a previous run finished.
    """

    def __init__(self, path: Path, ident: str) -> None:
        self.path = Path(path)
        self.done: dict[tuple[str, str], list[EpisodeRecord]] = {}
        if self.path.exists() and not self._read(ident):
            os.replace(self.path, self.path.with_name(self.path.name + ".stale"))
        # Written with the first finished model: a run refused before it leaves no log.
        self._header = None if self.path.exists() else {"identity": ident}

    def _read(self, ident: str) -> bool:
        """Load the finished models and cut the file after the last one (dropping the records
        of an unfinished model and a line torn by a kill); False when the log belongs to other
        settings."""
        pending: list[EpisodeRecord] = []
        good_end = 0
        with open(self.path, "rb") as handle:
            for number, line in enumerate(handle):
                try:
                    entry = json.loads(line)
                except json.JSONDecodeError:
                    break
                if number == 0:
                    if entry != {"identity": ident}:
                        return False
                    good_end = handle.tell()
                elif "done" in entry:
                    self.done[tuple(entry["done"])] = pending
                    pending = []
                    good_end = handle.tell()
                else:
                    pending.append(EpisodeRecord.from_json(entry))
        if good_end == 0:
            return False
        os.truncate(self.path, good_end)
        return True

    def _write_lines(self, entries: list[dict]) -> None:
        if self._header is not None:
            entries = [self._header, *entries]
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._header = None
        text = "".join(json.dumps(_plain(e), allow_nan=True) + "\n" for e in entries)
        append_durably(self.path, text)

    def append(self, dataset: str, key: str, records: list[EpisodeRecord]) -> None:
        """Record a finished model: its episodes, then its ``done`` line, synced to disk."""
        self._write_lines([r.to_json() for r in records] + [{"done": [dataset, key]}])
        self.done[(dataset, key)] = list(records)
