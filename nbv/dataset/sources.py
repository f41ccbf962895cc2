"""Where a dataset's meshes come from: the synthetic categories or a catalogue of real files.

Every source yields :class:`SourceModel` records with a key, a category and a split:

* ``synthetic``: the splits of :mod:`nbv.assets.synthetic`'s catalogue.
* ``shapenet``: models of the 8 training categories go to train / valid / test by a seeded
  shuffle per category (``split_fractions``); the 8 unseen categories are all ``test``.
* ``stanford``, ``linemod``, ``homebrew``, ``folder``: every model is ``test`` (evaluation sets).
* ``ycb``, ``scans``: the real objects that install here (:mod:`nbv.assets.real_objects`), every
  model ``test``; ``root`` defaults to where ``make real-data`` installs them.

The sources, their licences and catalogues are declared once, in
:data:`nbv.assets.mesh_sources.MESH_SOURCES`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nbv.assets.categories import SHAPENET_TRAIN_CATEGORIES
from nbv.assets.mesh_sources import MESH_SOURCES, catalogue
from nbv.assets.meshes import Mesh, load_mesh, normalise, validate_mesh
from nbv.assets.synthetic import SyntheticEntry, build
from nbv.assets.synthetic import catalogue as synthetic_catalogue
from nbv.utils.seeding import named_rng


@dataclass(frozen=True)
class SourceModel:
    """One model to render.

    Attributes:
        key: unique name, used as the HDF5 group name.
        category: category name.
        split: ``train``, ``valid`` or ``test``.
        source: the source it came from (a name of ``MESH_SOURCES``).
        source_path: the mesh file, or ``synthetic`` for generated shapes.
        synthetic: the synthetic catalogue entry, for generated shapes.
    """

    key: str
    category: str
    split: str
    source: str
    source_path: str
    synthetic: SyntheticEntry | None = None


def assign_splits(
    keys: list[str], fractions: dict[str, float], rng: np.random.Generator
) -> dict[str, str]:
    """Split keys into train / valid / test by a seeded shuffle.

    Args:
        keys: model keys of one category.
        fractions: ``{"valid": f, "test": f}``, fractions of the models for each.
        rng: generator of the shuffle.

    Returns:
        key -> split.
    """
    order = [keys[i] for i in rng.permutation(len(keys))]
    n_valid = int(round(fractions.get("valid", 0.0) * len(keys)))
    n_test = int(round(fractions.get("test", 0.0) * len(keys)))
    split = {k: "valid" for k in order[:n_valid]}
    split.update({k: "test" for k in order[n_valid : n_valid + n_test]})
    split.update({k: "train" for k in order[n_valid + n_test :]})
    return split


def list_models(
    source: str,
    root: str | Path | None = None,
    categories: list[str] | None = None,
    counts: dict[str, int] | None = None,
    split_fractions: dict[str, float] | None = None,
    seed: int = 0,
) -> list[SourceModel]:
    """Every model of a source, in a deterministic order.

    Args:
        source: a name of ``MESH_SOURCES``.
        root: folder of the meshes (all sources but ``synthetic``; ``ycb`` and ``scans``
            default to where ``make real-data`` installs them).
        categories: ShapeNet categories (names or synset ids); None = the 16 of the paper.
        counts: synthetic models per split (see :func:`nbv.assets.synthetic.catalogue`).
        split_fractions: real sources' valid/test fractions of each training category.
        seed: seed of the split shuffle.

    Returns:
        The models, sorted by category order then key.
    """
    if source not in MESH_SOURCES:
        raise ValueError(f"source={source!r} is not one of {', '.join(MESH_SOURCES)}")
    declared = MESH_SOURCES[source]
    if declared.catalogue is None:
        return [
            SourceModel(e.key, e.category, e.split, source, "synthetic", e)
            for e in synthetic_catalogue(counts)
        ]
    if root is None and declared.installed is not None:
        root = declared.installed()
    if root is None:
        raise ValueError(f"source={source} needs root=<folder of the meshes>")
    entries = catalogue(source, root, categories if declared.categories else None)
    split = {e.key: "test" for e in entries}
    if declared.splits:
        for name in SHAPENET_TRAIN_CATEGORIES:
            keys = [e.key for e in entries if e.category == name]
            rng = named_rng(seed, name)
            split.update(assign_splits(keys, split_fractions or {}, rng))
    return [SourceModel(e.key, e.category, split[e.key], source, str(e.path)) for e in entries]


def load_normalised(model: SourceModel, seed: int) -> tuple[Mesh, np.ndarray, float]:
    """The model's mesh normalised into the sphere of radius 0.5, with its centre and scale.

    Raises:
        meshes.MeshError: the mesh cannot be read or is unusable (the message names the file).
    """
    if model.synthetic is not None:
        vertices, faces = build(model.synthetic, seed)
        validate_mesh(vertices, faces, model.key)
        mesh = Mesh(vertices, faces, "synthetic")
    else:
        mesh = load_mesh(model.source_path)
    return normalise(mesh)
