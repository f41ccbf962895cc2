"""A plan from capture files equals the evaluator's episode on the same views of a dataset model,
also for a translated and scaled copy of the captures; bad capture folders are refused naming
the file, with nothing written."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
from capturegen import CAMERA, EPS, START, capture_model, episode_views, plan_captures, write_folder

from nbv.geometry.camera import Intrinsics, opencv_to_blender
from nbv.infogain.gain import view_gains
from nbv.infogain.settings import InfoGainSettings
from nbv.plan.config import PlanSettings
from nbv.policies.episode import EpisodeState
from nbv.policies.method import MethodContext
from nbv.policies.registry import METHODS
from nbv.scan.capture import CaptureError, check_rigid
from nbv.scan.captures import read_captures, write_captures
from nbv.scan.method import policy_rng
from nbv.scan.object_estimate import EstimateSettings, estimate_object
from nbv.scan.settings import ObjectSettings, ViewspaceSettings
from nbv.scan.shipped import with_shipped
from nbv.setcover.settings import SetCoverSettings


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return capture_model(tmp_path_factory.mktemp("dataset"))


#: A similarity of the world: captures scaled by SCALE and moved by SHIFT.
SCALE, SHIFT = 3.0, np.array([1.5, -2.0, 0.7])


def plan(folder: Path, method: str, center=(0.0, 0.0, 0.0), radius=0.5):
    settings = PlanSettings(
        out_dir=folder.parent / "out", method=method, captures=folder,
        object=ObjectSettings(center, radius), camera=CAMERA, eps=EPS, points_per_view=0,
        n_views=10,
    )  # fmt: skip
    return plan_captures(settings)


@pytest.mark.parametrize("kind", ["ply", "npy"])
def test_one_shot_plan_from_captures_is_the_episode_of_the_dataset(model, tmp_path, kind):
    views = episode_views(model, "hull_sco")
    folder = write_folder(tmp_path / "caps", model, views[:1], kind)
    result = plan(folder, "hull_sco")
    assert result.visited == [START]
    assert result.chosen == views[1:]
    assert result.gains is not None and len(result.gains) == 9


@pytest.mark.parametrize("kind", ["ply", "npy"])
@pytest.mark.parametrize("captured", [1, 4])
def test_next_view_from_captures_is_the_episode_of_the_dataset(model, tmp_path, kind, captured):
    views = episode_views(model, "ig")
    folder = write_folder(tmp_path / "caps", model, views[:captured], kind)
    result = plan(folder, "ig")
    assert result.visited == views[:captured]
    assert result.chosen == [views[captured]]
    # The planner's predicted gain is that of its decision: the best unvisited view's on its map.
    ctx = with_shipped(MethodContext({}, SetCoverSettings(), CAMERA, EPS, 10, InfoGainSettings()))
    policy = METHODS["ig"].build(ctx, policy_rng(0, "ig"))
    state = EpisodeState(model.captured("original"), np.isin(np.arange(33), views[:captured]),
                         list(views[:captured]))  # fmt: skip
    choice = policy(state)
    poses = model.views["original"].poses
    gains = view_gains(policy.occupancy, policy.candidate_voxels(poses), "unobserved")
    assert policy.last_gains == [gains[choice]] == [max(gains[~state.view_state])]
    assert result.gains == pytest.approx(policy.last_gains)
    assert result.gain_unit == "information gain (unobserved voxels)"


@pytest.mark.parametrize("kind", ["ply", "npy"])
@pytest.mark.parametrize("method", ["hull_sco", "ig", "spread", "vcnbv_map"])
def test_a_translated_and_scaled_copy_of_the_captures_gives_the_same_plan(
    model, tmp_path, method, kind
):
    views = episode_views(model, method)
    plain = plan(write_folder(tmp_path / "a", model, views[:2], kind), method)
    moved = write_folder(tmp_path / "b", model, views[:2], kind, SCALE, SHIFT)
    result = plan(moved, method, center=tuple(SHIFT), radius=0.5 * SCALE)
    assert result.chosen == plain.chosen
    if method != "hull_sco":  # a replanning method's next view is the episode's third view
        assert result.chosen == [views[2]]
    # The poses are the user's world: the chosen camera sits at SCALE times distance 1.
    world = result.frame.poses_to_world(result.views.poses)
    assert np.linalg.norm(world[result.chosen[0], :3, 3] - SHIFT) == pytest.approx(SCALE)


def test_blender_axes_give_the_same_plan(model, tmp_path):
    views = episode_views(model, "ig")
    folder = write_folder(tmp_path / "caps", model, views[:2], "ply")
    spec = json.loads((folder / "views.json").read_text())
    spec["axes"] = "blender"
    for entry in spec["views"]:
        entry["pose"] = opencv_to_blender(np.array(entry["pose"])).tolist()
    (folder / "views.json").write_text(json.dumps(spec))
    assert plan(folder, "ig").chosen == [views[2]]


def test_rigid_pose_check():
    good = np.eye(4)
    good[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    assert np.array_equal(check_rigid(good.tolist(), "p"), good)
    scaled = good.copy()
    scaled[:3, :3] *= 1.01
    with pytest.raises(CaptureError, match=r"p: pose is not rigid: R\^T R differs"):
        check_rigid(scaled, "p")
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(CaptureError, match=r"det R = -1"):
        check_rigid(mirror, "p")
    sheared = np.eye(4)
    sheared[0, 1] = 0.01
    with pytest.raises(CaptureError, match="not rigid"):
        check_rigid(sheared, "p")
    bottom = np.eye(4)
    bottom[3, 0] = 1.0
    with pytest.raises(CaptureError, match="last row"):
        check_rigid(bottom, "p")
    with pytest.raises(CaptureError, match="4x4"):
        check_rigid(np.eye(3), "p")


def _edit(folder: Path, change) -> None:
    spec = json.loads((folder / "views.json").read_text())
    change(spec)
    (folder / "views.json").write_text(json.dumps(spec))


def _bad_cases(model, tmp_path):
    """(name, folder builder, expected message fragment)."""
    record = model.views["original"]

    def nan_points(folder):
        pts = record.view_points(START).astype(np.float64)
        pts[5] = np.nan
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
        o3d.io.write_point_cloud(str(folder / "view_0.ply"), cloud)

    def not_rigid(folder):
        _edit(folder, lambda s: s["views"][0]["pose"][0].__setitem__(0, 2.0))

    def no_intrinsics(folder):
        _edit(folder, lambda s: s.pop("intrinsics"))

    def millimetres(folder):
        depth = np.load(folder / "view_0.npy")
        np.save(folder / "view_0.npy", np.where(np.isfinite(depth), depth * 1000, 0).astype(
            np.uint16))  # fmt: skip

    def empty(folder):
        np.save(folder / "view_0.npy", np.full((CAMERA.height, CAMERA.width), np.inf))

    def looks_away(folder):
        def turn(spec):
            pose = np.array(spec["views"][0]["pose"])
            pose[:3, :3] = pose[:3, :3] @ np.diag([-1.0, 1.0, -1.0])  # a half turn about y
            spec["views"][0]["pose"] = pose.tolist()

        _edit(folder, turn)

    return [
        ("ply", nan_points, "view_0.ply: 1 of 200 points are NaN or infinite"),
        ("ply", not_rigid, "view_0.ply: pose is not rigid"),
        ("npy", no_intrinsics, "view_0.npy: a depth image needs intrinsics"),
        ("npy", millimetres, "view_0.npy: integer depth (e.g. millimetres) without depth_scale"),
        ("npy", empty, "view_0.npy: empty view"),
        ("npy", looks_away, "view_0.npy: the camera does not look at the object"),
    ]


@pytest.mark.parametrize("case", range(6))
def test_bad_captures_are_refused_naming_the_file_and_nothing_is_written(model, tmp_path, case):
    kind, damage, message = _bad_cases(model, tmp_path)[case]
    folder = write_folder(tmp_path / "caps", model, [START], kind)
    damage(folder)
    with pytest.raises(CaptureError, match=message.replace("(", r"\(").replace(")", r"\)")):
        plan(folder, "ig")
    assert not (tmp_path / "out").exists()


def test_an_object_in_free_space_is_estimated_from_its_own_points(model, tmp_path):
    """The dataset's scene has no support or wall: no plane is removed (a face of the object is
    seen from outside by a camera), and the sphere is the bounding box of the object's cluster,
    a subset of the captured points."""
    folder = write_folder(tmp_path / "caps", model, [START, 17], "ply")
    captures, given = read_captures(folder)
    assert given is None
    settings = PlanSettings(out_dir=tmp_path / "out", method="spread", captures=folder,
                            camera=CAMERA)  # fmt: skip
    result = plan_captures(settings)
    assert result.frame_estimated and result.object_source == "estimated"
    assert result.estimate["planes"] == [] and result.estimate["support"] is None
    poses = np.stack([c.pose for c in captures])
    est = estimate_object(poses, [c.points for c in captures], np.array([0.0, 1.0, 0.0]),
                          EstimateSettings(), 0)  # fmt: skip
    points = np.concatenate([c.points for c in captures])
    assert {tuple(p) for p in est.points} <= {tuple(p) for p in points}
    center = 0.5 * (est.points.min(axis=0) + est.points.max(axis=0))
    np.testing.assert_allclose(result.frame.center, center)
    assert result.frame.radius == pytest.approx(np.linalg.norm(est.points - center, axis=1).max())
    assert result.estimate["counts"]["object"] == len(est.points) > len(points) / 2


def test_a_16_bit_png_with_depth_scale_reads_as_the_float_depth_quantised(model, tmp_path):
    from PIL import Image

    folder = write_folder(tmp_path / "caps", model, [START], "npy")
    depth = np.load(folder / "view_0.npy")
    millimetres = np.where(np.isfinite(depth), np.rint(depth * 1000), 0).astype(np.uint16)
    Image.fromarray(millimetres).save(folder / "view_0.png")
    _edit(folder, lambda s: (s["views"][0].update(file="view_0.png"), s.update(depth_scale=0.001)))
    (png,), _ = read_captures(folder)
    assert png.file.name == "view_0.png" and len(png.points) == 200
    stored = model.views["original"].view_points(START)
    # Half a millimetre of depth moves a point at most 0.5 mm times the ray's length (< 1.5).
    assert np.abs(png.points - stored).max() <= 0.0005 * 1.5


def test_an_exr_depth_view_reads_as_the_npy_one(model, tmp_path):
    import OpenEXR

    folder = write_folder(tmp_path / "caps", model, [START], "npy")
    depth = np.load(folder / "view_0.npy").astype(np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"Z": depth}) as exr:
        exr.write(str(folder / "view_0.exr"))
    _edit(folder, lambda s: s["views"][0].update(file="view_0.exr"))
    (exr_view,), _ = read_captures(folder)
    (npy_view,), _ = read_captures(write_folder(tmp_path / "npy", model, [START], "npy"))
    assert exr_view.file.name == "view_0.exr"
    # float32 depth: the same points to float32 rounding of the depth.
    np.testing.assert_allclose(exr_view.points, npy_view.points, atol=1e-6)
    with OpenEXR.File(header, {"A": depth}) as exr:
        exr.write(str(folder / "alpha.exr"))
    _edit(folder, lambda s: s["views"][0].update(file="alpha.exr"))
    with pytest.raises(CaptureError, match=r"alpha.exr.*no depth channel"):
        read_captures(folder)


def test_a_pcd_view_reads_the_stored_points(model, tmp_path):
    folder = write_folder(tmp_path / "caps", model, [START], "ply")
    cloud = o3d.io.read_point_cloud(str(folder / "view_0.ply"))
    assert o3d.io.write_point_cloud(str(folder / "view_0.pcd"), cloud)
    _edit(folder, lambda s: s["views"][0].update(file="view_0.pcd"))
    (pcd,), _ = read_captures(folder)
    np.testing.assert_array_equal(pcd.points, model.views["original"].view_points(START))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f, s: s["views"][0].update(file="view_9.npy"), "view_9.npy: no such file"),
        (lambda f, s: s["views"][0].update(file="view_0.jpg"), "view_0.jpg: unsupported view file"),
        (lambda f, s: s.update(axes="ros"), "axes='ros'; allowed: opencv, blender"),
        (lambda f, s: s.update(colour=1), r"unknown keys \['colour'\]"),
        (lambda f, s: s["intrinsics"].update(width=65), "depth is 64 x 48, the intrinsics say 65"),
        (lambda f, s: s.update(depth_scale=-1), "depth_scale=-1; must be a positive number"),
        (lambda f, s: np.save(f / "view_0.npy", np.load(f / "view_0.npy") * 1000),
         "another unit than the poses"),
        (lambda f, s: [row.__setitem__(3, 0.3 * row[3]) for row in s["views"][0]["pose"][:3]],
         "the camera is inside the object's sphere"),
    ],
)  # fmt: skip
def test_more_bad_depth_captures_name_the_file(model, tmp_path, change, message):
    folder = write_folder(tmp_path / "caps", model, [START], "npy")
    _edit(folder, lambda spec: change(folder, spec))
    with pytest.raises(CaptureError, match=message):
        plan(folder, "ig")
    assert not (tmp_path / "out").exists()


def test_captures_that_fill_the_plan_are_refused(model, tmp_path):
    folder = write_folder(tmp_path / "caps", model, list(range(10)), "ply")
    with pytest.raises(ValueError, match="n_views=10: the captures already hold 10 views"):
        plan(folder, "ig")


def test_a_capture_off_the_viewspace_joins_as_an_extra_visited_view(model, tmp_path):
    views = episode_views(model, "ig")
    folder = write_folder(tmp_path / "caps", model, views[:2], "ply")
    result = plan(folder, "ig")
    # The same captures with a viewspace of one ring that holds neither: both become extras,
    # and the plan chooses among the ring's views.
    settings = PlanSettings(
        out_dir=tmp_path / "out", method="ig", captures=folder,
        object=ObjectSettings((0.0, 0.0, 0.0), 0.5), camera=CAMERA, points_per_view=0,
        viewspace=ViewspaceSettings(kind="rings", elevations=(15.0,), per_ring=6),
    )  # fmt: skip
    ring = plan_captures(settings)
    assert ring.n_candidates == 6 and ring.visited == [6, 7] and 0 <= ring.chosen[0] < 6
    assert result.chosen == [views[2]]
    assert any("extra views" in note for note in ring.notes)


def test_depth_captures_of_one_camera_make_it_the_planner_camera(model, tmp_path):
    views = episode_views(model, "ig")
    folder = write_folder(tmp_path / "caps", model, views[:2], "npy")
    settings = PlanSettings(out_dir=tmp_path / "out", method="ig", captures=folder,
                            object=ObjectSettings((0.0, 0.0, 0.0), 0.5),
                            points_per_view=0)  # fmt: skip
    assert settings.camera != CAMERA
    result = plan_captures(settings)
    assert result.camera == CAMERA and result.chosen == [views[2]]
    # Point clouds carry no camera: the setting's is used.
    ply = plan_captures(dataclasses.replace(settings, captures=write_folder(
        tmp_path / "ply", model, views[:2], "ply")))  # fmt: skip
    assert ply.camera == settings.camera


def test_no_return_and_max_range_are_read_per_folder_and_per_view(tmp_path):
    camera = Intrinsics.centred(8, 6, 6.0)
    depth = np.full((2, 6, 8), 0.5, dtype=np.float32)
    depth[:, 0] = 0.0  # the top row: no measurement
    depth[:, 1] = 2.0  # the next: beyond the range
    pose = np.eye(4)
    folder = tmp_path / "caps"
    write_captures(folder, depth, np.stack([pose, pose]), camera, None, None, max_range=1.0)
    spec = json.loads((folder / "views.json").read_text())
    assert "object" not in spec and "no_return" not in spec and spec["max_range"] == 1.0
    spec["views"][1]["no_return"] = "free"
    (folder / "views.json").write_text(json.dumps(spec))
    (unknown, free), _ = read_captures(folder)
    for c in (unknown, free):
        assert len(c.points) == 4 * 8  # beyond the range: dropped
        assert c.misses.reach == 1.0 and c.misses.intrinsics == camera
    # Beyond the range is free up to it, whatever no_return; no return only where declared.
    assert unknown.no_return == "unknown" and free.no_return == "free"
    np.testing.assert_array_equal(unknown.misses.mask, np.arange(6)[:, None] == np.full(8, 1))
    np.testing.assert_array_equal(free.misses.mask, np.arange(6)[:, None] <= np.full(8, 1))
    # Without a range, an unknown view declares no misses at all.
    plain = tmp_path / "plain"
    write_captures(plain, depth[:1], pose[None], camera, None, None)
    ((c,), _) = read_captures(plain)
    assert c.misses is None and len(c.points) == 5 * 8


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("no_return", "maybe", "no_return='maybe'; allowed: unknown, free"),
        ("max_range", -1, "max_range=-1; must be a positive distance"),
        ("max_range", "far", "max_range='far'; must be a positive distance"),
    ],
)
def test_bad_sensor_declarations_name_the_key(tmp_path, key, value, message):
    camera = Intrinsics.centred(8, 6, 6.0)
    folder = tmp_path / "caps"
    write_captures(folder, np.full((1, 6, 8), 0.5), np.eye(4)[None], camera, None, None)
    spec = json.loads((folder / "views.json").read_text())
    spec["views"][0][key] = value
    (folder / "views.json").write_text(json.dumps(spec))
    with pytest.raises(CaptureError, match=re.escape(message)):
        read_captures(folder)
    spec["views"][0].pop(key)
    spec[key] = value
    (folder / "views.json").write_text(json.dumps(spec))
    with pytest.raises(CaptureError, match=re.escape(message)):
        read_captures(folder)
