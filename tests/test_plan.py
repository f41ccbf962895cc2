"""``python -m nbv.plan``: the config, a mesh episode through the real command (plan.json's poses
and coverage, the files), captures saved from it planned again, and refusals that name the key or
file and leave nothing behind."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
import trimesh
from hydra import compose, initialize_config_dir

from nbv.config.schema import ConfigError
from nbv.geometry.camera import opencv_to_blender
from nbv.geometry.viewspace import original_viewspace
from nbv.geometry.viewspace_generators import rings
from nbv.plan.config import ENTRY, PlanSettings
from nbv.policies.registry import METHODS
from nbv.scan.frame import ObjectFrame, candidate_poses, object_frame
from nbv.scan.placement import match_views
from nbv.scan.settings import PLANNABLE, ObjectSettings, ViewspaceSettings

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"
#: A box of 0.6 x 0.3 x 0.9 centred at CENTER: its radius is half its diagonal.
CENTER = np.array([2.0, 1.0, -3.0])
RADIUS = 0.5 * np.sqrt(0.6**2 + 0.3**2 + 0.9**2)


@pytest.fixture(scope="module")
def box(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("mesh") / "box.obj"
    trimesh.creation.box((0.6, 0.3, 0.9)).apply_translation(CENTER).export(path)
    return path


def run_plan(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """Run ``python -m nbv.plan args`` in ``cwd`` (hydra's one-line refusals: no full errors)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run(
        [sys.executable, "-m", "nbv.plan", *args], cwd=cwd, capture_output=True, text=True,
        timeout=600, env=env,
    )  # fmt: skip


def composed(overrides: list[str]):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        return compose("plan", overrides=overrides)


@pytest.mark.parametrize("camera", ["default", "small"])
def test_the_config_composes_into_settings(box, tmp_path, camera):
    cfg = composed([f"mesh={box}", f"out_dir={tmp_path}", f"camera={camera}"])
    settings = ENTRY.build(cfg)
    assert settings.mesh == box and settings.method == "ig" and settings.n_views == 10
    assert settings.viewspace.kind == "original" and settings.viewspace.radius is None
    assert settings.camera.width == (640 if camera == "default" else 64)


def test_methods_that_read_the_ground_truth_are_refused_with_the_allowed_list(box, tmp_path):
    truth = [name for name, m in METHODS.items() if m.ground_truth]
    assert truth and set(PLANNABLE) == set(METHODS) - set(truth)
    with pytest.raises(ConfigError) as err:
        PlanSettings(out_dir=tmp_path, method=truth[0], mesh=box)
    assert f"method={truth[0]!r} reads the ground truth; allowed: {', '.join(PLANNABLE)}" == str(
        err.value
    )


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ([], "give exactly one input: mesh=<mesh file>"),
        (["mesh=nowhere.obj"], "mesh='nowhere.obj': no such file or folder"),
        (["mesh=BOX", "start_view=40"], r"start_view=\[40\]: the viewspace 'original' has 33"),
        (["mesh=BOX", "viewspace.kind=sphere", "viewspace.n=0"], "viewspace.n=0: must be"),
        (["mesh=BOX", "viewspace.radius=-1"], "viewspace.radius=-1.0: must be null or a positive"),
        (
            ["mesh=BOX", "viewspace.kind=rings", "viewspace.per_ring=[2,x]"],
            r"viewspace.per_ring=\(2, 'x'\): must be an integer or a list of them",
        ),
        (["mesh=BOX", "match_degrees=90"], r"match_degrees=90.0: must be degrees in \[0, 90\)"),
        (["mesh=BOX", "n_views=1"], "n_views=1: must be an integer >= 2"),
        (["mesh=BOX", "object.center=[1,2]"], r"object.center=\[1.0, 2.0\]: must be"),
        (["mesh=BOX", "save_captures=11"], "save_captures=11: the episode has n_views=10"),
        (["mesh=BOX", "setcover.n_samp=0"], "setcover.n_samp=0: must be an integer >= 1"),
        (["captures=BOX", "save_captures=2"], "save_captures needs mesh="),
    ],
)
@pytest.mark.slow
def test_bad_settings_name_the_key(box, tmp_path, overrides, message):
    cfg = composed([o.replace("BOX", str(box)) for o in overrides] + [f"out_dir={tmp_path}"])
    with pytest.raises(ConfigError, match=message):
        ENTRY.build(cfg)


def test_cameras_inside_the_object_sphere_are_refused_given_or_found(box, tmp_path):
    inside = ViewspaceSettings(radius=0.2)
    given = PlanSettings(out_dir=tmp_path, mesh=box, viewspace=inside,
                         object=ObjectSettings(radius=0.5))  # fmt: skip
    with pytest.raises(ValueError) as err:
        object_frame(given, CENTER, RADIUS)
    assert str(err.value) == (
        "viewspace.radius=0.2: the cameras would sit inside the object's sphere (object.radius=0.5)"
    )
    found = PlanSettings(out_dir=tmp_path, mesh=box, viewspace=inside)
    with pytest.raises(ValueError, match=r"inside the object's sphere \(radius 0.5612\)"):
        object_frame(found, CENTER, RADIUS)
    outside = PlanSettings(out_dir=tmp_path, mesh=box, viewspace=ViewspaceSettings(radius=0.6))
    assert object_frame(outside, CENTER, RADIUS).radius == RADIUS


def test_a_network_method_defaults_to_its_paths_checkpoint(box, tmp_path):
    cfg = composed([f"mesh={box}", f"out_dir={tmp_path}", "method=pcnbv",
                    f"paths.checkpoints.pcnbv={tmp_path / 'best.pt'}"])  # fmt: skip
    assert ENTRY.build(cfg).checkpoint == tmp_path / "best.pt"
    given = composed([f"mesh={box}", f"out_dir={tmp_path}", "method=pcnbv", "checkpoint=w.pt"])
    assert ENTRY.build(given).checkpoint == Path("w.pt")
    assert ENTRY.build(composed([f"mesh={box}", f"out_dir={tmp_path}"])).checkpoint is None


def test_a_planner_led_by_a_network_defaults_to_the_leading_networks_checkpoint(box, tmp_path):
    cfg = composed([f"mesh={box}", f"out_dir={tmp_path}", "method=vig_hull_sco",
                    f"paths.checkpoints.pcnbv_sph_vig={tmp_path / 'vig.pt'}"])  # fmt: skip
    assert ENTRY.build(cfg).checkpoint == tmp_path / "vig.pt"


def test_candidates_sit_around_the_object_at_twice_its_radius_or_the_given_distance():
    frame = ObjectFrame(CENTER, RADIUS, "y")
    normalised = candidate_poses(original_viewspace(), frame, None)
    np.testing.assert_allclose(normalised[:, :3, 3], original_viewspace(), atol=0)
    world = frame.poses_to_world(normalised)
    np.testing.assert_allclose(world[:, :3, 3], CENTER + 2 * RADIUS * original_viewspace(),
                               atol=1e-12)  # fmt: skip
    # Each camera looks at the centre: its optical axis (+z) points there.
    to_centre = CENTER - world[:, :3, 3]
    to_centre /= np.linalg.norm(to_centre, axis=1)[:, None]
    np.testing.assert_allclose(world[:, :3, 2], to_centre, atol=1e-12)
    far = frame.poses_to_world(candidate_poses(original_viewspace(), frame, 3.0))
    np.testing.assert_allclose(np.linalg.norm(far[:, :3, 3] - CENTER, axis=1), 3.0, atol=1e-12)
    # Z up: the image's up (-y of the camera) is +z for the equator's views.
    zup = ObjectFrame(CENTER, RADIUS, "z")
    dirs = rings([0], 4, up="z")
    poses = zup.poses_to_world(candidate_poses(dirs, zup, None))
    np.testing.assert_allclose(-poses[:, :3, 1], np.tile([0, 0, 1.0], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(poses[:, :3, 3], CENTER + 2 * RADIUS * dirs, atol=1e-12)
    np.testing.assert_allclose(zup.poses_to_normalised(poses), candidate_poses(dirs, zup, None),
                               atol=1e-12)  # fmt: skip


def test_captures_match_the_nearest_free_view_within_the_tolerance():
    candidates = original_viewspace()
    tilted = candidates[[5, 5, 20]] + [[0, 0.01, 0], [0, 0, 0], [0.3, 0, 0]]
    # The first is 0.5 degrees off view 5; the second is view 5 again (taken: its next-nearest
    # is 45 degrees off, so an extra); the third is far from any view.
    assert match_views(tilted, candidates, 2.0) == [5, None, None]
    assert match_views(candidates[[3, 7]], candidates, 0.0) == [3, 7]


@pytest.fixture(scope="module")
def episode(box, tmp_path_factory):
    """A mesh episode through the real command, small camera, all points kept, 3 captures
    saved."""
    cwd = tmp_path_factory.mktemp("run")
    proc = run_plan(f"mesh={box}", "camera=small", "method=ig", "start_view=3",
                    "points_per_view=0", "save_captures=3", "out_dir=run", cwd=cwd)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return cwd / "run", proc


@pytest.mark.slow
def test_a_mesh_episode_writes_the_plan_the_cloud_the_picture_and_the_page(episode):
    out, proc = episode
    record = json.loads((out / "plan.json").read_text())
    assert proc.stdout.startswith(f"next view {record['next_view']}; plan {record['chosen']}")
    assert record["visited"] == [3] and len(record["chosen"]) == 9
    assert len(set(record["chosen"]) | {3}) == 10 and record["next_view"] == record["chosen"][0]
    np.testing.assert_allclose(record["object"]["center"], CENTER, atol=1e-12)
    assert record["object"]["radius"] == pytest.approx(RADIUS)
    assert record["camera_distance"] == pytest.approx(2 * RADIUS)
    for entry in record["views"]:
        pose = np.array(entry["opencv"])
        np.testing.assert_allclose(entry["blender"], opencv_to_blender(pose), atol=0)
        np.testing.assert_allclose(pose[:3, 3], entry["position"], atol=0)
        expected = CENTER + 2 * RADIUS * original_viewspace()[entry["view"]]
        np.testing.assert_allclose(pose[:3, 3], expected, atol=1e-12)
    coverage = np.array(record["coverage"])
    assert len(coverage) == 10 and np.all(np.diff(coverage) >= 0) and 0 < coverage[0] < 1
    assert record["auc"] == pytest.approx((coverage[:-1].sum() + 0.5 * coverage[-1]) / 10)
    assert len(record["timings"]["decisions"]) == 9
    assert len(record["candidates"]) == 33
    cloud = np.asarray(o3d.io.read_point_cloud(str(out / "cloud.ply")).points)
    assert len(cloud) > 0
    # The cloud is in the mesh's frame: on the box's surface.
    lo, hi = CENTER - [0.3, 0.15, 0.45], CENTER + [0.3, 0.15, 0.45]
    assert np.all(cloud >= lo - 1e-6) and np.all(cloud <= hi + 1e-6)
    on_face = np.isclose(cloud, lo, atol=1e-6) | np.isclose(cloud, hi, atol=1e-6)
    assert on_face.any(axis=1).all()
    assert (out / "plan.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"plotly" in (out / "plan.html").read_bytes()[:2_000_000]
    assert not list(out.glob("*.tmp*"))


@pytest.mark.slow
def test_captures_saved_from_the_episode_plan_the_episode_next_view(episode):
    out, _ = episode
    record = json.loads((out / "plan.json").read_text())
    spec = json.loads((out / "captures" / "views.json").read_text())
    assert [v["file"] for v in spec["views"]] == ["view_00.npy", "view_01.npy", "view_02.npy"]
    np.testing.assert_allclose(spec["object"]["center"], CENTER, atol=1e-12)
    proc = run_plan(f"captures={out / 'captures'}", "camera=small", "method=ig",
                    "points_per_view=0", "out_dir=next", cwd=out.parent)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    again = json.loads((out.parent / "next" / "plan.json").read_text())
    assert again["visited"] == [3] + record["chosen"][:2]
    assert again["chosen"] == [record["chosen"][2]]
    assert again["predicted_gains"][0] > 0 and again["gain_unit"].startswith("information gain")


@pytest.mark.slow
def test_a_bad_capture_folder_is_refused_in_one_line_and_leaves_nothing(episode, tmp_path):
    out, _ = episode
    folder = tmp_path / "caps"
    folder.mkdir()
    spec = json.loads((out / "captures" / "views.json").read_text())
    spec["views"][1]["pose"][0][0] *= 1.5
    (folder / "views.json").write_text(json.dumps(spec))
    for name in ("view_00.npy", "view_01.npy", "view_02.npy"):
        (folder / name).write_bytes((out / "captures" / name).read_bytes())
    proc = run_plan(f"captures={folder}", "camera=small", "out_dir=refused", cwd=tmp_path)
    assert proc.returncode == 2
    assert (
        proc.stderr.strip()
        .splitlines()[-1]
        .startswith(f"nbv.plan: {folder / 'view_01.npy'}: pose is not rigid")
    )
    assert not (tmp_path / "refused").exists()


@pytest.mark.parametrize("method", ["hull_sco", "ig"])
def test_the_bench_decision_is_the_plan_from_the_same_capture_file(box, tmp_path, method):
    from capturegen import plan_captures

    from nbv.assets.meshes import load_mesh, normalise
    from nbv.bench.plan import decide
    from nbv.geometry.camera import Intrinsics, backproject, viewspace_poses
    from nbv.render.raycast import render_raycast
    from nbv.setcover.settings import SetCoverSettings

    camera = Intrinsics.centred(160, 120, 119.0)
    mesh, _, _ = normalise(load_mesh(box))
    poses = viewspace_poses(original_viewspace())
    depth = render_raycast(mesh.vertices, mesh.faces, poses[[5]], camera)[0]
    points = backproject(depth, camera, poses[5])
    bench = decide(method, 5, points, poses, camera, SetCoverSettings())
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    (tmp_path / "caps").mkdir()
    assert o3d.io.write_point_cloud(str(tmp_path / "caps" / "v.ply"), cloud)
    # A rendered view, as the bench's: its background is empty space.
    spec = {"no_return": "free", "views": [{"file": "v.ply", "pose": poses[5].tolist()}]}
    (tmp_path / "caps" / "views.json").write_text(json.dumps(spec))
    settings = PlanSettings(out_dir=tmp_path / "out", method=method, captures=tmp_path / "caps",
                            object=ObjectSettings((0.0, 0.0, 0.0), 0.5), camera=camera,
                            points_per_view=0)  # fmt: skip
    planned = plan_captures(settings).chosen
    assert planned == (bench if isinstance(bench, list) else [bench])


def test_the_example_mesh_is_the_first_synthetic_model_of_its_category(tmp_path):
    from nbv.assets.meshes import load_mesh
    from nbv.assets.synthetic import build, catalogue
    from nbv.plan.example import write_example

    path = write_example(tmp_path / "chair.obj", "chair", seed=0)
    entry = next(e for e in catalogue() if e.category == "chair")
    vertices, faces = build(entry, 0)
    mesh = load_mesh(path)
    np.testing.assert_allclose(mesh.vertices, vertices, atol=1e-6)  # OBJ text, 8 decimals
    np.testing.assert_array_equal(mesh.faces, faces)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chair.obj"]
    with pytest.raises(ValueError, match="category='chairs': must be one of airplane, bed"):
        write_example(tmp_path / "x.obj", "chairs")
    assert not (tmp_path / "x.obj").exists()


@pytest.mark.slow
def test_the_example_command_writes_the_mesh_or_refuses_in_one_line(tmp_path):
    def example(*args: str) -> subprocess.CompletedProcess:
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        env.pop("HYDRA_FULL_ERROR", None)
        return subprocess.run(
            [sys.executable, "-m", "nbv.plan.example", *args, "hydra.run.dir=run"],
            cwd=tmp_path, capture_output=True, text=True, timeout=300, env=env,
        )  # fmt: skip

    for args, line in [
        (["out=chair.txt"], "out='chair.txt': must be a mesh file ending in .obj, .ply, .stl"),
        (["out=x.obj", "category=chairs"], "category='chairs': must be one of airplane, bed"),
        ([], "out: no value; the config must give one"),
    ]:
        proc = example(*args)
        assert proc.returncode == 2
        assert proc.stderr.strip().splitlines()[-1].startswith(f"nbv.plan.example: {line}")
        assert not list(tmp_path.iterdir())
    proc = example("out=mesh/bed.ply", "category=bed", "seed=1")
    assert proc.returncode == 0, proc.stderr
    assert len(trimesh.load(tmp_path / "mesh" / "bed.ply").faces) > 0
