"""PLY files whose faces are triangle strips (Stanford's scans: ``element tristrips``).

trimesh reads a PLY's ``vertex`` and ``face`` elements only, so a file whose surface is stored as
``element tristrips`` (a list property ``vertex_indices`` where -1 restarts a strip) comes back
without faces. :func:`has_strips` tells such a file from its header; :func:`read_ply_triangles`
reads it whole: the vertices, the ``face`` polygons (fan-triangulated) and the strips
(:func:`decode_strips`).

The reader is our own, not a library's: ``plyfile`` is GPL-3.0 and needs numpy >= 2 (the project
pins numpy 1.26 for Blender's wheel), meshio refuses elements other than ``vertex`` and ``face``,
and trimesh's binary reader assumes that every row of a list property has the same length (a
file with several strips of different lengths is "unexpected length"). It reads ASCII, binary
little-endian and binary big-endian files, every element of the header in order.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: PLY scalar type names -> numpy type codes (without byte order).
PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip

#: The PLY formats, and the byte order of each (None: ASCII).
FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}

#: The names exporters give a face's (or strip's) vertex index list.
INDEX_NAMES = ("vertex_indices", "vertex_index")

# A header longer than this is not a PLY header (it would be a garbage file that starts "ply").
_MAX_HEADER = 1 << 20


class PlyError(ValueError):
    """A PLY file that cannot be read (the caller adds the file's name)."""


@dataclass(frozen=True)
class Property:
    """One property of an element: a scalar (``count_type`` None) or a list."""

    name: str
    type: str
    count_type: str | None = None


@dataclass(frozen=True)
class Element:
    """An element of the header: its name, number of rows and properties."""

    name: str
    count: int
    properties: tuple[Property, ...]


@dataclass(frozen=True)
class Ragged:
    """A list property read for every row: row ``i`` is ``values[offsets[i]:offsets[i + 1]]``.

    Attributes:
        values: (sum of lengths,) the rows' values, concatenated.
        offsets: (rows + 1,) int64 start of each row in ``values``, then the total.
    """

    values: np.ndarray
    offsets: np.ndarray

    @property
    def lengths(self) -> np.ndarray:
        """(rows,) int64 length of each row."""
        return np.diff(self.offsets)


def _type(name: str) -> str:
    if name not in PLY_TYPES:
        raise PlyError(f"unknown property type {name!r}; allowed: {', '.join(PLY_TYPES)}")
    return PLY_TYPES[name]


def parse_header(data: bytes) -> tuple[str, list[Element], int]:
    """Read a PLY header.

    Args:
        data: the file's bytes (at least the whole header).

    Returns:
        ``(format, elements, body)``: the format (a key of :data:`FORMATS`), the elements in
        file order, and the offset of the first byte after ``end_header``'s line.

    Raises:
        PlyError: not a PLY file, an unknown format or type, or a malformed line.
    """
    end = data.find(b"end_header", 0, _MAX_HEADER)
    if not data.startswith(b"ply") or end < 0:
        raise PlyError("not a PLY file (no 'ply' ... 'end_header' header)")
    newline = data.find(b"\n", end)
    body = len(data) if newline < 0 else newline + 1
    fmt = None
    elements: list[Element] = []
    props: list[Property] = []
    for raw in data[:end].decode("ascii", errors="replace").splitlines()[1:]:
        words = raw.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            if elements:
                elements[-1] = Element(elements[-1].name, elements[-1].count, tuple(props))
            elements.append(Element(words[1], int(words[2]), ()))
            props = []
        elif words[:2] == ["property", "list"] and len(words) == 5 and elements:
            props.append(Property(words[4], _type(words[3]), _type(words[2])))
        elif words[0] == "property" and len(words) == 3 and elements:
            props.append(Property(words[2], _type(words[1])))
        else:
            raise PlyError(f"malformed header line {raw.strip()!r}")
    if fmt not in FORMATS:
        raise PlyError(f"unknown PLY format {fmt!r}; allowed: {', '.join(FORMATS)}")
    if elements:
        elements[-1] = Element(elements[-1].name, elements[-1].count, tuple(props))
    return fmt, elements, body


def has_strips(path: str | Path) -> bool:
    """True when the PLY file's header declares an element ``tristrips`` (False for a file that
    is not a PLY: the regular reader then says what is wrong with it)."""
    with open(path, "rb") as f:
        head = f.read(_MAX_HEADER)
    try:
        _, elements, _ = parse_header(head)
    except PlyError:
        return False
    return any(e.name == "tristrips" for e in elements)


def _columns(element: Element, columns: dict[str, list]) -> dict:
    """Rows read one by one -> a (rows,) array per scalar property, :class:`Ragged` per list."""
    out: dict = {}
    for p in element.properties:
        rows = columns[p.name]
        if p.count_type is None:
            out[p.name] = np.array(rows, dtype=np.float64).astype(p.type)
            continue
        lengths = np.array([len(r) for r in rows], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        values = np.concatenate(rows) if rows else np.zeros(0)
        out[p.name] = Ragged(values.astype(p.type), offsets)
    return out


def _ended(element: Element) -> PlyError:
    return PlyError(
        f"file ends inside element {element.name!r} (the header says {element.count} rows)"
    )


def _read_ascii(tokens: list[bytes], pos: int, element: Element) -> tuple[dict, int]:
    """One element's rows from whitespace-split ASCII tokens, from token ``pos``."""
    if all(p.count_type is None for p in element.properties):  # equal rows: one reshape
        width = len(element.properties)
        end = pos + element.count * width
        if end > len(tokens):
            raise _ended(element)
        table = np.array(tokens[pos:end], dtype=np.float64).reshape(element.count, width)
        return {p.name: table[:, j].astype(p.type) for j, p in enumerate(element.properties)}, end
    # Rows with lists, walked one by one: strips are few rows, and a file's faces go through
    # trimesh unless it has strips too.
    columns: dict[str, list] = {p.name: [] for p in element.properties}
    for _ in range(element.count):
        for p in element.properties:
            if pos >= len(tokens):
                raise _ended(element)
            if p.count_type is None:
                columns[p.name].append(float(tokens[pos]))
                pos += 1
                continue
            n = int(float(tokens[pos]))
            if n < 0 or pos + 1 + n > len(tokens):
                raise _ended(element)
            columns[p.name].append(np.array(tokens[pos + 1 : pos + 1 + n], dtype=np.float64))
            pos += 1 + n
    return _columns(element, columns), pos


def _read_binary(data: bytes, pos: int, element: Element, order: str) -> tuple[dict, int]:
    """One element's rows from binary ``data``, from byte ``pos``.

    When every row's lists have the first row's lengths (faces: all triangles), the element is
    one numpy read; otherwise (strips of different lengths) its rows are read one by one."""
    fields: list = []
    at = pos
    for p in element.properties:
        if p.count_type is None:
            fields.append((p.name, order + p.type))
            at += np.dtype(p.type).itemsize
            continue
        size = np.dtype(p.count_type).itemsize
        n = (
            int(np.frombuffer(data, order + p.count_type, 1, at)[0])
            if at + size <= len(data)
            else 0
        )
        fields += [
            (p.name + " count", order + p.count_type),
            (p.name, order + p.type, (max(n, 0),)),
        ]
        at += size + max(n, 0) * np.dtype(p.type).itemsize
    dtype = np.dtype(fields)
    end = pos + element.count * dtype.itemsize
    lists = [p for p in element.properties if p.count_type is not None]
    if end <= len(data):
        table = np.frombuffer(data, dtype, element.count, pos)
        width = {p.name: dtype[p.name].shape[0] for p in lists}
        if all(np.all(table[p.name + " count"] == width[p.name]) for p in lists):
            out: dict = {}
            for p in element.properties:
                if p.count_type is None:
                    out[p.name] = table[p.name].astype(p.type)
                else:
                    offsets = np.arange(element.count + 1, dtype=np.int64) * width[p.name]
                    out[p.name] = Ragged(table[p.name].reshape(-1).astype(p.type), offsets)
            return out, end
    if not lists:  # rows of one size: too few bytes for them
        raise _ended(element)
    columns: dict[str, list] = {p.name: [] for p in element.properties}
    for _ in range(element.count):
        for p in element.properties:
            kind = p.type if p.count_type is None else p.count_type
            size = np.dtype(kind).itemsize
            if pos + size > len(data):
                raise _ended(element)
            value = np.frombuffer(data, order + kind, 1, pos)[0]
            pos += size
            if p.count_type is None:
                columns[p.name].append(value)
                continue
            n, nbytes = int(value), int(value) * np.dtype(p.type).itemsize
            if n < 0 or pos + nbytes > len(data):
                raise _ended(element)
            columns[p.name].append(np.frombuffer(data, order + p.type, n, pos))
            pos += nbytes
    return _columns(element, columns), pos


def read_elements(data: bytes) -> dict[str, dict[str, np.ndarray | Ragged]]:
    """Every element of a PLY file: element name -> property name -> (rows,) array for a scalar
    property, :class:`Ragged` for a list property.

    Raises:
        PlyError: a bad header, or a body shorter than the header says (counts too large).
    """
    fmt, elements, pos = parse_header(data)
    order = FORMATS[fmt]
    tokens = data[pos:].split() if order is None else []
    at = 0 if order is None else pos
    out = {}
    for element in elements:
        if order is None:
            out[element.name], at = _read_ascii(tokens, at, element)
        else:
            out[element.name], at = _read_binary(data, at, element, order)
    return out


def decode_strips(indices: np.ndarray) -> np.ndarray:
    """Triangles of triangle strips.

    A strip ``a b c d e`` gives ``(a, b, c), (c, b, d), (c, d, e)``: the k-th triangle of a strip
    is ``(s[k], s[k+1], s[k+2])`` for even k and ``(s[k+1], s[k], s[k+2])`` for odd k, so that
    every triangle keeps the strip's orientation. -1 ends a strip and starts the next. The parity
    counts from each strip's start, degenerate triangles included (exporters insert them to turn
    a strip), and triangles with a repeated index are then dropped.

    Args:
        indices: (K,) integer vertex indices, -1 between strips.

    Returns:
        (F, 3) int64 triangles, in strip order.
    """
    s = np.asarray(indices, dtype=np.int64).reshape(-1)
    if len(s) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    position = np.arange(len(s))
    # The index of each entry's strip start: one past the last -1 at or before it.
    start = np.maximum.accumulate(np.where(s == -1, position + 1, 0))
    a, b, c = s[:-2], s[1:-1], s[2:]
    whole = (a != -1) & (b != -1) & (c != -1)
    odd = (position[:-2] - start[:-2]) % 2 == 1
    tri = np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1)[whole]
    distinct = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])
    return tri[distinct]


def fan_triangles(polygons: Ragged) -> np.ndarray:
    """Polygons as triangle fans: ``(p0, p[i], p[i+1])`` for i in 1 .. n-2 (a polygon of fewer
    than 3 vertices gives none).

    Args:
        polygons: the ``face`` element's index lists.

    Returns:
        (F, 3) int64 triangles, polygon by polygon.
    """
    lengths = polygons.lengths
    per = np.maximum(lengths - 2, 0)
    first = np.repeat(polygons.offsets[:-1], per)
    # i = 1 .. n-2 within each polygon.
    i = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per) + 1
    v = np.asarray(polygons.values, dtype=np.int64)
    return np.stack([v[first], v[first + i], v[first + i + 1]], axis=1).reshape(-1, 3)


def _index_list(element: dict, name: str) -> Ragged:
    for key in INDEX_NAMES:
        if isinstance(element.get(key), Ragged):
            return element[key]
    raise PlyError(f"element {name!r} has no list property {' or '.join(INDEX_NAMES)}")


def read_ply_triangles(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """The vertices and triangles of a PLY file: its ``face`` polygons (fan-triangulated) then
    its ``tristrips`` (:func:`decode_strips`, each row a strip or several separated by -1).

    Returns:
        ``(vertices, faces)``: (N, 3) float64 x, y, z of the ``vertex`` element, (F, 3) int64
        triangles (indices not checked against N: :func:`nbv.assets.meshes.validate_mesh` does).

    Raises:
        PlyError: the file cannot be read, or has no vertex x, y, z.
    """
    elements = read_elements(Path(path).read_bytes())
    vertex = elements.get("vertex", {})
    if not all(isinstance(vertex.get(k), np.ndarray) for k in "xyz"):
        raise PlyError("no element 'vertex' with properties x, y, z")
    vertices = np.stack([vertex[k] for k in "xyz"], axis=1).astype(np.float64)
    faces = [np.zeros((0, 3), dtype=np.int64)]
    if "face" in elements:
        faces.append(fan_triangles(_index_list(elements["face"], "face")))
    if "tristrips" in elements:
        strips = _index_list(elements["tristrips"], "tristrips")
        # Each row is a strip of its own: a -1 after every row keeps rows apart.
        rows = np.insert(np.asarray(strips.values, dtype=np.int64), strips.offsets[1:], -1)
        faces.append(decode_strips(rows))
    return vertices, np.concatenate(faces)
