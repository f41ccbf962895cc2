import numpy as np
import pytest

from nbv.geometry.camera import (
    Intrinsics,
    backproject,
    look_at,
    opencv_to_blender,
    pixel_rays,
    project,
    valid_depth,
    viewspace_poses,
)
from nbv.geometry.viewspace import original_viewspace


def test_default_intrinsics_are_pcnbv():
    k = Intrinsics.centred()
    assert (k.width, k.height, k.fx, k.fy, k.cx, k.cy) == (640, 480, 476.0, 476.0, 319.5, 239.5)
    assert k == Intrinsics()
    assert np.rad2deg(k.horizontal_fov) == pytest.approx(67.8, abs=0.05)


def test_intrinsics_as_dict_round_trips_with_plain_types():
    k = Intrinsics(64, 48, 50.0, 51, 31.5, 23)
    d = k.as_dict()
    assert d == {"width": 64, "height": 48, "fx": 50.0, "fy": 51.0, "cx": 31.5, "cy": 23.0}
    assert [type(v) for v in d.values()] == [int, int, float, float, float, float]
    assert Intrinsics(**d) == k


@pytest.mark.parametrize("bad", [dict(width=0), dict(fx=-1.0)])
def test_bad_intrinsics_refused(bad):
    with pytest.raises(ValueError):
        Intrinsics(**bad)


def test_look_at_is_a_rigid_pose_pointing_at_target():
    for eye in original_viewspace():
        pose = look_at(eye)
        r = pose[:3, :3]
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(pose[:3, 2], -eye / np.linalg.norm(eye), atol=1e-12)
        np.testing.assert_allclose(pose[:3, 3], eye)


def test_look_at_keeps_world_up_up_and_is_defined_at_poles():
    pose = look_at(np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(pose[:3, 0], [1, 0, 0], atol=1e-12)  # right
    np.testing.assert_allclose(pose[:3, 1], [0, -1, 0], atol=1e-12)  # image down is world down
    for eye in ([0.0, 1.0, 0.0], [0.0, -2.0, 0.0], [4e-17, 1.0, 4e-17]):
        pose = look_at(np.array(eye))
        assert np.all(np.isfinite(pose))
        np.testing.assert_allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3), atol=1e-12)
    # The pole pose does not depend on float noise in the direction.
    np.testing.assert_allclose(
        look_at(np.array([0.0, 1.0, 0.0])), look_at(np.array([4e-17, 1.0, -4e-17])), atol=1e-12
    )


def test_look_at_refuses_eye_on_target():
    with pytest.raises(ValueError, match="coincides"):
        look_at(np.zeros(3))


def test_plane_at_known_distance_backprojects_onto_the_plane():
    k = Intrinsics.centred(64, 48, 40.0)
    pose = look_at(np.array([0.0, 0.0, 2.0]))
    depth = np.full((48, 64), 1.5)  # the plane z = 0.5 seen from z = 2
    pts = backproject(depth, k, pose)
    assert pts.shape == (64 * 48, 3)
    np.testing.assert_allclose(pts[:, 2], 0.5, atol=1e-12)
    # Corner pixel (0, 0) is up-left in the image: world -x, +y from this camera.
    np.testing.assert_allclose(pts[0, :2], [-31.5 * 1.5 / 40, 23.5 * 1.5 / 40], atol=1e-12)


def test_sphere_depth_backprojects_onto_the_sphere():
    k = Intrinsics.centred(80, 60, 50.0)
    eye = np.array([0.3, 0.5, 1.2])
    pose = look_at(eye)
    radius = 0.4
    # Analytic planar depth of a sphere at the origin: nearest ray-sphere hit times ray z.
    rays = pixel_rays(k) @ pose[:3, :3].T
    b = rays @ eye
    a = np.sum(rays * rays, axis=-1)
    disc = b**2 - a * (eye @ eye - radius**2)
    depth = np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / a, np.inf)
    pts = backproject(depth, k, pose)
    assert len(pts) == np.count_nonzero(disc >= 0) > 100
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), radius, atol=1e-12)


def test_project_then_backproject_round_trip():
    rng = np.random.default_rng(0)
    k = Intrinsics.centred()
    for pose in viewspace_poses(original_viewspace()):
        cam = np.column_stack([rng.uniform(-0.3, 0.3, (50, 2)), rng.uniform(0.5, 1.5, 50)])
        world = cam @ pose[:3, :3].T + pose[:3, 3]
        uv, z = project(world, k, pose)
        np.testing.assert_allclose(z, cam[:, 2], atol=1e-12)
        # Back-project through a depth image holding each point at its (fractional) pixel.
        rays = np.column_stack([(uv[:, 0] - k.cx) / k.fx, (uv[:, 1] - k.cy) / k.fy, np.ones(50)])
        back = (rays * z[:, None]) @ pose[:3, :3].T + pose[:3, 3]
        np.testing.assert_allclose(back, world, atol=1e-6)


def test_backproject_then_project_hits_pixel_centres():
    k = Intrinsics.centred(32, 24, 30.0)
    pose = look_at(np.array([1.0, 0.2, 0.0]))
    depth = np.random.default_rng(1).uniform(0.5, 2.0, (24, 32))
    depth[3, 4] = np.inf
    depth[5, 6] = 1e10
    depth[7, 8] = np.nan
    pts = backproject(depth, k, pose)
    assert len(pts) == 32 * 24 - 3
    uv, z = project(pts, k, pose)
    vv, uu = np.nonzero(np.isfinite(depth) & (depth < 1e9))
    np.testing.assert_allclose(uv, np.column_stack([uu, vv]), atol=1e-6)
    np.testing.assert_allclose(z, depth[vv, uu], atol=1e-9)


def test_backproject_checks_image_size():
    with pytest.raises(ValueError, match="depth image"):
        backproject(np.ones((10, 10)), Intrinsics.centred(), np.eye(4))


def test_blender_pose_looks_down_its_minus_z():
    pose = look_at(np.array([0.0, 0.0, 3.0]))
    b = opencv_to_blender(pose)
    np.testing.assert_allclose(-b[:3, 2], [0, 0, -1], atol=1e-12)  # looks towards the origin
    np.testing.assert_allclose(b[:3, 1], [0, 1, 0], atol=1e-12)  # camera up is world up
    np.testing.assert_allclose(b[:3, 3], pose[:3, 3])


def test_backproject_equals_the_whole_image_rays_masked():
    """The rays of the valid pixels alone give, bit for bit, what masking every pixel's ray
    gives, in the same row-major order."""
    k = Intrinsics(width=64, height=48, fx=60.0, fy=61.0, cx=31.7, cy=23.2)
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.5, 2.0, (48, 64)).astype(np.float32)
    depth[rng.random((48, 64)) < 0.5] = np.inf
    depth[0, :5] = 0.0  # not a surface either
    pose = np.eye(4)
    pose[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    pose[:3, 3] = [1.0, 2.0, 3.0]
    mask = valid_depth(depth)
    expected = (pixel_rays(k)[mask] * depth[mask].astype(np.float64)[:, None]) @ pose[:3, :3].T
    assert np.array_equal(backproject(depth, k, pose), expected + pose[:3, 3])
    # A mask of some of the valid pixels: those alone, the same arithmetic.
    some = mask & (np.arange(64) < 40)[None, :]
    expected = (pixel_rays(k)[some] * depth[some].astype(np.float64)[:, None]) @ pose[:3, :3].T
    assert np.array_equal(backproject(depth, k, pose, some), expected + pose[:3, 3])
