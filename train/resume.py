"""Resuming a run only with the settings, dataset and samples it started with.

A run folder's ``last.pt`` records the run's *identity*: every setting that changes its numbers,
a hash of the dataset (its settings and model keys) and a hash of the samples files of its score.
Resuming compares the identity key by key; any difference stops the run with the changed keys
named, since continuing would mix two runs in one set of weights, metrics and optimizer state.
``resume=false`` deletes the run's own files (:data:`RUN_FILES`, nothing else) and starts afresh.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

from train.config import TrainConfigError, TrainSettings, stored_settings

#: Settings that may differ on resumption: they do not change the numbers of the epochs run.
#: (``epochs`` lets a finished run train on; ``random_repeats`` only affects heldout.json,
#: which records it and is recomputed when it differs.)
RESUMABLE = ("epochs", "progress", "threads", "out_dir", "resume", "random_repeats")
#: What a training run writes into its folder; resume=false deletes exactly these.
RUN_FILES = ("last.pt", "best.pt", "metrics.csv", "settings.json", "heldout.json", "tb",
             "val_spearman_by_model.csv", "baselines.json")  # fmt: skip


def file_digest(paths: list[Path]) -> str:
    """SHA-256 (first 16 hex digits) of the files' names and bytes, in the order given."""
    digest = hashlib.sha256()
    for path in paths:
        digest.update(path.name.encode())
        with open(path, "rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()[:16]


def run_identity(settings: TrainSettings, dataset_id: str, samples_id: str) -> dict:
    """The settings that change a run's numbers (JSON types), with the dataset and samples hashes.

    Args:
        settings: the run's settings.
        dataset_id: :func:`train.records.dataset_identity` of the dataset folder.
        samples_id: :func:`file_digest` of the samples files of the run's score.
    """
    out = {k: v for k, v in stored_settings(settings).items() if k not in RESUMABLE}
    out["dataset_identity"] = dataset_id
    out["samples_identity"] = samples_id
    return out


def changed_keys(saved: dict | None, now: dict) -> list[str]:
    """``key (saved -> now)`` for every key whose value differs (sorted by key).

    A checkpoint without an identity (written before identities existed) differs in every key.
    """
    if saved is None:
        return ["run identity (not recorded: the run was made by an older version)"]
    keys = sorted(set(saved) | set(now))
    missing = object()
    return [
        f"{k} ({saved.get(k, '<unset>')!r} -> {now.get(k, '<unset>')!r})"
        for k in keys
        if saved.get(k, missing) != now.get(k, missing)
    ]


def check_resumable(out_dir: Path, saved: dict | None, now: dict) -> None:
    """Stop when the identity of ``last.pt`` (``saved``) differs from this run's (``now``).

    Raises:
        TrainConfigError: the changed keys, and the two ways out.
    """
    changed = changed_keys(saved, now)
    if changed:
        raise TrainConfigError(
            f"{out_dir} holds a run with other settings, data or samples: {'; '.join(changed)}. "
            "Resuming would mix two runs. Set a new out_dir=... for this run, or resume=false to "
            f"delete that run's files ({', '.join(RUN_FILES)}) and start afresh"
        )


def clear_run(out_dir: Path) -> list[str]:
    """Delete the training files of ``out_dir`` (:data:`RUN_FILES`); returns the deleted names.

    Anything else in the folder (hydra's config, the job log, the user's files) stays.
    """
    deleted = []
    for name in RUN_FILES:
        path = out_dir / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
        else:
            continue
        deleted.append(name)
    return deleted
