"""Every mesh file a user brings is read, or refused in one line naming it: a corpus of malformed
and awkward files, generated here, through ``load_mesh`` (what ``nbv.plan mesh=``,
``nbv.dataset source=folder`` and ``nbv.eval mesh_dir=`` read with), the dataset's generator over
the whole corpus in-process, hypothesis's garbage and truncations, and the three commands run for
real on a few of them: exit 0, or one line with exit 2, never a traceback."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hydra import compose, initialize_config_dir
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nbv.assets.meshes import MESH_SUFFIXES, Mesh, MeshError, load_mesh, normalise
from nbv.plan.output import EMPTY_CLOUD_PLY, write_cloud

ROOT = Path(__file__).resolve().parents[1]

# Tetrahedron on the unit axes: 4 vertices, 4 faces, every face outward.
TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
TET_AREA = 1.5 + np.sqrt(3) / 2


def obj(vertices, faces, extra: str = "") -> bytes:
    rows = ["v " + " ".join(str(x) for x in v) for v in vertices]
    rows += ["f " + " ".join(str(i) for i in f) for f in faces]  # 1-based, as written
    return (extra + "\n".join(rows) + "\n").encode()


def ply_header(fmt: str, n_vertices: int, n_faces: int) -> bytes:
    lines = ["ply", f"format {fmt} 1.0", f"element vertex {n_vertices}", "property float x",
             "property float y", "property float z", f"element face {n_faces}",
             "property list uchar int vertex_indices", "end_header"]  # fmt: skip
    return ("\n".join(lines) + "\n").encode()


def ply_ascii(vertices, faces, n_vertices: int | None = None) -> bytes:
    """An ASCII PLY; ``n_vertices`` makes its header lie about the vertex count."""
    rows = [" ".join(str(x) for x in v) for v in vertices]
    rows += [" ".join(str(i) for i in [len(f), *f]) for f in faces]
    head = ply_header("ascii", n_vertices or len(vertices), len(faces))
    return head + ("\n".join(rows) + "\n").encode()


def ply_big_endian(vertices, faces, n_vertices: int | None = None) -> bytes:
    body = np.asarray(vertices, ">f4").tobytes()
    body += b"".join(bytes([len(f)]) + np.asarray(f, ">i4").tobytes() for f in faces)
    return ply_header("binary_big_endian", n_vertices or len(vertices), len(faces)) + body


def export(mesh: trimesh.Trimesh | trimesh.Scene, file_type: str) -> bytes:
    out = mesh.export(file_type=file_type)
    return out.encode() if isinstance(out, str) else out


def tet() -> trimesh.Trimesh:
    return trimesh.Trimesh(TET_V, TET_F, process=False)


def two_body_scene() -> trimesh.Scene:
    """The tetrahedron at the origin and a unit box moved to (5, 0, 0) and turned 90 degrees
    about z: 4 + 8 vertices, 4 + 12 faces."""
    scene = trimesh.Scene()
    scene.add_geometry(tet(), node_name="tet", geom_name="tet")
    move = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1])
    move[:3, 3] = [5.0, 0.0, 0.0]
    scene.add_geometry(trimesh.creation.box((1, 2, 3)), node_name="box", geom_name="box",
                       transform=move)  # fmt: skip
    return scene


def gltf_missing_bin() -> bytes:
    """A glTF whose buffers are separate .bin files that are not there."""
    files = two_body_scene().export(file_type="gltf")
    return files["model.gltf"]


def garbage(n: int, seed: int) -> bytes:
    return np.random.default_rng(seed).integers(0, 256, n, dtype=np.uint8).tobytes()


def truncated(data: bytes, keep: float) -> bytes:
    return data[: int(len(data) * keep)]


OK = "ok"
#: name -> (the file's bytes, what load_mesh gives: (OK, vertices, faces, area) or a refusal's
#: pattern, which follows "<path>: ").
CASES: dict[str, tuple[Callable[[], bytes], tuple]] = {
    # Garbage under each suffix.
    "garbage.obj": (lambda: garbage(300, 1), r"no faces \(0 vertices read\): .* OBJ reader"),
    "garbage.ply": (lambda: garbage(300, 2), r"cannot read mesh \("),
    "garbage.off": (lambda: garbage(300, 3), r"cannot read mesh \("),
    # A binary STL's size must match its header's triangle count.
    "garbage.stl": (lambda: garbage(300, 4), r"binary STL header promises \d+ triangles"),
    "garbage.glb": (lambda: garbage(300, 5), r"cannot read mesh \("),
    "garbage.gltf": (lambda: garbage(300, 6), r"cannot read mesh \("),
    # Empty files.
    "empty.obj": (lambda: b"", r"the file is empty \(0 bytes\)"),
    "empty.ply": (lambda: b"", r"the file is empty \(0 bytes\)"),
    "empty.stl": (lambda: b"", r"the file is empty \(0 bytes\)"),
    "empty.off": (lambda: b"", r"the file is empty \(0 bytes\)"),
    "empty.glb": (lambda: b"", r"the file is empty \(0 bytes\)"),
    # Cut short, and headers that promise more than the file holds.
    "cut_binary.stl": (
        lambda: truncated(export(tet(), "stl"), 0.7),
        r"header promises 4 triangles \(284 bytes\) but the file has 198 bytes",
    ),  # fmt: skip
    "cut_binary.ply": (lambda: truncated(export(tet(), "ply"), 0.8), r"cannot read mesh \("),
    "cut.glb": (lambda: truncated(export(tet(), "glb"), 0.6), r"cannot read mesh \("),
    # ASCII: trimesh reads the face rows as vertices too, and finds no faces.
    "lying_header.ply": (
        lambda: ply_ascii(TET_V, TET_F, n_vertices=40),
        r"mesh has no faces \(8 vertices read\)",
    ),  # fmt: skip
    "lying_header_binary.ply": (
        lambda: ply_big_endian(TET_V, TET_F, n_vertices=40),
        r"cannot read mesh \(",
    ),  # fmt: skip
    "lying_counts.off": (
        lambda: b"OFF\n9 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n",
        r"cannot read mesh \(",
    ),  # fmt: skip
    # Numbers that are not a surface.
    "nan.obj": (
        lambda: obj([["nan", 0, 0], [1, 0, 0], [0, 1, 0]], [[1, 2, 3]]),
        "1 of 3 vertices are NaN or infinite",
    ),  # fmt: skip
    "inf.ply": (
        lambda: ply_ascii([[0, 0, 0], [1, "inf", 0], [0, 1, 0]], [[0, 1, 2]]),
        "1 of 3 vertices are NaN or infinite",
    ),  # fmt: skip
    "index_out_of_range.obj": (lambda: obj(TET_V, [[1, 2, 9]]), r"cannot read mesh \("),
    "index_out_of_range.ply": (
        lambda: ply_ascii(TET_V, [[0, 1, 9]]),
        r"face indices must lie in \[0, 4\), got \[0, 9\]",
    ),  # fmt: skip
    "negative_index.ply": (
        lambda: ply_ascii(TET_V, [[0, 1, -5]]),
        r"face indices must lie in \[0, 4\), got \[-5, 1\]",
    ),  # fmt: skip
    "only_vertices.obj": (lambda: obj(TET_V, []), r"mesh has no faces \(0 vertices read\)"),
    "coincident.obj": (lambda: obj([[1, 1, 1]] * 3, [[1, 2, 3]]), "total surface area is zero"),
    "collinear.stl": (
        lambda: export(
            trimesh.Trimesh([[0, 0, 0], [1, 1, 1], [2, 2, 2]], [[0, 1, 2]], process=False), "stl"
        ),
        "total surface area is zero",
    ),  # fmt: skip
    "two_coords.obj": (lambda: b"v 0 0\nv 1 0\nv 0 1\nf 1 2 3\n", r"vertices must have shape"),
    # Awkward but valid: read, with the geometry the file holds.
    "empty_v_line.obj": (lambda: obj(TET_V, TET_F + 1, extra="v\n"), (OK, 4, 4, TET_AREA)),
    "negative_relative_index.obj": (
        lambda: obj(TET_V, [[-4, -2, -3], [-4, -3, -1]]),
        (OK, 4, 2, 1.0),
    ),
    "groups_materials_quads_ngons.obj": (
        lambda: (
            b"mtllib missing.mtl\no cube\ng bottom\nusemtl red\n"
            b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0\n"
            b"f 1 4 3 2\ng roof\nusemtl blue\nf 4 5 3\ng fan\nf 1 2 3 5 4\n"
        ),
        (OK, 9, 6, 2.5),
    ),  # fmt: skip
    "ascii.stl": (lambda: export(tet(), "stl_ascii"), (OK, 12, 4, TET_AREA)),
    # SolidWorks and others write binary STL with a header that starts "solid", like ASCII.
    "binary_solid_header.stl": (
        lambda: b"solid part" + export(tet(), "stl")[10:],
        (OK, 12, 4, TET_AREA),
    ),  # fmt: skip
    "binary.stl": (lambda: export(tet(), "stl"), (OK, 12, 4, TET_AREA)),
    "polygons.off": (
        lambda: b"OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 1.5 0\n4 0 1 2 3\n3 3 2 4\n",
        (OK, 5, 3, 1.25),
    ),  # fmt: skip
    "binary_big_endian.ply": (lambda: ply_big_endian(TET_V, TET_F), (OK, 4, 4, TET_AREA)),
    "two_bodies.glb": (lambda: export(two_body_scene(), "glb"), (OK, 12, 16, TET_AREA + 22.0)),
    "two_bodies.obj": (lambda: export(two_body_scene(), "obj"), (OK, 12, 16, TET_AREA + 22.0)),
    "missing_bin.gltf": (gltf_missing_bin, r"cannot read mesh \("),
    "flat_square.ply": (
        lambda: ply_ascii([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]]),
        (OK, 4, 2, 1.0),
    ),  # fmt: skip
    "one_triangle.obj": (
        lambda: obj([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[1, 2, 3]]),
        (OK, 3, 1, 0.5),
    ),
    "zero_area_faces.obj": (
        lambda: obj(TET_V, [*(TET_F + 1), [1, 1, 2], [2, 3, 3]]),
        (OK, 4, 6, TET_AREA),
    ),
    "huge_coordinates.obj": (lambda: obj(TET_V * 1e30, TET_F + 1), (OK, 4, 4, TET_AREA * 1e60)),
    "uppercase.OBJ": (lambda: obj(TET_V, TET_F + 1), (OK, 4, 4, TET_AREA)),
}


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    """The corpus's files in one folder, with a folder named like a mesh and a file of an
    unknown suffix (both passed over by a folder of meshes, refused by name by load_mesh)."""
    folder = tmp_path_factory.mktemp("corpus")
    for name, (make, _) in CASES.items():
        (folder / name).write_bytes(make())
    (folder / "folder.obj").mkdir()
    (folder / "cloud.xyz").write_text("0 0 0\n")
    return folder


def test_the_corpus_has_at_least_30_cases():
    assert len(CASES) >= 30
    assert sum(expected[0] == OK for _, expected in CASES.values()) == 15
    assert len(CASES) == 42


@pytest.mark.parametrize("name", list(CASES))
def test_each_file_is_read_or_refused_in_one_line_naming_it(corpus, name):
    path = corpus / name
    expected = CASES[name][1]
    if expected[0] == OK:
        mesh = load_mesh(path)
        assert (len(mesh.vertices), len(mesh.faces)) == expected[1:3]
        assert mesh.area == pytest.approx(expected[3], rel=1e-6)
        return
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    assert re.search(expected, message), message


def test_a_folder_named_like_a_mesh_and_an_unknown_suffix_are_refused_by_name(corpus):
    with pytest.raises(MeshError, match=r"folder\.obj: cannot read mesh: is a directory"):
        load_mesh(corpus / "folder.obj")
    allowed = ", ".join(MESH_SUFFIXES)
    with pytest.raises(MeshError, match=rf"cloud\.xyz: unsupported mesh file type '\.xyz'; "
                       rf"allowed: {allowed}"):  # fmt: skip
        load_mesh(corpus / "cloud.xyz")


def test_scenes_merge_their_bodies_with_the_transforms_applied(corpus):
    scene = two_body_scene()
    expected = np.concatenate([tet().vertices, scene.to_geometry().vertices[4:]])
    for name in ("two_bodies.glb", "two_bodies.obj"):
        mesh = load_mesh(corpus / name)
        np.testing.assert_allclose(np.sort(mesh.vertices, axis=0), np.sort(expected, axis=0),
                                   atol=1e-6)  # fmt: skip
    # The box (1 x 2 x 3) turned 90 degrees about z and moved to x = 5: x spans 4 .. 6.
    box = load_mesh(corpus / "two_bodies.glb").vertices
    box = box[box[:, 0] > 2]
    np.testing.assert_allclose(box.min(axis=0), [4.0, -0.5, -1.5], atol=1e-6)
    np.testing.assert_allclose(box.max(axis=0), [6.0, 0.5, 1.5], atol=1e-6)


def test_the_empty_v_line_and_huge_coordinates_keep_the_geometry(corpus):
    mesh = load_mesh(corpus / "empty_v_line.obj")
    np.testing.assert_array_equal(mesh.vertices, TET_V)
    np.testing.assert_array_equal(mesh.faces, TET_F)
    huge, _, scale = normalise(load_mesh(corpus / "huge_coordinates.obj"))
    small, _, small_scale = normalise(load_mesh(corpus / "uppercase.OBJ"))
    np.testing.assert_allclose(huge.vertices, small.vertices, atol=1e-12)
    assert scale == pytest.approx(small_scale * 1e-30)


def test_metres_and_millimetres_normalise_to_the_same_vertices(tmp_path):
    # A YCB-like object in metres (a 6 x 3 x 9 cm box off the origin, as YCB's STL files are)
    # and the same one in millimetres: the same normalised mesh, scales 1000 apart.
    box = trimesh.creation.box((0.06, 0.03, 0.09)).apply_translation([0.01, -0.02, 0.045])
    (tmp_path / "metres.stl").write_bytes(export(box, "stl"))
    (tmp_path / "millimetres.stl").write_bytes(export(box.copy().apply_scale(1000.0), "stl"))
    metres, center_m, scale_m = normalise(load_mesh(tmp_path / "metres.stl"))
    millimetres, center_mm, scale_mm = normalise(load_mesh(tmp_path / "millimetres.stl"))
    # STL stores float32: the two files agree to float32's relative precision.
    np.testing.assert_allclose(metres.vertices, millimetres.vertices, atol=1e-6)
    np.testing.assert_allclose(center_mm, 1000.0 * center_m, rtol=1e-6)
    assert scale_m == pytest.approx(1000.0 * scale_mm, rel=1e-6)
    radius = np.linalg.norm(metres.vertices, axis=1).max()
    assert radius == pytest.approx(0.5)


# ---------------------------------------------------------------------------------------------
# Generated: garbage bytes under every suffix, and valid files cut anywhere.


def read_or_refuse(path: Path) -> Mesh | MeshError:
    """load_mesh's answer: a mesh or a one-line MeshError naming the file (anything else, a
    traceback, fails the test)."""
    try:
        return load_mesh(path)
    except MeshError as err:
        assert "\n" not in str(err) and str(err).startswith(f"{path}: ")
        return err


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.binary(max_size=400), suffix=st.sampled_from(MESH_SUFFIXES))
def test_any_bytes_under_any_suffix_are_read_or_refused(tmp_path, data, suffix):
    path = tmp_path / f"any{suffix}"
    path.write_bytes(data)
    read_or_refuse(path)


VALID = {
    "stl": lambda: export(tet(), "stl"),
    "ply": lambda: export(tet(), "ply"),
    "glb": lambda: export(two_body_scene(), "glb"),
    "off": lambda: export(tet(), "off"),
    "obj": lambda: export(two_body_scene(), "obj"),
}


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(kind=st.sampled_from(sorted(VALID)), cut=st.floats(0.0, 1.0))
def test_valid_files_cut_anywhere_are_read_or_refused(tmp_path, kind, cut):
    path = tmp_path / f"cut.{kind}"
    path.write_bytes(truncated(VALID[kind](), cut))
    read_or_refuse(path)


# ---------------------------------------------------------------------------------------------
# What the commands do with them.


def test_an_empty_cloud_is_written_as_a_valid_ply_without_points(tmp_path):
    write_cloud(tmp_path / "cloud.ply", np.zeros((0, 3)))
    assert (tmp_path / "cloud.ply").read_bytes() == EMPTY_CLOUD_PLY
    assert trimesh.load(tmp_path / "cloud.ply").is_empty
    assert not list(tmp_path.glob(".*"))


def plan_in_process(mesh: Path, out: Path, *overrides: str) -> dict:
    """nbv.plan's own start and finish on the cheapest settings: plan.json's record."""
    from nbv.plan.__main__ import finish, start

    with initialize_config_dir(str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("plan", overrides=[f"mesh={mesh}", f"out_dir={out}", "camera=small",
                                         "method=random", "n_views=3", "picture=false",
                                         "page=false", "n_gt=1000", *overrides])  # fmt: skip
    finish(start(cfg))
    return json.loads((out / "plan.json").read_text())


@pytest.mark.parametrize(
    "name", ["flat_square.ply", "one_triangle.obj", "zero_area_faces.obj", "huge_coordinates.obj"]
)
@pytest.mark.slow
def test_degenerate_but_valid_meshes_are_planned(corpus, tmp_path, name):
    record = plan_in_process(corpus / name, tmp_path / "out")
    assert record["visited"] == [0] and len(record["chosen"]) == 2
    assert (tmp_path / "out" / "cloud.ply").exists()


def test_a_flat_mesh_seen_edge_on_plans_with_an_empty_cloud_and_says_so(corpus, tmp_path):
    # The triangle lies in z = 0 and start view 0 looks along it: the start view sees nothing.
    record = plan_in_process(corpus / "one_triangle.obj", tmp_path / "out")
    assert record["coverage"][0] == 0.0
    assert record["notes"][-1] == (
        "the visited views saw nothing of the object: cloud.ply holds no points"
    )
    assert (tmp_path / "out" / "cloud.ply").read_bytes() == EMPTY_CLOUD_PLY


@pytest.mark.slow
def test_the_dataset_generator_makes_every_readable_file_and_records_the_rest(corpus, tmp_path):
    from nbv.dataset.generator import generate
    from nbv.dataset.generator_settings import GeneratorSettings
    from nbv.geometry.camera import Intrinsics

    summary = generate(GeneratorSettings(
        source="folder", root=str(corpus), out_dir=tmp_path / "out", n_gt=500,
        viewspaces={"original": "original"}, intrinsics=Intrinsics.centred(64, 48),
        points_per_view=50, progress=False,
    ))  # fmt: skip
    reasons = [reason for _, reason in summary.failures]
    assert all("\n" not in reason for reason in reasons)
    # Each refused file is named by exactly one failure, which is load_mesh's one line.
    refused = sorted(n for n, (_, e) in CASES.items() if e[0] != OK)
    assert sorted(n for n in CASES for r in reasons if r.startswith(f"{corpus / n}: ")) == refused
    assert summary.produced == sum(e[0] == OK for _, e in CASES.values())


# ---------------------------------------------------------------------------------------------
# The commands themselves, on a few files each.


def run_cli(module: str, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run([sys.executable, "-m", module, *args], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env=env)  # fmt: skip


def assert_refused(proc: subprocess.CompletedProcess, prefix: str) -> None:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith(prefix), proc.stderr


@pytest.mark.parametrize("name", ["garbage.glb", "missing_bin.gltf"])
@pytest.mark.slow
def test_nbv_plan_refuses_a_bad_file_in_one_line_and_leaves_nothing(corpus, tmp_path, name):
    proc = run_cli("nbv.plan", f"mesh={corpus / name}", "camera=small", "out_dir=out",
                   cwd=tmp_path)  # fmt: skip
    assert_refused(proc, f"nbv.plan: {corpus / name}: cannot read mesh (")
    assert not list(tmp_path.iterdir())


@pytest.mark.slow
def test_nbv_plan_refuses_a_mesh_no_view_shows(tmp_path):
    # Two unit triangles 10,000 apart: once the whole fits the views, each is below a pixel.
    far = tmp_path / "far.obj"
    far.write_bytes(obj([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1e4, 1e4, 1e4], [10001, 1e4, 1e4],
                         [1e4, 10001, 1e4]], [[1, 2, 3], [4, 5, 6]]))  # fmt: skip
    proc = run_cli("nbv.plan", f"mesh={far}", "camera=small", "out_dir=out", cwd=tmp_path)
    assert_refused(proc, f"nbv.plan: {far}: empty render: no view shows anything of the object")
    # It had begun (its log says it ray cast the views): the run folder keeps the log, with the
    # refusal as its last line, and nothing else of the plan's (nbv.config.cli.refuse).
    files = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert files == [".hydra", "plan.log"]
    log = (tmp_path / "out" / "plan.log").read_text().strip().splitlines()
    assert log[-1].endswith("nothing to plan from")


@pytest.mark.slow
def test_nbv_plan_writes_a_valid_empty_cloud_for_a_triangle_seen_edge_on(corpus, tmp_path):
    proc = run_cli("nbv.plan", f"mesh={corpus / 'one_triangle.obj'}", "camera=small",
                   "method=random", "page=false", "out_dir=out", cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "cloud.ply holds no points" in proc.stderr and "Traceback" not in proc.stderr
    assert (tmp_path / "out" / "cloud.ply").read_bytes() == EMPTY_CLOUD_PLY
    assert (tmp_path / "out" / "plan.png").read_bytes()[:4] == b"\x89PNG"
    assert json.loads((tmp_path / "out" / "plan.json").read_text())["coverage"][0] == 0.0


@pytest.fixture(scope="module")
def mixed(corpus, tmp_path_factory) -> Path:
    """A folder of one good mesh and three bad ones, from the corpus."""
    folder = tmp_path_factory.mktemp("mixed")
    for name in ("binary.stl", "garbage.glb", "nan.obj", "missing_bin.gltf"):
        (folder / name).write_bytes((corpus / name).read_bytes())
    return folder


@pytest.mark.slow
def test_nbv_dataset_makes_the_good_file_and_names_each_bad_one_on_a_line(mixed, tmp_path):
    proc = run_cli("nbv.dataset", "source=folder", f"root={mixed}", "camera=small",
                   "n_gt=500", "viewspaces=[original]", "out_dir=data", "progress=false",
                   cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "1/4 models" in proc.stderr
    for key, name in (("garbage", "garbage.glb"), ("nan", "nan.obj"),
                      ("missing_bin", "missing_bin.gltf")):  # fmt: skip
        line = next(
            li for li in proc.stderr.splitlines() if li.strip().startswith(f"failed {key}:")
        )
        assert f"{mixed / name}: " in line


@pytest.mark.slow
def test_nbv_eval_prepares_the_good_file_and_refuses_a_folder_of_bad_ones(mixed, tmp_path):
    cheap = ["dataset=meshes", "methods=[random]", "viewspace=[original]", "start_views=[0]",
             "disturb.checks=[]", "random_repeats=1", "n_views=3", "plots=false",
             "progress=false", "camera@prepare.camera=small", "prepare.n_gt=500",
             "out_root=out", f"prepare.dir={tmp_path / 'prepared'}"]  # fmt: skip
    proc = run_cli("nbv.eval", f"mesh_dir={mixed}", *cheap, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    report = next((tmp_path / "out").glob("*/report.md")).read_text()
    assert "not produced: garbage" in report and "missing_bin" in report
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "garbage.glb").write_bytes((mixed / "garbage.glb").read_bytes())
    proc = run_cli("nbv.eval", f"mesh_dir={bad}", *cheap, cwd=tmp_path)
    assert_refused(proc, f"nbv.eval: mesh_dir='{bad}': no mesh could be prepared (garbage: {bad}")


@pytest.mark.slow
def test_nbv_dataset_refuses_a_folder_of_bad_files_in_one_line(mixed, tmp_path):
    bad = tmp_path / "bad"
    bad.mkdir()
    for name in ("garbage.glb", "nan.obj"):
        (bad / name).write_bytes((mixed / name).read_bytes())
    proc = run_cli("nbv.dataset", "source=folder", f"root={bad}", "camera=small", "n_gt=500",
                   "viewspaces=[original]", "out_dir=data", "progress=false",
                   cwd=tmp_path)  # fmt: skip
    assert_refused(
        proc,
        f"nbv.dataset: shard-00000-of-00001.h5: none of its 2 models could be made (garbage: {bad}",
    )
