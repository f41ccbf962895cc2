"""What every trainer records beside its weights: the epochs' rows of its CSV files, and the
identity of the dataset it read.

Shared by the trainers (:mod:`train.loop`, :mod:`train.conditioned`, :mod:`train.scorer`) and
the developer tool that ships their weights (``scripts/ship_weights.py``); no trainer imports
another.
"""

from __future__ import annotations

import csv
import hashlib
import json
from pathlib import Path

import nbv.dataset
from nbv.utils.artefacts import read_csv
from nbv.utils.atomic import atomic_path


def dataset_identity(folder: Path) -> str:
    """A short hash (16 hex digits) of a dataset's shard settings and model keys."""
    ds = nbv.dataset.open(folder)
    text = json.dumps([str(ds.attrs.get("config", "")), sorted(ds)], sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def append_csv_rows(path: Path, new: list[dict]) -> None:
    """Append one epoch's rows, each with the same ``epoch`` (replacing the rows of that epoch
    and later ones, as a resumed run writes them again), rewriting the header when new columns
    appear."""
    rows = read_csv(path, "training metrics file", numeric=("epoch",)) if path.exists() else []
    rows = [r for r in rows if int(float(r["epoch"])) < new[0]["epoch"]] + new
    columns = list(dict.fromkeys(k for r in rows for k in r))
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, columns)
        writer.writeheader()
        writer.writerows(rows)
