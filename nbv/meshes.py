"""Meshes: loading, validation, normalisation, surface sampling and catalogues of real data.

* :func:`load_mesh` reads OBJ, PLY, OFF, STL, GLB and glTF files through trimesh. Scenes are
  flattened into one mesh (node transforms applied), polygons are triangulated, and trimesh's
  "processing" (vertex merging, face removal) is switched off so that the geometry is what the
  file holds. Vertices that no face uses are dropped; they are not part of the surface and would
  otherwise move the bounding box.
* :func:`validate_mesh` refuses, with one :class:`MeshError` naming the file, a mesh without
  faces, with NaN or infinite vertices, with face indices out of range, or whose faces all have
  zero area. Flat meshes (zero volume, non-zero area) are fine.
* :func:`normalise` puts the centre of the bounding box at the origin and the farthest vertex at
  radius 0.5 (ShapeNet's convention): ``normalised = (vertices - center) * scale``. Undo it with
  ``vertices = normalised / scale + center``. Units of the input do not matter (Linemod's PLY
  files are in millimetres, ShapeNet's are unitless, Stanford's vary).
* :func:`sample_surface` draws points uniformly by area on the surface.
* Catalogues list the meshes of a dataset as the user has it on disk, as :class:`MeshEntry`
  records with a unique key that is safe as a file name and HDF5 group name:
  :func:`shapenet_catalogue` (ShapeNetCore v1 and v2), :func:`stanford_catalogue`,
  :func:`bop_catalogue` (:func:`linemod_catalogue`, :func:`homebrew_catalogue`) and
  :func:`folder_catalogue` (any folder of meshes); :func:`catalogue` dispatches on a source name.
  :func:`check_catalogue` loads every entry and reports the bad ones instead of stopping.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from tqdm import tqdm

#: File suffixes :func:`load_mesh` reads (compared in lower case).
MESH_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")

#: Radius of the sphere that holds a normalised mesh (ShapeNet's convention).
NORMALISED_RADIUS = 0.5

#: The 8 ShapeNetCore training categories of PC-NBV: name -> synset id.
SHAPENET_TRAIN_CATEGORIES: dict[str, str] = {
    "airplane": "02691156",
    "cabinet": "02933112",
    "car": "02958343",
    "chair": "03001627",
    "lamp": "03636649",
    "sofa": "04256520",
    "table": "04379243",
    "vessel": "04530566",
}

#: The 8 ShapeNetCore categories PC-NBV tests on without training on them: name -> synset id.
SHAPENET_UNSEEN_CATEGORIES: dict[str, str] = {
    "bus": "02924116",
    "bed": "02818832",
    "bookshelf": "02871439",
    "bench": "02828884",
    "guitar": "03467517",
    "motorbike": "03790512",
    "skateboard": "04225987",
    "pistol": "03948459",
}

#: All 16 named categories: name -> synset id.
SHAPENET_CATEGORIES: dict[str, str] = {**SHAPENET_TRAIN_CATEGORIES, **SHAPENET_UNSEEN_CATEGORIES}

#: Catalogue sources accepted by :func:`catalogue`.
SOURCES = ("shapenet", "stanford", "linemod", "homebrew", "folder")

#: BOP model folders, in order of preference (the first one present is used).
BOP_MODEL_DIRS = ("models", "models_eval", "models_reconst")

# A total area at or below this fraction of the squared bounding-box extent counts as zero:
# collinear triangles leave rounding residue of order 1e-16, not exactly zero.
_ZERO_AREA_RTOL = 1e-12
_SYNSET_RE = re.compile(r"^\d{8}$")
_UNSAFE_KEY_CHARS = re.compile(r"[^A-Za-z0-9_-]+")


class MeshError(ValueError):
    """A mesh that cannot be used; the message names the file (or array) and the reason."""


class CatalogueError(ValueError):
    """A dataset folder that cannot be catalogued; the message names the folder and the reason."""


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh.

    Attributes:
        vertices: (N, 3) float64 positions (read-only).
        faces: (F, 3) int64 vertex indices of the triangles (read-only).
        source_path: the file it was loaded from, or "" for a mesh made in memory.
    """

    vertices: np.ndarray
    faces: np.ndarray
    source_path: str = ""

    def __post_init__(self) -> None:
        vertices = np.array(self.vertices, dtype=np.float64, order="C")
        faces = np.array(self.faces, dtype=np.int64, order="C")
        name = self.source_path or "<in-memory mesh>"
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise MeshError(f"{name}: vertices must have shape (N, 3), got {vertices.shape}")
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise MeshError(f"{name}: faces must have shape (F, 3), got {faces.shape}")
        # Read-only copies: a frozen mesh whose arrays could change in place would not be frozen.
        vertices.flags.writeable = False
        faces.flags.writeable = False
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)

    @property
    def area(self) -> float:
        """Total surface area, in squared input units."""
        return float(face_areas(self.vertices, self.faces).sum())


@dataclass(frozen=True)
class MeshEntry:
    """One mesh of a catalogue.

    Attributes:
        key: unique within its catalogue; only letters, digits, ``_`` and ``-``, so it is safe as a
            file name and an HDF5 group name.
        path: the mesh file.
        category: the category name (``"chair"``, ``"bunny"``, ``"obj_000001"``, ...).
        source: the catalogue it comes from, one of :data:`SOURCES`.
    """

    key: str
    path: Path
    category: str
    source: str


# ---------------------------------------------------------------------------------------------
# Loading and validation


def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of each triangle: (N, 3) float vertices, (F, 3) int faces -> (F,) float64."""
    v = np.asarray(vertices, dtype=np.float64)
    tri = v[np.asarray(faces, dtype=np.int64)]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def validate_mesh(vertices: np.ndarray, faces: np.ndarray, name: str) -> None:
    """Raise :class:`MeshError` unless ``vertices`` and ``faces`` make a usable surface.

    Args:
        vertices: (N, 3) float positions.
        faces: (F, 3) integer vertex indices.
        name: what to call the mesh in the message (its file name, a synthetic shape's name).

    Raises:
        MeshError: wrong shapes, no faces, NaN or infinite vertices, non-integer faces, face
            indices outside ``[0, N)``, or a total area of zero (every face degenerate).
    """
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"{name}: vertices must have shape (N, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise MeshError(f"{name}: faces must have shape (F, 3) triangles, got {f.shape}")
    if len(f) == 0:
        raise MeshError(f"{name}: mesh has no faces ({len(v)} vertices); a surface is needed")
    if not np.issubdtype(v.dtype, np.number) or np.issubdtype(v.dtype, np.complexfloating):
        raise MeshError(f"{name}: vertices must be real numbers, got dtype {v.dtype}")
    if not np.issubdtype(f.dtype, np.integer):
        raise MeshError(f"{name}: faces must be integer vertex indices, got dtype {f.dtype}")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise MeshError(
            f"{name}: {int(bad.sum())} of {len(v)} vertices are NaN or infinite "
            f"(first: vertex {first} = {v[first].tolist()})"
        )
    if f.min() < 0 or f.max() >= len(v):
        raise MeshError(
            f"{name}: face indices must lie in [0, {len(v)}), got [{int(f.min())}, {int(f.max())}]"
        )
    used = v[np.unique(f)].astype(np.float64)
    extent = float(np.ptp(used, axis=0).max())
    area = float(face_areas(v, f).sum())
    if not area > _ZERO_AREA_RTOL * extent**2:
        raise MeshError(
            f"{name}: total surface area is zero ({len(f)} faces, all degenerate); "
            "a mesh needs at least one triangle with non-zero area"
        )


def _drop_unused_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep only the vertices that faces use, in their original order; remap the faces."""
    used = np.unique(faces)
    if len(used) == len(vertices):
        return vertices, faces
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used), dtype=np.int64)
    return vertices[used], remap[faces]


def load_mesh(path: str | os.PathLike) -> Mesh:
    """Read a triangle mesh from an OBJ, PLY, OFF, STL, GLB or glTF file.

    Scenes (several objects, glTF node trees) are concatenated into one mesh with their
    transforms applied; polygons (quads, n-gons) are triangulated. Vertices are not merged, so an
    STL file keeps three vertices a triangle. Vertices no face uses are dropped. Materials and
    textures are not read.

    Args:
        path: the mesh file; its suffix (any case) picks the reader, see :data:`MESH_SUFFIXES`.

    Returns:
        The mesh, in the units of the file, with ``source_path = str(path)``.

    Raises:
        MeshError: naming the file, for an unknown suffix, a missing or unreadable file, or a
            mesh :func:`validate_mesh` refuses.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise MeshError(
            f"{path}: unsupported mesh file type {path.suffix!r}; "
            f"allowed: {', '.join(MESH_SUFFIXES)}"
        )
    if not path.is_file():
        reason = "is a directory, not a file" if path.is_dir() else "no such file"
        raise MeshError(f"{path}: cannot read mesh: {reason}")
    try:
        # process=False: no merging or face removal, the geometry stays as the file has it.
        loaded = trimesh.load_mesh(
            str(path), file_type=suffix[1:], process=False, skip_materials=True
        )
    except Exception as err:  # any reader failure means a bad file, whatever trimesh raises
        detail = f"{type(err).__name__}: {err}" if str(err) else type(err).__name__
        raise MeshError(f"{path}: cannot read mesh ({detail})") from err
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
    validate_mesh(vertices, faces, str(path))
    vertices, faces = _drop_unused_vertices(vertices, faces)
    return Mesh(vertices, faces, str(path))


# ---------------------------------------------------------------------------------------------
# Normalisation and sampling


def normalise(mesh: Mesh) -> tuple[Mesh, np.ndarray, float]:
    """Centre the bounding box at the origin and put the farthest vertex at radius 0.5.

    ``normalised.vertices = (mesh.vertices - center) * scale``; to undo it,
    ``mesh.vertices = normalised.vertices / scale + center`` (also for points sampled on or
    rendered from the normalised mesh).

    Args:
        mesh: any valid mesh, in any units.

    Returns:
        ``(normalised, center, scale)``: the normalised mesh (same faces and source path),
        ``center`` (3,) float64 the bounding-box centre of the input in input units, and
        ``scale`` a float in 1 / input units.

    Raises:
        MeshError: if all vertices coincide (no size to scale).
    """
    v = mesh.vertices
    center = 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = float(np.linalg.norm(v - center, axis=1).max())
    if not radius > 0.0:
        raise MeshError(f"{mesh.source_path or '<in-memory mesh>'}: all vertices coincide")
    scale = NORMALISED_RADIUS / radius
    return Mesh((v - center) * scale, mesh.faces, mesh.source_path), center, scale


def sample_surface(mesh: Mesh, n: int, rng: np.random.Generator) -> np.ndarray:
    """Draw ``n`` points uniformly by area on the surface of ``mesh``.

    Each point picks a triangle with probability proportional to its area, then a uniform point
    in it: with ``u, w`` uniform on [0, 1) and ``s = sqrt(u)``, the barycentric weights
    ``(1 - s, s (1 - w), s w)``.

    Args:
        mesh: the mesh (total area must be positive).
        n: number of points, >= 0.
        rng: the random generator; the same generator state gives the same points.

    Returns:
        (n, 3) float32 points, in the units of the mesh.
    """
    if int(n) != n or n < 0:
        raise ValueError(f"number of points must be a non-negative integer, got {n!r}")
    n = int(n)
    areas = face_areas(mesh.vertices, mesh.faces)
    cdf = np.cumsum(areas)
    total = cdf[-1] if len(cdf) else 0.0
    if not total > 0.0:
        raise MeshError(f"{mesh.source_path or '<in-memory mesh>'}: zero surface area")
    # searchsorted on the cumulative areas: side="right" so zero-area faces are never chosen.
    chosen = np.searchsorted(cdf, rng.random(n) * total, side="right")
    chosen = np.minimum(chosen, len(areas) - 1)
    tri = mesh.vertices[mesh.faces[chosen]]
    u, w = rng.random((2, n))
    s = np.sqrt(u)
    points = (
        (1.0 - s)[:, None] * tri[:, 0]
        + (s * (1.0 - w))[:, None] * tri[:, 1]
        + (s * w)[:, None] * tri[:, 2]
    )
    return points.astype(np.float32)


# ---------------------------------------------------------------------------------------------
# Catalogues


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
    if categories is None:
        found = sorted(p.name for p in root.iterdir() if p.is_dir() and _SYNSET_RE.match(p.name))
        if not found:
            raise CatalogueError(
                f"{root}: no ShapeNet synset folders (8-digit names such as 03001627) found"
            )
        return [(synset, names.get(synset, synset)) for synset in found]
    if isinstance(categories, str):
        categories = [categories]
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
            (``"03001627"``); None takes every synset folder found.

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


def catalogue(
    source: str, root: str | os.PathLike, categories: list[str] | None = None
) -> list[MeshEntry]:
    """The catalogue of ``source`` (one of :data:`SOURCES`) under ``root``.

    ``categories`` is passed to :func:`shapenet_catalogue` and must be None for other sources.

    Raises:
        CatalogueError: unknown source, categories given for a source without them, or whatever
            the source's catalogue raises.
    """
    if source not in SOURCES:
        raise CatalogueError(f"unknown mesh source {source!r}; allowed: {', '.join(SOURCES)}")
    if source == "shapenet":
        return shapenet_catalogue(root, categories)
    if categories is not None:
        raise CatalogueError(
            f"categories={categories!r} given for source {source!r}; only 'shapenet' selects "
            "categories"
        )
    return {
        "stanford": stanford_catalogue,
        "linemod": linemod_catalogue,
        "homebrew": homebrew_catalogue,
        "folder": folder_catalogue,
    }[source](root)


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
