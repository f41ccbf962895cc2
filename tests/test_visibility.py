"""Analytic visibility: the per-sample and per-triangle paths against each other, against
projection by brute force and on shapes with known answers, and the margin that widens the
image."""

import numpy as np
import pytest
from shapes import cube_corners, fibonacci_sphere

from nbv.geometry.camera import Intrinsics, project, viewspace_poses
from nbv.geometry.viewspace import original_viewspace
from nbv.setcover.hull_sampling import convex_hull, sample_on_hull
from nbv.setcover.view_sets import view_sets
from nbv.setcover.visibility import analytic_visibility, analytic_visibility_faces

K = Intrinsics()


def _brute_force_visibility(samples, normals, poses, intrinsics, margin=0.0) -> np.ndarray:
    """Per view with nbv.geometry.camera.project: facing the camera and inside the image; with a
    margin, within ``margin`` (world units) of each plane through the camera centre and an image
    border."""
    k = intrinsics
    seen = np.zeros((len(poses), len(samples)), dtype=bool)
    for v, pose in enumerate(poses):
        uv, z = project(samples, k, pose)
        if margin == 0.0:
            inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= k.width - 1)
            inside &= (uv[:, 1] >= 0) & (uv[:, 1] <= k.height - 1)
        else:
            # Distance to the plane through the centre and the border u = b (camera frame):
            # (fx x - (b - cx) z) / |(fx, b - cx)|, with x = (u - cx) z / fx.
            inside = z > 0
            for coord, f, c, last in (
                (uv[:, 0], k.fx, k.cx, k.width - 1),
                (uv[:, 1], k.fy, k.cy, k.height - 1),
            ):
                lateral = (coord - c) * z / f
                for border, sign in ((0.0, 1.0), (last, -1.0)):
                    signed = sign * (f * lateral - (border - c) * z) / np.hypot(f, border - c)
                    inside &= signed >= -margin
        facing = ((pose[:3, 3] - samples) * normals).sum(axis=1) > 1e-9
        seen[v] = inside & facing
    return seen


def _both_analytic(hull, samples, normals, faces, poses, intrinsics=K, margin=0.0):
    """The visible sets by sample and by triangle, which must agree."""
    per_sample = analytic_visibility(samples, normals, poses, intrinsics, margin)
    per_face = analytic_visibility_faces(hull, samples, faces, poses, intrinsics, margin)
    assert np.array_equal(per_sample, per_face)
    if margin == 0.0:
        assert np.array_equal(per_sample, view_sets(samples, normals, poses, intrinsics))
        exact = view_sets(
            samples, normals, poses, intrinsics, hull=hull, face_ids=faces, dilate=False
        )
        assert np.array_equal(per_sample, exact)
    return per_sample


def test_analytic_cube_sees_exactly_the_faces_turned_to_the_camera():
    hull = convex_hull(cube_corners(0.2))
    samples, normals, faces = sample_on_hull(hull, 3000, rng=0)
    top = np.array([0.0, 0.0, 1.0])
    corner = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)
    seen = _both_analytic(hull, samples, normals, faces, viewspace_poses(np.stack([top, corner])))
    # Whole cube in view from distance 1: the +z face only, and the three faces of the corner.
    assert np.array_equal(seen[0], normals[:, 2] > 0.5)
    assert np.array_equal(seen[1], normals @ corner > 0.5)


@pytest.mark.parametrize(
    "intrinsics", [K, Intrinsics(20, 16, 20.0, 25.0, 7.0, 9.0)], ids=["default", "tiny"]
)
def test_analytic_clips_to_the_image(intrinsics):
    # 0.1 in front of the +z face; camera x is world x and camera y is world -y, so pixel
    # centres 0 .. W - 1 cover (-cx / fx .. (W - 1 - cx) / fx) * 0.1 in x, and so on.
    k = intrinsics
    hull = convex_hull(cube_corners(0.2))
    samples, normals, faces = sample_on_hull(hull, 20000, rng=1)
    poses = viewspace_poses(np.array([[0, 0, 0.3]]))
    seen = _both_analytic(hull, samples, normals, faces, poses, k)
    x, y = samples[:, 0] / 0.1, -samples[:, 1] / 0.1
    expected = (normals[:, 2] > 0.5) & (-k.cx / k.fx <= x) & (x <= (k.width - 1 - k.cx) / k.fx)
    expected &= (-k.cy / k.fy <= y) & (y <= (k.height - 1 - k.cy) / k.fy)
    assert expected.sum() > 100
    assert np.array_equal(seen[0], expected)


@pytest.mark.parametrize("distance", [1.0, 2.0])
def test_analytic_sphere_shows_a_cap_of_known_area(distance):
    # A camera at distance d sees the fraction (1 - r / d) / 2 of a sphere of radius r.
    radius = 0.3
    hull = convex_hull(radius * fibonacci_sphere(2000))
    samples, normals, faces = sample_on_hull(hull, 16384, rng=2)
    poses = viewspace_poses(distance * original_viewspace())
    seen = _both_analytic(hull, samples, normals, faces, poses)
    expected = (1.0 - radius / distance) / 2.0
    fractions = seen.mean(axis=1)
    assert abs(fractions.mean() - expected) < 0.005
    assert np.abs(fractions - expected).max() < 0.02


def test_analytic_paths_agree_with_projection_brute_force():
    # Larger than the vertical field of view: many triangles are cut by the image border.
    rng = np.random.default_rng(4)
    points = fibonacci_sphere(400) * [0.5, 0.45, 0.48] + [0.02, -0.03, 0.01]
    hull = convex_hull(points)
    samples, normals, faces = sample_on_hull(hull, 8000, rng=3)
    poses = viewspace_poses(original_viewspace())
    expected = _brute_force_visibility(samples, normals, poses, K)
    assert 0 < expected.mean() < 0.5
    assert np.array_equal(_both_analytic(hull, samples, normals, faces, poses), expected)
    # Samples in any order: the per-triangle path does not need them grouped.
    perm = rng.permutation(len(samples))
    shuffled = analytic_visibility_faces(hull, samples[perm], faces[perm], poses, K)
    assert np.array_equal(shuffled, expected[:, perm])
    # A smaller, off-centre image.
    small = Intrinsics(200, 100, 150.0, 160.0, 80.0, 60.0)
    expected_small = _brute_force_visibility(samples, normals, poses, small)
    assert np.array_equal(
        _both_analytic(hull, samples, normals, faces, poses, small), expected_small
    )


def test_analytic_margin_widens_the_image_by_a_distance():
    points = fibonacci_sphere(400) * [0.5, 0.45, 0.48] + [0.02, -0.03, 0.01]
    hull = convex_hull(points)
    samples, normals, faces = sample_on_hull(hull, 8000, rng=3)
    poses = viewspace_poses(original_viewspace())
    for intrinsics in (K, Intrinsics(200, 100, 150.0, 160.0, 80.0, 60.0)):
        exact = _both_analytic(hull, samples, normals, faces, poses, intrinsics)
        wide = _both_analytic(hull, samples, normals, faces, poses, intrinsics, margin=0.03)
        expected = _brute_force_visibility(samples, normals, poses, intrinsics, margin=0.03)
        assert np.array_equal(wide, expected)
        assert np.all(wide >= exact) and (wide & ~exact).sum() > 100
    with pytest.raises(ValueError, match="margin"):
        analytic_visibility(samples, normals, poses, K, margin=-1.0)
