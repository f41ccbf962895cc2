"""Network weights shipped with the package (bfloat16; ``python scripts/ship_weights.py``
writes them).

``<method>.pt`` is used by the evaluator and the planner when the method's configured checkpoint
does not exist (no local training run; :func:`nbv.scan.shipped.resolve_weights`); its
``extra["shipped"]`` records the command that trained it and the dataset's identity.
"""

from __future__ import annotations

from pathlib import Path

#: The folder of the shipped weights.
FOLDER = Path(__file__).resolve().parent
#: The learned score of ``ig_learned`` (JSON, :mod:`nbv.infogain.gain_scorer`; ``python -m
#: train.scorer`` writes it).
SHIPPED_SCORER = FOLDER / "ig_learned.json"


def shipped_weights(method: str) -> Path | None:
    """The shipped weights of a network method, or None when the package has none."""
    path = FOLDER / f"{method}.pt"
    return path if path.is_file() else None


def is_shipped(path: str | Path) -> bool:
    """``path`` is one of the shipped weight files."""
    return Path(path).resolve().parent == FOLDER
