"""The synthetic dataset: which models it holds, and how one is built from a seed.

* :func:`make_model` builds one model of a category from a ``numpy.random.Generator``: the
  category's parts, concatenated, centred on the bounding-box centre and scaled to a bounding-box
  diagonal of 1, like ShapeNetCore v2's ``model_normalized.obj``.
* :func:`catalogue` lists the models of the default dataset (:data:`DEFAULT_COUNTS`);
  :func:`build` makes one of them from a seed, independently of every other model
  (:func:`model_rng`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from nbv.assets.categories import CATEGORIES, TRAIN_CATEGORIES
from nbv.assets.synthetic.craft import _airplane, _vessel
from nbv.assets.synthetic.furniture import _bed, _bookshelf, _cabinet, _table
from nbv.assets.synthetic.objects import _guitar, _lamp, _pistol
from nbv.assets.synthetic.primitives import Part
from nbv.assets.synthetic.seating import _bench, _chair, _sofa
from nbv.assets.synthetic.vehicles import _bus, _car, _motorbike, _skateboard
from nbv.utils.seeding import named_rng

#: Models per category of the default dataset: per split for the training categories, and
#: ``unseen`` (all in split "test") for the unseen ones; 8 * 6 + 8 * 2 = 64 models.
DEFAULT_COUNTS: dict[str, int] = {"train": 4, "valid": 1, "test": 1, "unseen": 2}
#: Splits of the catalogue.
SPLITS: tuple[str, ...] = ("train", "valid", "test")


_BUILDERS: dict[str, Callable[[np.random.Generator], list[Part]]] = {
    "airplane": _airplane,
    "cabinet": _cabinet,
    "car": _car,
    "chair": _chair,
    "lamp": _lamp,
    "sofa": _sofa,
    "table": _table,
    "vessel": _vessel,
    "bus": _bus,
    "bed": _bed,
    "bookshelf": _bookshelf,
    "bench": _bench,
    "guitar": _guitar,
    "motorbike": _motorbike,
    "skateboard": _skateboard,
    "pistol": _pistol,
}


def _check_category(category: str) -> None:
    if category not in _BUILDERS:
        raise ValueError(
            f"unknown synthetic category {category!r}; allowed: {', '.join(CATEGORIES)}"
        )


def make_model(category: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One random model of ``category``, drawn with ``rng``.

    Args:
        category: one of :data:`CATEGORIES`.
        rng: the only source of randomness; the same generator state gives the same model.

    Returns:
        ``(vertices, faces)``: (N, 3) float64 in ShapeNet's frame (Y up, front +z), centred on the
        bounding-box centre with a bounding-box diagonal of 1 (unitless); (F, 3) int64 indices.
        Parts are concatenated, not merged: vertices are not shared between parts.
    """
    _check_category(category)
    parts = _BUILDERS[category](rng)
    counts = np.cumsum([0] + [len(p.vertices) for p in parts])
    vertices = np.concatenate([np.asarray(p.vertices, np.float64) for p in parts])
    faces = np.concatenate(
        [np.asarray(p.faces, np.int64) + o for p, o in zip(parts, counts, strict=False)]
    )
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    vertices = (vertices - (lo + hi) / 2) / np.linalg.norm(hi - lo)
    return vertices, faces


@dataclass(frozen=True)
class SyntheticEntry:
    """One model of the synthetic dataset: ``key`` like ``"chair_0003"``, its ``category``,
    ``split`` ("train", "valid" or "test") and ``index`` within the category."""

    key: str
    category: str
    split: str
    index: int


def _check_counts(counts: dict[str, int] | None) -> dict[str, int]:
    merged = dict(DEFAULT_COUNTS)
    for key, value in (counts or {}).items():
        if key not in DEFAULT_COUNTS:
            raise ValueError(
                f"unknown key {key!r} in synthetic counts; allowed: {', '.join(DEFAULT_COUNTS)}"
            )
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
            raise ValueError(f"synthetic counts[{key!r}] = {value!r}; allowed: an integer >= 0")
        merged[key] = int(value)
    return merged


def catalogue(counts: dict[str, int] | None = None) -> list[SyntheticEntry]:
    """The models of the synthetic dataset, in a fixed order (category order, then index).

    Args:
        counts: models per split for each training category (keys "train", "valid", "test") and
            per unseen category ("unseen", all in split "test"); missing keys take
            :data:`DEFAULT_COUNTS`.

    Returns:
        The entries. In a training category, indices ``0 .. test-1`` are the test models, then
        come the valid models, then the train models, so that a larger training set keeps the
        same valid and test models.
    """
    c = _check_counts(counts)
    entries = []
    for category in CATEGORIES:
        if category in TRAIN_CATEGORIES:
            splits = ["test"] * c["test"] + ["valid"] * c["valid"] + ["train"] * c["train"]
        else:
            splits = ["test"] * c["unseen"]
        entries.extend(
            SyntheticEntry(f"{category}_{i:04d}", category, split, i)
            for i, split in enumerate(splits)
        )
    return entries


def model_rng(category: str, index: int, seed: int) -> np.random.Generator:
    """The generator of model ``index`` of ``category`` for dataset ``seed``: it depends on these
    three only, through a stable hash of the name (CRC-32, :func:`nbv.utils.seeding.named_rng`), so
    it is the same in every process."""
    _check_category(category)
    if index < 0 or seed < 0:
        raise ValueError(f"model index {index} and seed {seed} must be >= 0")
    return named_rng(seed, category, index)


def build(entry: SyntheticEntry, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The mesh of ``entry`` for dataset ``seed``: see :func:`make_model` for the arrays.

    The model depends only on (seed, category, index), not on the split or the other models.
    """
    return make_model(entry.category, model_rng(entry.category, entry.index, seed))
