"""``python -m train.ship <best.pt> <out.pt> --command "<the training command>"``: a training
checkpoint (PCNBV, PCNBV-sph or the viewspace-conditioned network, told apart by the
checkpoint's format) as shipped weights (bfloat16 tensors, the optimizer state dropped), with the
command that made it and the dataset's identity in ``extra["shipped"]``."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import torch

from nbv.models.checkpoints import (
    CHECKPOINT_FORMAT,
    CheckpointError,
    load_checkpoint,
    save_checkpoint,
)
from nbv.models.conditioned import CONDITIONED_FORMAT, load_conditioned, save_conditioned
from train.loop import dataset_identity

log = logging.getLogger("train.ship")


def ship(src: Path, dst: Path, command: str, dataset: Path) -> dict:
    """Write ``dst`` from ``src``; returns the provenance stored in it.

    Raises:
        CheckpointError: ``src`` is not a checkpoint of one of the project's networks.
    """
    load, save = _FORMATS.get(checkpoint_format(src), (None, None))
    if load is None:
        raise CheckpointError(
            f"{src}: not a checkpoint of PCNBV or of the view-conditioned network (formats "
            f"{', '.join(_FORMATS)})"
        )
    model, extra = load(src)
    model = model.to(torch.bfloat16)
    provenance = {"command": command, "dataset": str(dataset),
                  "dataset_identity": dataset_identity(dataset), "source": str(src)}  # fmt: skip
    keep = {k: v for k, v in extra.items() if k not in ("optimizer",)}
    save(dst, model, {**keep, "shipped": provenance})
    return provenance


#: Checkpoint format -> its reader and writer.
_FORMATS = {
    CHECKPOINT_FORMAT: (load_checkpoint, save_checkpoint),
    CONDITIONED_FORMAT: (load_conditioned, save_conditioned),
}


def checkpoint_format(path: Path) -> str | None:
    """The format tag of a checkpoint file; None when it is not a torch file with one."""
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # unreadable or not torch: the caller names the file
        return None
    return payload.get("format") if isinstance(payload, dict) else None


def main() -> None:
    parser = argparse.ArgumentParser(prog="train.ship", description=__doc__.split("\n\n")[0])
    parser.add_argument("src", type=Path)
    parser.add_argument("dst", type=Path)
    parser.add_argument("--command", required=True, help="the command that trained src")
    parser.add_argument("--dataset", type=Path, default=Path("data/generated/synthetic"))
    args = parser.parse_args()
    print(ship(args.src, args.dst, args.command, args.dataset))


if __name__ == "__main__":
    main()
