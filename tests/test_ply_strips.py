"""PLY files whose faces are triangle strips (Stanford's ``element tristrips``): built here from a
known grid, in ASCII and binary (both byte orders), and read by ``load_mesh`` with the faces an
independent, loop-by-loop decoding of the same strips gives, every triangle facing +z."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nbv.assets.meshes import MeshError, face_areas, load_mesh
from nbv.assets.ply import Ragged, decode_strips, fan_triangles

# A grid of ROWS x COLS vertices in the plane z = 0: vertex (r, c) is index r * COLS + c at
# (c, r, 0).
ROWS, COLS = 4, 5
GRID = np.array([[c, r, 0.0] for r in range(ROWS) for c in range(COLS)])


def vid(r: int, c: int) -> int:
    return r * COLS + c


def band(r: int, cols: range) -> list[int]:
    """The strip over grid row r: (r+1, c), (r, c) alternately, so its triangles face +z."""
    return [i for c in cols for i in (vid(r + 1, c), vid(r, c))]


# Each row of the element is a strip or several separated by -1. Row 0 covers grid band 0 in two
# strips (a restart); row 1 covers band 1 in two strips joined the usual way, the last index of
# the first and the first of the second repeated (four degenerate triangles, dropped; the parity
# counts them); row 2 covers band 2, a single strip.
STRIP_ROWS = [
    band(0, range(0, 3)) + [-1] + band(0, range(2, 5)),
    band(1, range(0, 3)) + [vid(1, 2), vid(2, 2)] + band(1, range(2, 5)),
    band(2, range(0, 5)),
]


def brute_force(rows: list[list[int]]) -> list[tuple[int, int, int]]:
    """The strips' triangles, written as a plain loop: the k-th triangle of a strip is
    (s[k], s[k+1], s[k+2]), its first two swapped for odd k; -1 (and each row's end) ends a
    strip; a triangle with a repeated index is dropped."""
    out = []
    for row in rows:
        strip: list[int] = []
        for index in [*row, -1]:
            if index == -1:
                for k in range(len(strip) - 2):
                    a, b, c = strip[k], strip[k + 1], strip[k + 2]
                    tri = (b, a, c) if k % 2 else (a, b, c)
                    if len(set(tri)) == 3:
                        out.append(tri)
                strip = []
            else:
                strip.append(index)
    return out


def header(fmt: str, n_vertices: int, n_strips: int, faces: list[list[int]] | None) -> bytes:
    lines = ["ply", f"format {fmt} 1.0", "comment made by test_ply_strips",
             f"element vertex {n_vertices}", "property float x", "property float y",
             "property float z"]  # fmt: skip
    if faces is not None:
        lines += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    lines += [f"element tristrips {n_strips}", "property list int int vertex_indices", "end_header"]
    return ("\n".join(lines) + "\n").encode()


def ply_bytes(fmt: str, rows: list[list[int]], faces: list[list[int]] | None = None) -> bytes:
    """A PLY file of GRID with the strip rows (and a face element before them, when given)."""
    out = header(fmt, len(GRID), len(rows), faces)
    if fmt == "ascii":
        text = [" ".join(f"{x:g}" for x in v) for v in GRID]
        text += [" ".join(str(i) for i in [len(f), *f]) for f in faces or []]
        text += [" ".join(str(i) for i in [len(r), *r]) for r in rows]
        return out + ("\n".join(text) + "\n").encode()
    order = "<" if fmt == "binary_little_endian" else ">"
    out += GRID.astype(order + "f4").tobytes()
    for f in faces or []:
        out += np.array([len(f)], "u1").tobytes() + np.array(f, order + "i4").tobytes()
    for r in rows:
        out += np.array([len(r), *r], order + "i4").tobytes()
    return out


FORMATS = ["ascii", "binary_little_endian", "binary_big_endian"]


@pytest.mark.parametrize("fmt", FORMATS)
def test_strips_read_as_the_loop_decodes_them_all_facing_up(tmp_path, fmt):
    path = tmp_path / "strips.ply"
    path.write_bytes(ply_bytes(fmt, STRIP_ROWS))
    mesh = load_mesh(path)
    expected = brute_force(STRIP_ROWS)
    # Each band gives 8 triangles (two strips of 4 or one of 8); the join's four degenerate
    # triangles are dropped: 24 triangles, the 3 bands in full, each once.
    assert len(expected) == 24
    np.testing.assert_array_equal(mesh.faces, np.array(expected))
    np.testing.assert_array_equal(mesh.vertices, GRID)
    tri = mesh.vertices[mesh.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    np.testing.assert_array_equal(normals, np.tile([0.0, 0.0, 1.0], (24, 1)))
    assert mesh.area == pytest.approx(3 * 4)


def test_the_stitch_keeps_the_parity_of_its_strip():
    # 5 6 0 1 (a quad) then a repeated 1 and the strip goes on: 1 1 x is degenerate, and the
    # triangle after it is odd, flipped.
    assert decode_strips(np.array([5, 0, 6, 1, 1, 7, 2])).tolist() == [
        [5, 0, 6], [6, 0, 1], [1, 7, 2],
    ]  # fmt: skip
    assert decode_strips(np.array([0, 1, 2, 3, 4])).tolist() == [[0, 1, 2], [2, 1, 3], [2, 3, 4]]
    assert decode_strips(np.array([0, 1, -1, 2, 3, 4])).tolist() == [[2, 3, 4]]
    assert decode_strips(np.array([0, 1])).shape == (0, 3)


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_face_element_and_strips_are_both_read(tmp_path, fmt):
    # A quad and a pentagon over band 2 (fan-triangulated) come first, then the strips'.
    faces = [[vid(2, 0), vid(2, 1), vid(3, 1), vid(3, 0)],
             [vid(2, 1), vid(2, 2), vid(2, 3), vid(3, 3), vid(3, 1)]]  # fmt: skip
    path = tmp_path / "both.ply"
    path.write_bytes(ply_bytes(fmt, STRIP_ROWS, faces))
    mesh = load_mesh(path)
    fans = [[10, 11, 16], [10, 16, 15], [11, 12, 13], [11, 13, 18], [11, 18, 16]]
    np.testing.assert_array_equal(mesh.faces, np.array(fans + brute_force(STRIP_ROWS)))


def test_fan_triangles_of_ragged_polygons():
    polygons = Ragged(np.array([0, 1, 2, 3, 4, 5, 6, 7, 8, 9]), np.array([0, 4, 6, 10]))
    # A quad, a two-vertex "polygon" (no triangle) and a quad.
    assert fan_triangles(polygons).tolist() == [[0, 1, 2], [0, 2, 3], [6, 7, 8], [6, 8, 9]]


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_strip_file_whose_header_lies_is_refused_in_one_line(tmp_path, fmt):
    data = ply_bytes(fmt, STRIP_ROWS).replace(b"tristrips 3", b"tristrips 9")
    path = tmp_path / "lie.ply"
    path.write_bytes(data)
    with pytest.raises(MeshError, match=r"lie\.ply: cannot read mesh .*'tristrips'.*9 rows"):
        load_mesh(path)


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_strip_index_out_of_range_is_refused(tmp_path, fmt):
    path = tmp_path / "range.ply"
    path.write_bytes(ply_bytes(fmt, [[0, 1, 5, 99]]))
    with pytest.raises(MeshError, match=r"range\.ply: face indices must lie in \[0, 20\)"):
        load_mesh(path)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.lists(st.integers(-1, 7), max_size=12), min_size=1, max_size=4))
def test_decoding_matches_the_loop_for_any_strips(rows):
    joined = [i for row in rows for i in [*row, -1]]
    expected = np.array(brute_force(rows), dtype=np.int64).reshape(-1, 3)
    np.testing.assert_array_equal(decode_strips(np.array(joined, dtype=np.int64)), expected)


@pytest.mark.skipif(
    not (Path(__file__).resolve().parents[2] / "shared" / "meshes" / "igea.ply").exists(),
    reason="Stanford's igea.ply is not in ../shared/meshes",
)
def test_stanfords_igea_reads_with_its_strips():
    mesh = load_mesh(Path(__file__).resolve().parents[2] / "shared" / "meshes" / "igea.ply")
    assert len(mesh.vertices) == 134_345 and len(mesh.faces) > 0
    assert face_areas(mesh.vertices, mesh.faces).min() > 0
