"""``nbv.scan.Planner``, the planner kept warm in a robot's loop: its choices are the evaluator's
episode and the command's plan on the same views, it resumes from a saved folder to the same next
view, a depth image and its points are the same view, bad input is refused in one line; the
robot loop of docs/planning.md runs; the shelf bin example plans (when ../shared is there)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from capturegen import (
    CAMERA,
    EPS,
    START,
    capture_model,
    depth_image,
    episode_views,
    plan_captures,
    write_folder,
)

from nbv.assets.synthetic.catalogue import make_model
from nbv.config.schema import ConfigError
from nbv.geometry.camera import Intrinsics, opencv_to_blender
from nbv.plan.config import PlanSettings
from nbv.render.scene import SceneSettings, table_scene
from nbv.scan import NextView, Planner
from nbv.scan.capture import CaptureError
from nbv.scan.settings import ObjectSettings, ScanSettings, ViewspaceSettings

ROOT = Path(__file__).resolve().parents[1]
SHELF = ROOT.parent / "shared" / "captures" / "shelf_bin"
#: The dataset model's frame is the planners' own: its sphere.
UNIT = {"object": {"center": [0.0, 0.0, 0.0], "radius": 0.5}}
#: The table scene's camera (small: the tests' time) and candidates.
TABLE_CAMERA = Intrinsics.centred(320, 240, 238.0)
HEMISPHERE = {"kind": "hemisphere", "n": 40, "up": "z", "radius": 0.45}


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return capture_model(tmp_path_factory.mktemp("dataset"))


def dataset_planner(method: str, **kw) -> Planner:
    return Planner(method=method, camera=CAMERA, eps=EPS, points_per_view=0, n_views=10,
                   **UNIT, **kw)  # fmt: skip


def add_dataset_view(planner: Planner, model, v: int, kind: str = "points") -> None:
    """View ``v`` of the dataset model, as its stored points or their sparse depth image (a
    rendered view: its background is free)."""
    record = model.views["original"]
    points, pose = record.view_points(v).astype(np.float64), record.poses[v]
    if kind == "points":
        planner.add_view(points, pose, no_return="free")
    else:
        planner.add_view(depth_image(points, pose), pose, CAMERA, no_return="free")


@pytest.mark.parametrize("method", ["ig", "ig_learned", "vcnbv_map"])
@pytest.mark.parametrize("kind", ["points", "depth"])
def test_a_robot_loop_takes_the_views_of_the_evaluators_episode(model, method, kind):
    views = episode_views(model, method)
    planner = dataset_planner(method)
    add_dataset_view(planner, model, START, kind)
    for expected in views[1:]:
        step = planner.next_view()
        assert step.index == step.view == expected
        add_dataset_view(planner, model, step.index, kind)
    assert planner.result.visited == views[:-1]


def test_a_one_shot_plan_is_the_episodes(model):
    views = episode_views(model, "hull_sco")
    planner = dataset_planner("hull_sco")
    add_dataset_view(planner, model, START)
    plan = planner.plan()
    assert [p.index for p in plan] == views[1:]
    assert all(p.gain is not None for p in plan)
    # Asked again without a new view: the same decision (the planner draws its hull samples
    # once a decision).
    again = planner.next_view()
    assert (again.index, again.gain) == (plan[0].index, plan[0].gain)


@pytest.mark.parametrize(("method", "decisions"), [("ig", 4), ("ig_learned", 4), ("hull_sco", 1)])
def test_the_planner_decides_as_the_command_on_the_same_captures(
    model,
    tmp_path,
    method,
    decisions,
):
    """At every decision for the methods whose decision reads only the views; a one-shot
    planner's later plans draw their hull samples on from the first's generator (the command's
    fresh one draws anew): its first decision."""
    views = episode_views(model, method)
    planner = dataset_planner(method)
    for k, v in enumerate(views[:decisions]):
        add_dataset_view(planner, model, v)
        folder = write_folder(tmp_path / f"caps{k}", model, views[: k + 1], "ply")
        settings = PlanSettings(out_dir=tmp_path / "out", method=method, captures=folder,
                                object=ObjectSettings((0.0, 0.0, 0.0), 0.5), camera=CAMERA,
                                eps=EPS, points_per_view=0, n_views=10)  # fmt: skip
        command = plan_captures(settings)
        mine = planner.decide()
        assert mine.chosen == command.chosen and mine.visited == command.visited
        assert mine.gains == command.gains


def test_the_returned_pose_is_the_candidates_in_both_axes(model):
    planner = dataset_planner("ig")
    add_dataset_view(planner, model, START)
    step = planner.next_view()
    assert isinstance(step, NextView)
    # The dataset's frame is the planner's: the pose is the viewspace's view, distance 1.
    np.testing.assert_allclose(step.opencv, model.views["original"].poses[step.index], atol=1e-12)
    np.testing.assert_array_equal(step.blender, opencv_to_blender(step.opencv))
    np.testing.assert_array_equal(step.position, step.opencv[:3, 3])
    assert step.gain == planner.result.gains[0] > 0
    assert step.gain_unit == "information gain (unobserved voxels)"


def test_a_depth_image_and_its_points_are_the_same_view(model):
    """A depth view declared free and the same pixels as points declared free: the same points
    (to the float32 rounding of the stored ones), the same map (each block without a stored
    point is a miss either way) and the same choices."""
    by_points, by_depth = dataset_planner("ig"), dataset_planner("ig")
    add_dataset_view(by_points, model, START, "points")
    add_dataset_view(by_depth, model, START, "depth")
    a, b = by_points.next_view(), by_depth.next_view()
    assert (a.index, a.gain) == (b.index, b.gain)
    np.testing.assert_allclose(by_points.captures[0].points, by_depth.captures[0].points,
                               rtol=0, atol=1e-7)  # fmt: skip
    maps = [p._decider.policy.occupancy.log_odds for p in (by_points, by_depth)]
    np.testing.assert_array_equal(maps[0], maps[1])


@pytest.fixture(scope="module")
def cabinet():
    vertices, faces = make_model("cabinet", np.random.default_rng(1))
    return vertices[:, [0, 2, 1]] * np.array([1.0, -1.0, 1.0]), faces


def table_planner(**kw) -> Planner:
    return Planner(method="ig", viewspace=HEMISPHERE, n_views=8, **kw)


def render(cabinet, pose: np.ndarray, seed: int) -> np.ndarray:
    scene = table_scene(*cabinet, TABLE_CAMERA, SceneSettings(), seed, poses=pose[None])
    return scene.depth[0]


def test_save_and_load_resume_to_the_same_next_view(cabinet, tmp_path):
    first = table_scene(*cabinet, TABLE_CAMERA, SceneSettings(views=2), seed=0)
    planner = table_planner(candidates={"min_elevation": 10.0})
    for depth, pose in zip(first.depth, first.poses, strict=True):
        planner.add_view(depth, pose, TABLE_CAMERA, max_range=1.2)
    step = planner.next_view()
    planner.add_view(render(cabinet, step.opencv, 1), step.opencv, TABLE_CAMERA, max_range=1.2)
    planner.save(tmp_path / "scan")
    before = planner.next_view()
    resumed = Planner.load(tmp_path / "scan")
    after = resumed.next_view()
    assert (after.index, after.view, after.gain) == (before.index, before.view, before.gain)
    np.testing.assert_array_equal(after.opencv, before.opencv)
    # The frame was placed once, from the first two views: the resumed planner keeps it.
    np.testing.assert_array_equal(resumed.frame.center, planner.frame.center)
    assert resumed.result.candidate_limits == planner.result.candidate_limits
    # A second save replaces the first (the folder holds the views of the last one).
    planner.add_view(render(cabinet, before.opencv, 2), before.opencv, TABLE_CAMERA,
                     max_range=1.2)  # fmt: skip
    planner.save(tmp_path / "scan")
    spec = json.loads((tmp_path / "scan" / "views.json").read_text())
    assert len(spec["views"]) == 4 and spec["views"][0]["max_range"] == 1.2
    assert Planner.load(tmp_path / "scan").next_view().index == planner.next_view().index


def test_the_table_scene_is_planned_without_object_settings_and_reconstructed(cabinet):
    scene = table_scene(*cabinet, TABLE_CAMERA, SceneSettings(views=1), seed=0)
    planner = table_planner()
    planner.add_view(scene.depth[0], scene.poses[0], TABLE_CAMERA, max_range=1.2)
    step = planner.next_view()
    assert planner.result.object_source == "estimated"
    # The frame: within 10 % of the object's radius of its centre (the bar).
    assert np.linalg.norm(planner.frame.center - scene.center) < 0.1 * scene.radius
    # A camera above the table, 0.45 m from the object's centre, looking at it.
    assert step.position[2] > 0
    assert np.linalg.norm(step.position - planner.frame.center) == pytest.approx(0.45)
    fused = planner.reconstruct()
    assert fused.views == [0] and len(fused.triangles) > 0
    # The fused surface lies on the measured scene: near the view's points.
    from scipy.spatial import cKDTree

    distance, _ = cKDTree(planner.captures[0].points).query(fused.vertices)
    assert np.median(distance) < 2 * fused.voxel


def _bad_inputs():
    pose = np.eye(4)
    pose[:3, 3] = [0.0, 0.0, -1.0]
    depth = np.ones((48, 64))
    return [
        ((depth, pose), "without intrinsics, points (N, 3)"),
        ((np.zeros((0, 3)), pose), "without intrinsics, points (N, 3) with N >= 1"),
        ((np.full((5, 3), np.nan), pose), "NaN or infinite points"),
        ((depth, np.eye(3), CAMERA), "pose must be 4x4"),
        ((depth, 2 * pose, CAMERA), "pose's last row"),
        ((np.ones((10, 10)), pose, CAMERA), "depth is 10 x 10, the intrinsics say 64 x 48"),
        ((np.zeros((48, 64)), pose, CAMERA), "empty view: no pixel holds a depth"),
        ((depth, pose, CAMERA, "ros"), "axes='ros'; allowed: opencv, blender"),
        ((depth, pose, {"fx": 1}), "intrinsics must be an nbv.geometry.camera.Intrinsics"),
    ]


@pytest.mark.parametrize(("args", "message"), _bad_inputs())
def test_bad_views_are_refused_in_one_line_naming_the_view(args, message):
    planner = dataset_planner("ig")
    with pytest.raises(CaptureError) as err:
        planner.add_view(*args)
    assert str(err.value).startswith("add_view #0: ") and message in str(err.value)
    assert "\n" not in str(err.value) and planner.captures == []


def test_bad_settings_and_calls_are_refused_naming_the_key():
    with pytest.raises(ConfigError, match=r"viewspace.n=0: must be an integer >= 2"):
        Planner(viewspace={"kind": "sphere", "n": 0})
    with pytest.raises(ConfigError, match="colour: unknown key; allowed: method, checkpoint"):
        Planner(colour="red")
    with pytest.raises(ConfigError, match="method='oracle' reads the ground truth"):
        Planner(method="oracle")
    with pytest.raises(CaptureError, match="no views yet; add_view first"):
        Planner().next_view()
    with pytest.raises(CaptureError, match="no_return='none'; allowed: unknown, free"):
        Planner().add_view(np.zeros((3, 3)), np.eye(4), no_return="none")


def test_settings_and_overrides_build_the_same_planner():
    given = ScanSettings(method="ig_learned", viewspace=ViewspaceSettings(kind="sphere", n=60,
                                                                          up="z"))  # fmt: skip
    a = Planner(given)
    b = Planner(method="ig_learned", viewspace={"kind": "sphere", "n": 60, "up": "z"})
    assert a.settings == b.settings == given
    assert Planner(given, n_views=20).settings.n_views == 20
    # The command's settings give the planner their scan keys, nothing else.
    command = PlanSettings(out_dir=Path("plan"), method="ig_learned", page=False,
                           viewspace=ViewspaceSettings(kind="sphere", n=60, up="z"))  # fmt: skip
    assert type(Planner(command).settings) is ScanSettings and Planner(command).settings == given


def test_the_planner_api_runs_without_hydra():
    """A robot's process imports the planner, decides and saves without hydra or OmegaConf."""
    code = (
        "import sys, numpy as np\n"
        "from nbv.scan import Planner\n"
        "p = Planner(method='spread', viewspace={'kind': 'sphere', 'n': 20}, n_views=4)\n"
        "p.add_view(np.random.default_rng(0).normal(size=(200, 3)) * 0.05 + [0, 0, 1], np.eye(4))\n"
        "p.next_view()\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('hydra', 'omegaconf')]\n"
        "print(bad)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, check=True)  # fmt: skip
    assert out.stdout.strip() == "[]"
    import nbv.plan

    assert not hasattr(nbv.plan, "Planner")  # one home: nbv.scan


def snippet(title: str, lang: str = "python") -> str:
    """The Python block under ``title`` in docs/planning.md."""
    text = (ROOT / "docs" / "planning.md").read_text()
    section = text[text.index(title) :]
    return re.search(rf"```{lang}\n(.*?)```", section, re.S).group(1)


class FakeRobot:
    """A depth camera on an arm over the table scene: it renders the scene where it is moved."""

    def __init__(self, cabinet) -> None:
        self.cabinet = cabinet
        self.intrinsics = TABLE_CAMERA
        self.pose = table_scene(*cabinet, TABLE_CAMERA, SceneSettings(views=1), 0).poses[0]
        self.moves: list[np.ndarray] = []
        self.seed = 0

    def capture(self) -> tuple[np.ndarray, np.ndarray]:
        self.seed += 1
        return render(self.cabinet, self.pose, self.seed), self.pose

    def move_to(self, pose: np.ndarray) -> None:
        self.moves.append(pose)
        self.pose = pose


@pytest.mark.slow
def test_the_robot_loop_of_the_docs_runs(cabinet, tmp_path, monkeypatch):
    code = snippet("### A robot loop")
    assert len(code.strip().splitlines()) <= 16
    monkeypatch.chdir(tmp_path)
    robot = FakeRobot(cabinet)
    scope = {"robot": robot}
    exec(compile(code, "docs/planning.md", "exec"), scope)  # noqa: S102
    planner = scope["planner"]
    assert len(robot.moves) == 5 and len(planner.captures) == 6
    # Every move went to a different candidate, above the table.
    assert len({m.tobytes() for m in robot.moves}) == 5
    assert all(m[2, 3] > 0 for m in robot.moves)
    assert Planner.load(tmp_path / "scan").next_view().index == planner.next_view().index
    assert len(scope["mesh"].triangles) > 0


@pytest.mark.skipif(not SHELF.is_dir(), reason="../shared/captures/shelf_bin is not here")
@pytest.mark.slow
def test_the_shelf_bin_example_plans_from_three_views(tmp_path):
    command = snippet("## The shelf bin", "bash").strip()
    args = [a.strip("'") for a in command.split()[3:] if a != "\\"]
    args = [a.replace("../shared", str(ROOT.parent / "shared")) for a in args]
    args = [f"out_dir={tmp_path / 'out'}" if a.startswith("out_dir=") else a for a in args]
    proc = subprocess.run([sys.executable, "-m", "nbv.plan", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    record = json.loads((tmp_path / "out" / "plan.json").read_text())
    assert [Path(v["file"]).name for v in record["input"]["views"]] == [
        "frame-000000.png", "frame-000007.png", "frame-000014.png"]  # fmt: skip
    assert record["object"]["source"] == "region of interest"
    limits = record["candidate_limits"]
    assert limits["dropped"] > 0 and record["next_view"] < len(limits["kept_views"])
    # The chosen camera looks into the bin: within the cone about [-1, 0, 0.2] of its centre.
    position = np.array(record["views"][0]["position"])
    direction = position - np.array(record["object"]["center"])
    axis = np.array([-1.0, 0.0, 0.2]) / np.linalg.norm([-1.0, 0.0, 0.2])
    assert np.degrees(np.arccos(direction @ axis / np.linalg.norm(direction))) <= 40.0 + 1e-9
    assert (tmp_path / "out" / "reconstruction.ply").is_file()
    assert (tmp_path / "out" / "plan.png").is_file()
