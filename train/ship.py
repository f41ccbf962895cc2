"""``python -m train.ship <best.pt> <out.pt> --command "<the training command>"``: a training
checkpoint of the viewspace-conditioned network as shipped weights (bfloat16 tensors, the
optimizer state dropped), with the command that made it and the dataset's identity in
``extra["shipped"]``."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import torch

from nbv.models.conditioned import load_conditioned, save_conditioned
from train.loop import dataset_identity

log = logging.getLogger("train.ship")


def ship(src: Path, dst: Path, command: str, dataset: Path) -> dict:
    """Write ``dst`` from ``src``; returns the provenance stored in it."""
    model, extra = load_conditioned(src)
    model = model.to(torch.bfloat16)
    provenance = {"command": command, "dataset": str(dataset),
                  "dataset_identity": dataset_identity(dataset), "source": str(src)}  # fmt: skip
    keep = {k: v for k, v in extra.items() if k not in ("optimizer",)}
    save_conditioned(dst, model, {**keep, "shipped": provenance})
    return provenance


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
