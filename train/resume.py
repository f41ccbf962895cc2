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

import numpy as np

from nbv.dataset.reader import shard_files
from nbv.dataset.samples import samples_path
from nbv.models.checkpoints import CheckpointError, load_checkpoint, save_checkpoint
from nbv.models.precision import resolve_precision
from nbv.utils.artefacts import read_csv
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
        dataset_id: :func:`train.run_log.dataset_identity` of the dataset folder.
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


def resume_state(out_dir: Path, identity: dict, model, optimizer, scheduler) -> tuple[int, float]:
    """Load ``last.pt`` when present; returns (next epoch, best validation AUC).

    Raises:
        TrainConfigError: ``last.pt`` was made with other settings, data or samples.
    """
    last = out_dir / "last.pt"
    if not last.exists():
        return 0, -np.inf
    saved, extra = load_checkpoint(last, n_views=model.config.n_views)
    check_resumable(out_dir, extra.get("run_identity"), identity)
    done = int(extra["epoch"]) + 1
    rows = read_csv(out_dir / "metrics.csv", "training metrics file", numeric=("epoch",))
    missing = sorted(set(range(1, done + 1)) - {int(float(r["epoch"])) for r in rows})
    if missing:
        raise TrainConfigError(
            f"{out_dir / 'metrics.csv'}: no rows for epochs {missing}, which {last} has trained; "
            "the run's record is incomplete. Set a new out_dir=..., or resume=false to start afresh"
        )
    if saved.config != model.config:
        raise CheckpointError(
            f"checkpoint {last} holds another network ({saved.config}); set out_dir=... or "
            "resume=false to start afresh"
        )
    model.load_state_dict(saved.state_dict())
    opt = extra["optimizer"]
    opt["state"] = {int(k): v for k, v in opt["state"].items()}
    optimizer.load_state_dict(opt)
    scheduler.load_state_dict(extra["scheduler"])
    return int(extra["epoch"]) + 1, float(extra.get("best_auc", -np.inf))


def save_last(out_dir: Path, model, optimizer, scheduler, extra: dict) -> None:
    """``last.pt``: the weights, ``extra``, and the optimizer's and scheduler's state to resume."""
    opt = optimizer.state_dict()
    opt["state"] = {str(k): v for k, v in opt["state"].items()}
    save_checkpoint(out_dir / "last.pt", model,
                    {**extra, "optimizer": opt, "scheduler": scheduler.state_dict()})  # fmt: skip


def samples_identity(settings: TrainSettings) -> str:
    """Hash of the samples files of the dataset (one per shard)."""
    folder = Path(settings.dataset)
    files = [folder] if folder.is_file() else [samples_path(f) for f in shard_files(folder)]
    return file_digest([f for f in files if f.exists()])


def checkpoint_extra(settings: TrainSettings, identity: dict, lmax: int, device,
                      selection_keys: list[str]) -> dict:  # fmt: skip
    """What every checkpoint of the run records beside its weights."""
    return {
        "settings": stored_settings(settings),
        "run_identity": identity,
        "dataset_identity": identity["dataset_identity"],
        "input": settings.model.input,
        "lmax": lmax,
        "eval_points": settings.eval_points,
        # Resolved here: "auto" would be resolved again on the evaluating machine, maybe otherwise.
        "precision": resolve_precision(settings.precision, device),
        "held_out": settings.held_out,
        "select": settings.select,
        # The models whose episodes chose this checkpoint: nbv.eval leaves them out.
        "selection_keys": selection_keys if settings.select == "valid" else [],
        # The network, where it is not PCNBV (whose checkpoints never named it).
        **({"network": settings.model.network} if settings.model.network != "pcnbv" else {}),
    }
