"""The category table: PC-NBV's 8 training and 8 unseen ShapeNetCore categories.

One row per category: its name, its ShapeNetCore synset id, and whether PC-NBV trains on it
(``train``) or only tests on it (``unseen``). The synthetic shapes, the ShapeNet catalogue, the
training folds and the evaluator all read their category names from here.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Category:
    """One ShapeNetCore category: ``name``, ``synset`` (8 digits), ``group`` (train | unseen)."""

    name: str
    synset: str
    group: str


#: The 16 categories, the training ones first, each group in ShapeNet's order of PC-NBV.
TABLE: tuple[Category, ...] = (
    Category("airplane", "02691156", "train"),
    Category("cabinet", "02933112", "train"),
    Category("car", "02958343", "train"),
    Category("chair", "03001627", "train"),
    Category("lamp", "03636649", "train"),
    Category("sofa", "04256520", "train"),
    Category("table", "04379243", "train"),
    Category("vessel", "04530566", "train"),
    Category("bus", "02924116", "unseen"),
    Category("bed", "02818832", "unseen"),
    Category("bookshelf", "02871439", "unseen"),
    Category("bench", "02828884", "unseen"),
    Category("guitar", "03467517", "unseen"),
    Category("motorbike", "03790512", "unseen"),
    Category("skateboard", "04225987", "unseen"),
    Category("pistol", "03948459", "unseen"),
)

#: PC-NBV's 8 training categories, in order (fold k holds out the k-th).
TRAIN_CATEGORIES: tuple[str, ...] = tuple(c.name for c in TABLE if c.group == "train")
#: PC-NBV's 8 unseen test categories.
UNSEEN_CATEGORIES: tuple[str, ...] = tuple(c.name for c in TABLE if c.group == "unseen")
#: All 16 categories: the training ones, then the unseen ones.
CATEGORIES: tuple[str, ...] = TRAIN_CATEGORIES + UNSEEN_CATEGORIES
#: Training categories: name -> ShapeNetCore synset id.
SHAPENET_TRAIN_CATEGORIES: dict[str, str] = {c.name: c.synset for c in TABLE if c.group == "train"}
#: Unseen categories: name -> ShapeNetCore synset id.
SHAPENET_UNSEEN_CATEGORIES: dict[str, str] = {
    c.name: c.synset for c in TABLE if c.group == "unseen"
}
#: All 16 categories: name -> synset id.
SHAPENET_CATEGORIES: dict[str, str] = {**SHAPENET_TRAIN_CATEGORIES, **SHAPENET_UNSEEN_CATEGORIES}
