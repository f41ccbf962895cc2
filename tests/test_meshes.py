import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from nbv.assets.catalogues import (
    CatalogueError,
    MeshEntry,
    bop_catalogue,
    check_catalogue,
    folder_catalogue,
    homebrew_catalogue,
    linemod_catalogue,
    shapenet_catalogue,
    stanford_catalogue,
)
from nbv.assets.categories import SHAPENET_TRAIN_CATEGORIES, SHAPENET_UNSEEN_CATEGORIES
from nbv.assets.mesh_sources import MESH_SOURCES, catalogue
from nbv.assets.meshes import (
    MESH_SUFFIXES,
    Mesh,
    MeshError,
    face_areas,
    load_mesh,
    normalise,
    sample_surface,
    validate_mesh,
)

# Tetrahedron on the unit axes: three right triangles of area 1/2 and one equilateral of side
# sqrt(2), area sqrt(3)/2.
TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
TET_AREA = 1.5 + np.sqrt(3) / 2

# Unit cube centred at the origin, six quads (OBJ indices are 1-based).
CUBE_OBJ = """# unit cube, quads
v -0.5 -0.5 -0.5
v 0.5 -0.5 -0.5
v 0.5 0.5 -0.5
v -0.5 0.5 -0.5
v -0.5 -0.5 0.5
v 0.5 -0.5 0.5
v 0.5 0.5 0.5
v -0.5 0.5 0.5
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
"""


def ply_text(vertices, faces) -> str:
    header = [
        "ply",
        "format ascii 1.0",
        f"element vertex {len(vertices)}",
        "property float x",
        "property float y",
        "property float z",
        f"element face {len(faces)}",
        "property list uchar int vertex_indices",
        "end_header",
    ]
    rows = [" ".join(str(x) for x in v) for v in vertices]
    rows += [" ".join(str(i) for i in [len(f), *f]) for f in faces]
    return "\n".join(header + rows) + "\n"


def obj_text(vertices, faces) -> str:
    rows = ["v " + " ".join(str(x) for x in v) for v in vertices]
    rows += ["f " + " ".join(str(i + 1) for i in f) for f in faces]
    return "\n".join(rows) + "\n"


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def tiny(path: Path) -> Path:
    """A tetrahedron in the format the suffix says (OBJ or PLY)."""
    if path.suffix == ".ply":
        return write(path, ply_text(TET_V, TET_F))
    return write(path, obj_text(TET_V, TET_F))


# ---------------------------------------------------------------------------------------------
# Loading


def test_obj_quads_are_triangulated(tmp_path):
    mesh = load_mesh(write(tmp_path / "cube.obj", CUBE_OBJ))
    assert mesh.vertices.shape == (8, 3) and mesh.vertices.dtype == np.float64
    assert mesh.faces.shape == (12, 3) and mesh.faces.dtype == np.int64
    assert mesh.area == pytest.approx(6.0, abs=1e-12)
    assert mesh.source_path == str(tmp_path / "cube.obj")
    np.testing.assert_array_equal(np.abs(mesh.vertices), 0.5)


def check_tetrahedron(mesh: Mesh):
    assert mesh.faces.shape == (4, 3)
    assert mesh.area == pytest.approx(TET_AREA, rel=1e-6)
    # Same set of corners whatever the writer did with vertex order or duplication.
    np.testing.assert_allclose(
        np.unique(mesh.vertices, axis=0), np.unique(TET_V, axis=0), atol=1e-6
    )


def test_load_ascii_ply_off_and_uppercase_suffix(tmp_path):
    check_tetrahedron(load_mesh(write(tmp_path / "t.ply", ply_text(TET_V, TET_F))))
    off = "OFF\n4 4 0\n" + "".join(f"{x} {y} {z}\n" for x, y, z in TET_V)
    off += "".join(f"3 {a} {b} {c}\n" for a, b, c in TET_F)
    check_tetrahedron(load_mesh(write(tmp_path / "t.off", off)))
    check_tetrahedron(load_mesh(write(tmp_path / "T.PLY", ply_text(TET_V, TET_F))))


def test_load_binary_ply_and_stl(tmp_path):
    tet = trimesh.Trimesh(TET_V, TET_F, process=False)
    (tmp_path / "t.stl").write_bytes(trimesh.exchange.stl.export_stl(tet))
    (tmp_path / "b.ply").write_bytes(trimesh.exchange.ply.export_ply(tet, encoding="binary"))
    stl = load_mesh(tmp_path / "t.stl")
    check_tetrahedron(stl)
    assert len(stl.vertices) == 12  # STL repeats corners and the loader does not merge them
    check_tetrahedron(load_mesh(tmp_path / "b.ply"))


def test_glb_scene_is_flattened_with_transforms(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.Trimesh(TET_V, TET_F, process=False), node_name="a")
    shift = np.eye(4)
    shift[:3, 3] = [10.0, 0.0, 0.0]
    scene.add_geometry(trimesh.creation.box(), node_name="b", transform=shift)
    (tmp_path / "s.glb").write_bytes(scene.export(file_type="glb"))
    mesh = load_mesh(tmp_path / "s.glb")
    assert mesh.faces.shape == (4 + 12, 3)
    assert mesh.area == pytest.approx(TET_AREA + 6.0, rel=1e-6)
    np.testing.assert_allclose(mesh.vertices.min(axis=0), [0, -0.5, -0.5], atol=1e-6)
    np.testing.assert_allclose(mesh.vertices.max(axis=0), [10.5, 1, 1], atol=1e-6)


def test_unused_vertices_dropped_and_flat_mesh_loads(tmp_path):
    # A flat square (zero volume, area 1) plus a vertex no face uses, far away.
    verts = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [100, 100, 100]]
    mesh = load_mesh(write(tmp_path / "flat.obj", obj_text(verts, [[0, 1, 2], [0, 2, 3]])))
    np.testing.assert_array_equal(mesh.vertices, verts[:4])
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 2, 3]])
    assert mesh.area == pytest.approx(1.0)
    normalised, center, scale = normalise(mesh)
    np.testing.assert_allclose(center, [0.5, 0.5, 0])
    assert scale == pytest.approx(0.5 / np.sqrt(0.5))


def test_mesh_arrays_are_read_only():
    mesh = Mesh(TET_V, TET_F)
    with pytest.raises(ValueError):
        mesh.vertices[0, 0] = 1.0
    with pytest.raises(MeshError, match="shape"):
        Mesh(np.zeros((3, 2)), TET_F)


# ---------------------------------------------------------------------------------------------
# Bad meshes


BAD_FILES = {
    "garbage.ply": (b"\x00\x01garbage\xff not a mesh", "cannot read"),
    "garbage.off": (b"hello world\n", "cannot read"),
    "garbage.glb": (b"hello world\n", "cannot read"),
    "garbage.obj": (b"hello world\n", "no faces"),
    "empty.obj": (b"", "the file is empty"),
    "points.ply": (ply_text(TET_V, []).encode(), "no faces"),
    "nan.obj": (obj_text([["nan", 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).encode(), "NaN"),
    "inf.obj": (obj_text([[0, 0, 0], [1, "inf", 0], [0, 1, 0]], [[0, 1, 2]]).encode(), "NaN"),
    "nan.ply": (ply_text([[0, 0, 0], [1, 0, 0], [0, "nan", 0]], [[0, 1, 2]]).encode(), "NaN"),
    "line.obj": (obj_text([[0, 0, 0], [1, 1, 1], [2, 2, 2]], [[0, 1, 2]]).encode(), "area"),
    "point.off": (b"OFF\n3 1 0\n1 1 1\n1 1 1\n1 1 1\n3 0 1 2\n", "area"),
    "index.ply": (ply_text(TET_V, [[0, 1, 9]]).encode(), "face indices"),
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_file_refused_naming_file(tmp_path, name):
    content, reason = BAD_FILES[name]
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(MeshError, match=reason) as info:
        load_mesh(path)
    assert str(path) in str(info.value)


def test_missing_directory_and_unknown_suffix_refused(tmp_path):
    with pytest.raises(MeshError, match="no such file") as info:
        load_mesh(tmp_path / "missing.obj")
    assert "missing.obj" in str(info.value)
    (tmp_path / "folder.obj").mkdir()
    with pytest.raises(MeshError, match="directory"):
        load_mesh(tmp_path / "folder.obj")
    path = write(tmp_path / "cloud.xyz", "0 0 0\n")
    with pytest.raises(MeshError, match=r"cloud\.xyz.*'\.xyz'.*\.obj, \.ply, \.off, \.stl, \.glb"):
        load_mesh(path)


def test_validate_mesh_on_arrays():
    validate_mesh(TET_V, TET_F, "tet")
    with pytest.raises(MeshError, match="^sphere: .*no faces"):
        validate_mesh(TET_V, np.zeros((0, 3), int), "sphere")
    with pytest.raises(MeshError, match="^tet: .*integer"):
        validate_mesh(TET_V, TET_F.astype(float), "tet")
    with pytest.raises(MeshError, match="^tet: .*shape"):
        validate_mesh(TET_V[:, :2], TET_F, "tet")
    with pytest.raises(MeshError, match="^tet: .*-1"):
        validate_mesh(TET_V, TET_F - 1, "tet")
    v = TET_V.copy()
    v[2, 1] = -np.inf
    with pytest.raises(MeshError, match=r"^tet: 1 of 4 vertices .*vertex 2 = \[0.0, -inf, 0.0\]"):
        validate_mesh(v, TET_F, "tet")
    with pytest.raises(MeshError, match="^tet: .*area"):
        validate_mesh(np.ones((4, 3)), TET_F, "tet")


# ---------------------------------------------------------------------------------------------
# Normalisation


def test_normalise_box_exact_values():
    # Box [1, 3] x [2, 6] x [3, 11]: centre (2, 4, 7), half-diagonal sqrt(1 + 4 + 16).
    box = trimesh.creation.box(bounds=[[1, 2, 3], [3, 6, 11]])
    mesh = Mesh(box.vertices, box.faces, "box")
    normalised, center, scale = normalise(mesh)
    np.testing.assert_allclose(center, [2, 4, 7], atol=1e-15)
    assert scale == pytest.approx(0.5 / np.sqrt(21), rel=1e-15)
    expected = np.broadcast_to(np.array([1.0, 2.0, 4.0]) * scale, (8, 3))
    np.testing.assert_allclose(np.abs(normalised.vertices), expected, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(normalised.vertices, axis=1), 0.5, atol=1e-15)
    np.testing.assert_array_equal(normalised.faces, mesh.faces)
    assert normalised.source_path == "box"


def test_normalise_general_mesh_and_inverse():
    rng = np.random.default_rng(3)
    verts = rng.normal(size=(50, 3)) * [3.0, 0.2, 40.0] + [100.0, -7.0, 2.0]
    mesh = Mesh(verts, rng.integers(0, 50, size=(80, 3)))
    normalised, center, scale = normalise(mesh)
    # Independent brute force: bounding-box centre, farthest vertex from it.
    bb_center = (verts.min(axis=0) + verts.max(axis=0)) / 2
    np.testing.assert_allclose(center, bb_center, atol=1e-12)
    np.testing.assert_allclose(scale, 0.5 / np.linalg.norm(verts - bb_center, axis=1).max())
    out = normalised.vertices
    np.testing.assert_allclose(out.min(axis=0) + out.max(axis=0), 0.0, atol=1e-12)
    assert np.linalg.norm(out, axis=1).max() == pytest.approx(0.5, abs=1e-15)
    np.testing.assert_allclose((verts - center) * scale, out, atol=1e-15)
    np.testing.assert_allclose(out / scale + center, verts, atol=1e-12)


def test_normalise_refuses_a_point():
    with pytest.raises(MeshError, match="^p.obj: all vertices coincide"):
        normalise(Mesh(np.ones((3, 3)), [[0, 1, 2]], "p.obj"))


# ---------------------------------------------------------------------------------------------
# Sampling


def test_samples_lie_on_cube_surface(tmp_path):
    mesh = load_mesh(write(tmp_path / "cube.obj", CUBE_OBJ))
    points = sample_surface(mesh, 5000, np.random.default_rng(0))
    assert points.shape == (5000, 3) and points.dtype == np.float32
    np.testing.assert_allclose(np.abs(points).max(axis=1), 0.5, atol=1e-7)
    # Each of the 6 faces gets about 1/6 of the points (binomial sd ~0.005).
    axis = np.argmax(np.abs(points), axis=1)
    face_of = 2 * axis + (points[np.arange(5000), axis] > 0)
    np.testing.assert_allclose(np.bincount(face_of, minlength=6) / 5000, 1 / 6, atol=0.025)


def test_samples_uniform_by_area():
    # Two disjoint squares: area 1 at z = 0 and area 3 (side sqrt 3) at z = 5.
    s = np.sqrt(3.0)
    verts = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 5], [s, 0, 5], [s, s, 5], [0, s, 5]]
    faces = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]
    points = sample_surface(Mesh(verts, faces), 40000, np.random.default_rng(1))
    assert set(np.unique(points[:, 2])) == {0.0, 5.0}
    assert np.mean(points[:, 2] == 5.0) == pytest.approx(0.75, abs=0.01)  # sd 0.002


def test_samples_uniform_inside_a_triangle():
    # Right triangle (0,0) (1,0) (0,1): the corner triangle x + y < 1/2 holds 1/4 of the area,
    # the strip x < 1/2 holds 3/4, and the mean is the centroid (1/3, 1/3).
    mesh = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    p = sample_surface(mesh, 40000, np.random.default_rng(2)).astype(np.float64)
    assert np.all(p[:, 0] >= 0) and np.all(p[:, 1] >= 0) and np.all(p.sum(axis=1) <= 1 + 1e-6)
    assert np.mean(p[:, 0] + p[:, 1] < 0.5) == pytest.approx(0.25, abs=0.01)
    assert np.mean(p[:, 0] < 0.5) == pytest.approx(0.75, abs=0.01)
    np.testing.assert_allclose(p[:, :2].mean(axis=0), 1 / 3, atol=0.005)


def test_samples_skip_zero_area_faces_and_are_deterministic():
    verts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5], [6, 6, 6], [7, 7, 7]]
    mesh = Mesh(verts, [[3, 4, 5], [0, 1, 2], [3, 3, 4]])
    a = sample_surface(mesh, 1000, np.random.default_rng(7))
    assert np.all(a[:, 2] == 0.0)
    np.testing.assert_array_equal(a, sample_surface(mesh, 1000, np.random.default_rng(7)))
    assert not np.array_equal(a, sample_surface(mesh, 1000, np.random.default_rng(8)))
    assert sample_surface(mesh, 0, np.random.default_rng(7)).shape == (0, 3)
    with pytest.raises(ValueError, match="non-negative"):
        sample_surface(mesh, -1, np.random.default_rng(7))


def test_face_areas():
    np.testing.assert_allclose(face_areas(TET_V, TET_F), [0.5, 0.5, 0.5, np.sqrt(3) / 2])


# ---------------------------------------------------------------------------------------------
# Catalogues

SAFE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def summary(entries):
    assert all(SAFE_KEY.match(e.key) for e in entries)
    assert [e.key for e in entries] == sorted(e.key for e in entries)
    return [(e.key, e.category, e.source) for e in entries]


def test_category_constants():
    assert list(SHAPENET_TRAIN_CATEGORIES.items()) == [
        ("airplane", "02691156"),
        ("cabinet", "02933112"),
        ("car", "02958343"),
        ("chair", "03001627"),
        ("lamp", "03636649"),
        ("sofa", "04256520"),
        ("table", "04379243"),
        ("vessel", "04530566"),
    ]
    assert list(SHAPENET_UNSEEN_CATEGORIES.items()) == [
        ("bus", "02924116"),
        ("bed", "02818832"),
        ("bookshelf", "02871439"),
        ("bench", "02828884"),
        ("guitar", "03467517"),
        ("motorbike", "03790512"),
        ("skateboard", "04225987"),
        ("pistol", "03948459"),
    ]


@pytest.fixture
def shapenet_v2(tmp_path):
    root = tmp_path / "ShapeNetCore.v2"
    for synset, model in [
        ("03001627", "c2"),
        ("03001627", "c1"),
        ("02691156", "a1"),
        ("02924116", "b1"),
        ("09999999", "x1"),
    ]:
        tiny(root / synset / model / "models" / "model_normalized.obj")
    (root / "03001627" / "empty_model").mkdir()  # no mesh: skipped
    write(root / "taxonomy.json", "[]")
    return root


def test_shapenet_v2_catalogue(shapenet_v2):
    # Every synset folder with categories=[all], sorted by key ...
    entries = shapenet_catalogue(shapenet_v2, ["all"])
    assert summary(entries) == [
        ("09999999_x1", "09999999", "shapenet"),
        ("airplane_a1", "airplane", "shapenet"),
        ("bus_b1", "bus", "shapenet"),
        ("chair_c1", "chair", "shapenet"),
        ("chair_c2", "chair", "shapenet"),
    ]
    assert entries[3].path == shapenet_v2 / "03001627/c1/models/model_normalized.obj"
    assert catalogue("shapenet", shapenet_v2, ["all"]) == entries
    # ... and by default only PC-NBV's 16 categories (the unnamed synset is left out).
    default = shapenet_catalogue(shapenet_v2)
    assert summary(default) == [s for s in summary(entries) if s[1] != "09999999"]
    assert catalogue("shapenet", shapenet_v2) == default


def test_shapenet_category_selection(shapenet_v2):
    keys = [e.key for e in shapenet_catalogue(shapenet_v2, ["chair"])]
    assert keys == ["chair_c1", "chair_c2"]
    keys = [e.key for e in shapenet_catalogue(shapenet_v2, ["02691156", "chair", "03001627"])]
    assert keys == ["airplane_a1", "chair_c1", "chair_c2"]
    assert [e.key for e in catalogue("shapenet", shapenet_v2, ["bus"])] == ["bus_b1"]
    with pytest.raises(CatalogueError, match="'chiar'.*airplane, cabinet.*pistol"):
        shapenet_catalogue(shapenet_v2, ["chiar"])
    with pytest.raises(CatalogueError, match="04379243.*'table'"):
        shapenet_catalogue(shapenet_v2, ["table"])


def test_shapenet_v1_catalogue(tmp_path):
    for synset, model in [("04379243", "t1"), ("04530566", "v1"), ("04530566", "v0")]:
        tiny(tmp_path / synset / model / "model.obj")
    entries = shapenet_catalogue(tmp_path)
    assert summary(entries) == [
        ("table_t1", "table", "shapenet"),
        ("vessel_v0", "vessel", "shapenet"),
        ("vessel_v1", "vessel", "shapenet"),
    ]
    assert entries[0].path == tmp_path / "04379243" / "t1" / "model.obj"


def test_shapenet_catalogue_errors(tmp_path):
    with pytest.raises(CatalogueError, match="nowhere.*no such folder"):
        shapenet_catalogue(tmp_path / "nowhere")
    tiny(tmp_path / "chairs" / "a.obj")
    with pytest.raises(CatalogueError, match="no ShapeNet synset folders"):
        shapenet_catalogue(tmp_path)
    tiny(tmp_path / "09999999" / "x1" / "model.obj")
    with pytest.raises(CatalogueError, match="no ShapeNet synset folders of the 16 PC-NBV"):
        shapenet_catalogue(tmp_path)
    assert [e.key for e in shapenet_catalogue(tmp_path, ["all"])] == ["09999999_x1"]
    (tmp_path / "09999999" / "x1" / "model.obj").unlink()
    (tmp_path / "03001627" / "m1").mkdir(parents=True)
    with pytest.raises(CatalogueError, match="no ShapeNet models"):
        shapenet_catalogue(tmp_path)


def test_stanford_catalogue(tmp_path):
    for rel in [
        "bunny/reconstruction/bun_zipper.ply",
        "bunny/reconstruction/bun_zipper_res2.ply",
        "dragon_recon/dragon_vrip.ply",
        "Armadillo.ply",
    ]:
        tiny(tmp_path / rel)
    write(tmp_path / "bunny" / "README", "scans")
    entries = stanford_catalogue(tmp_path)
    assert summary(entries) == [
        ("Armadillo", "Armadillo", "stanford"),
        ("bunny_reconstruction_bun_zipper", "bunny", "stanford"),
        ("bunny_reconstruction_bun_zipper_res2", "bunny", "stanford"),
        ("dragon_recon_dragon_vrip", "dragon", "stanford"),
    ]
    assert entries[3].path == tmp_path / "dragon_recon" / "dragon_vrip.ply"
    assert catalogue("stanford", tmp_path) == entries
    (tmp_path / "empty").mkdir()
    with pytest.raises(CatalogueError, match="empty: no PLY"):
        stanford_catalogue(tmp_path / "empty")


def test_bop_catalogues(tmp_path):
    lm = tmp_path / "lm"
    for name in ["obj_000002.ply", "obj_000001.ply"]:
        tiny(lm / "models" / name)
    tiny(lm / "models_eval" / "obj_000003.ply")  # models/ is preferred
    write(lm / "models" / "models_info.json", "{}")
    entries = linemod_catalogue(lm)
    assert summary(entries) == [
        ("linemod_obj_000001", "obj_000001", "linemod"),
        ("linemod_obj_000002", "obj_000002", "linemod"),
    ]
    assert entries[0].path == lm / "models" / "obj_000001.ply"
    assert catalogue("linemod", lm) == entries
    # The models folder itself, and a dataset with only models_eval.
    assert linemod_catalogue(lm / "models") == entries
    hb = tmp_path / "hb"
    tiny(hb / "models_eval" / "obj_000007.ply")
    assert summary(homebrew_catalogue(hb)) == [("homebrew_obj_000007", "obj_000007", "homebrew")]
    assert catalogue("homebrew", hb) == homebrew_catalogue(hb)
    assert bop_catalogue(hb, "hb")[0].key == "hb_obj_000007"
    (tmp_path / "empty" / "models").mkdir(parents=True)
    with pytest.raises(CatalogueError, match="no BOP object models"):
        linemod_catalogue(tmp_path / "empty")


def test_folder_catalogue(tmp_path):
    tiny(tmp_path / "a.obj")
    tiny(tmp_path / "chair" / "b.ply")
    tiny(tmp_path / "chair" / "deep" / "my model.obj")
    tiny(tmp_path / "table" / "d.obj")
    tiny(tmp_path / "table" / "d.ply")
    tiny(tmp_path / ".hidden" / "x.obj")
    tiny(tmp_path / "table" / "._d.obj")
    write(tmp_path / "notes.txt", "not a mesh")
    entries = folder_catalogue(tmp_path)
    assert summary(entries) == [
        ("a", "default", "folder"),
        ("chair_b", "chair", "folder"),
        ("chair_deep_my_model", "chair", "folder"),
        ("table_d_obj", "table", "folder"),
        ("table_d_ply", "table", "folder"),
    ]
    assert entries[2].path == tmp_path / "chair" / "deep" / "my model.obj"
    assert catalogue("folder", tmp_path) == entries
    assert {Path(e.path).suffix for e in entries} <= set(MESH_SUFFIXES)


def test_folder_catalogue_errors(tmp_path):
    write(tmp_path / "notes.txt", "not a mesh")
    with pytest.raises(CatalogueError, match="no mesh files"):
        folder_catalogue(tmp_path)
    tiny(tmp_path / "x y.obj")
    tiny(tmp_path / "x_y.obj")
    with pytest.raises(CatalogueError, match="same key 'x_y_obj'.*x y.obj and .*x_y.obj"):
        folder_catalogue(tmp_path)
    with pytest.raises(CatalogueError, match="is a file"):
        folder_catalogue(tmp_path / "x_y.obj")


def test_catalogue_dispatch_errors(tmp_path):
    with pytest.raises(CatalogueError, match="'modelnet'.*" + ", ".join(MESH_SOURCES)):
        catalogue("modelnet", tmp_path)
    with pytest.raises(CatalogueError, match="only 'shapenet'"):
        catalogue("folder", tmp_path, ["chair"])
    assert issubclass(CatalogueError, ValueError) and issubclass(MeshError, ValueError)


def test_check_catalogue_reports_bad_and_goes_on(tmp_path):
    tiny(tmp_path / "a.obj")
    (tmp_path / "b.ply").write_bytes(b"\x00corrupted")
    write(tmp_path / "c.obj", CUBE_OBJ)
    write(tmp_path / "d.obj", obj_text([[0, 0, 0], [1, 0, 0], [0, "nan", 0]], [[0, 1, 2]]))
    entries = folder_catalogue(tmp_path)
    good, bad = check_catalogue(entries, progress=True)
    assert [e.key for e in good] == ["a", "c"]
    assert [e.key for e, _ in bad] == ["b", "d"]
    assert str(tmp_path / "b.ply") in bad[0][1] and "cannot read" in bad[0][1]
    assert str(tmp_path / "d.obj") in bad[1][1] and "NaN" in bad[1][1]
    assert isinstance(good[0], MeshEntry)
