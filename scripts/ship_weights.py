"""Turn a training checkpoint into weights the package ships (a developer tool).

    python scripts/ship_weights.py <best.pt> nbv/assets/weights/<method>.pt \
        --command "<the training command>" [--dataset data/generated/research]

A checkpoint of PCNBV, PCNBV-sph, the viewspace-conditioned or the completion network (told
apart by the checkpoint's format) is written as shipped weights: bfloat16 tensors, the optimizer
state dropped, and in ``extra["shipped"]`` the command that made it, the dataset and its identity
(:func:`train.run_log.dataset_identity`) and the source file. Only those who ship weights with the
package need it; users train with ``python -m train`` and evaluate their own ``best.pt``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from nbv.models.checkpoints import (
    CHECKPOINT_FORMAT,
    CheckpointError,
    load_checkpoint,
    save_checkpoint,
)
from nbv.models.completion_inference import COMPLETION_FORMAT, load_completion, save_completion
from nbv.models.view_conditioned import CONDITIONED_FORMAT, load_conditioned, save_conditioned
from train.run_log import dataset_identity

#: Checkpoint format -> its reader and writer.
FORMATS = {
    CHECKPOINT_FORMAT: (load_checkpoint, save_checkpoint),
    CONDITIONED_FORMAT: (load_conditioned, save_conditioned),
    COMPLETION_FORMAT: (load_completion, save_completion),
}


def data_identity(src_format: str | None, dataset: Path) -> str:
    """The identity of what the checkpoint was trained on: a dataset's
    (:func:`train.run_log.dataset_identity`), or for the completion network the hash of its
    data shards' names and settings."""
    if src_format != COMPLETION_FORMAT:
        return dataset_identity(dataset)
    import hashlib

    import h5py

    text = "".join(
        f"{p.name}:{h5py.File(p, 'r').attrs['settings']}" for p in sorted(dataset.glob("*.h5"))
    )
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def checkpoint_format(path: Path) -> str | None:
    """The format tag of a checkpoint file; None when it is not a torch file with one."""
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # unreadable or not torch: the caller names the file
        return None
    return payload.get("format") if isinstance(payload, dict) else None


def ship(src: Path, dst: Path, command: str, dataset: Path) -> dict:
    """Write ``dst`` from ``src``; returns the provenance stored in it.

    Args:
        src: a ``best.pt`` of ``python -m train`` or ``python -m train.conditioned``.
        dst: the shipped file (bfloat16 weights).
        command: the command that trained ``src`` (recorded).
        dataset: the dataset folder it was trained on (its identity is recorded).

    Raises:
        CheckpointError: ``src`` is not a checkpoint of one of the project's networks.
    """
    found = checkpoint_format(src)
    load, save = FORMATS.get(found, (None, None))
    if load is None:
        raise CheckpointError(
            f"{src}: not a checkpoint of PCNBV, the view-conditioned or the completion network "
            "(formats "
            f"{', '.join(FORMATS)})"
        )
    model, extra = load(src)
    model = model.to(torch.bfloat16)
    provenance = {
        "command": command,
        "dataset": str(dataset),
        "dataset_identity": data_identity(found, dataset),
        "source": str(src),
    }
    keep = {k: v for k, v in extra.items() if k not in ("optimizer",)}
    save(dst, model, {**keep, "shipped": provenance})
    return provenance


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="scripts/ship_weights.py", description=__doc__.splitlines()[0]
    )
    parser.add_argument("src", type=Path)
    parser.add_argument("dst", type=Path)
    parser.add_argument("--command", required=True, help="the command that trained src")
    parser.add_argument("--dataset", type=Path, default=Path("data/generated/synthetic"))
    args = parser.parse_args(argv)
    print(ship(args.src, args.dst, args.command, args.dataset))


if __name__ == "__main__":
    main()
