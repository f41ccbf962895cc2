"""Meshes: loading, validation, normalisation, surface sampling and catalogues of real data.

* :func:`load_mesh` reads OBJ, PLY, OFF, STL, GLB and glTF files through trimesh, and PLY files
  with triangle strips (Stanford's scans) through :mod:`nbv.assets.ply`. Scenes are
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
  :func:`check_catalogue` loads every entry and reports the bad ones instead of stopping."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from nbv.assets.ply import has_strips, read_ply_triangles

#: File suffixes :func:`load_mesh` reads (compared in lower case).
MESH_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")


#: Radius of the sphere that holds a normalised mesh (ShapeNet's convention).
NORMALISED_RADIUS = 0.5


# A total area at or below this fraction of the squared bounding-box extent counts as zero:
# collinear triangles leave rounding residue of order 1e-16, not exactly zero.
_ZERO_AREA_RTOL = 1e-12


class MeshError(ValueError):
    """A mesh that cannot be used; the message names the file (or array) and the reason."""


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
    transforms applied; polygons (quads, n-gons) are triangulated; a PLY file's triangle strips
    (``element tristrips``) are decoded (:mod:`nbv.assets.ply`). Vertices are not merged, so an
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
    size = path.stat().st_size
    if size == 0:
        raise MeshError(f"{path}: cannot read mesh: the file is empty (0 bytes)")
    if suffix == ".stl":
        _check_stl_size(path, size)
    try:
        if suffix == ".ply" and has_strips(path):
            # trimesh reads no strips: Stanford's scans would have no faces.
            vertices, faces = read_ply_triangles(path)
        else:
            # process=False: no merging or face removal, the geometry stays as the file has it.
            loaded = trimesh.load_mesh(
                str(path), file_type=suffix[1:], process=False, skip_materials=True
            )
            vertices = np.asarray(loaded.vertices, dtype=np.float64)
            faces = np.asarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
    except Exception as err:  # any reader failure means a bad file, whatever the reader raises
        detail = f"{type(err).__name__}: {err}" if str(err) else type(err).__name__
        raise MeshError(f"{path}: cannot read mesh ({detail})") from err
    if len(faces) == 0 and vertices.ndim == 2:
        raise MeshError(
            f"{path}: mesh has no faces ({len(vertices)} vertices read): the file holds no "
            f"triangles that a {suffix[1:].upper()} reader understands"
        )
    validate_mesh(vertices, faces, str(path))
    vertices, faces = _drop_unused_vertices(vertices, faces)
    return Mesh(vertices, faces, str(path))


#: A binary STL: an 80-byte header, a uint32 triangle count, then 50 bytes a triangle.
_STL_HEADER_BYTES = 84
_STL_TRIANGLE_BYTES = 50


def _check_stl_size(path: Path, size: int) -> None:
    """Refuse a binary STL whose size disagrees with its triangle count (cut short, or not an
    STL at all), which trimesh would read as a mesh of no triangles. ASCII STL passes.

    Raises:
        MeshError: naming the file, the count its header promises and the bytes it has.
    """
    with open(path, "rb") as handle:
        head = handle.read(_STL_HEADER_BYTES)
    # A binary STL may start with "solid" too: the size decides first, then the ASCII keyword.
    ascii_stl = head.lstrip().startswith(b"solid")
    if size < _STL_HEADER_BYTES:
        if ascii_stl:
            return
        raise MeshError(
            f"{path}: cannot read mesh: {size} bytes is too short for a binary STL "
            f"(its header alone is {_STL_HEADER_BYTES} bytes) and it is not ASCII STL"
        )
    count = int(np.frombuffer(head[80:84], dtype="<u4")[0])
    need = _STL_HEADER_BYTES + _STL_TRIANGLE_BYTES * count
    if size == need or ascii_stl:
        return
    raise MeshError(
        f"{path}: cannot read mesh: its binary STL header promises {count} triangles "
        f"({need} bytes) but the file has {size} bytes; it is cut short or not an STL file"
    )


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
