"""Viewspace symmetries: known groups, exact signature maps, and the augmented sample equal to the
sample of the mapped object rendered again."""

import itertools

import numpy as np
import pytest
import trimesh

from nbv.assets.meshes import sample_surface
from nbv.dataset.generator import view_data
from nbv.geometry.camera import Intrinsics, viewspace_poses
from nbv.geometry.scores import coverage_gains
from nbv.geometry.sph import signature
from nbv.geometry.symmetry import (
    map_signature,
    permute_views,
    signature_map,
    viewspace_symmetries,
)
from nbv.geometry.viewspace import get_viewspace
from nbv.render.raycast import render_raycast
from train.augment import Augmentation


def _check_group(positions, symmetries):
    for s in symmetries:
        np.testing.assert_allclose(s.matrix.T @ s.matrix, np.eye(3), atol=1e-9)
        np.testing.assert_allclose(positions @ s.matrix.T, positions[s.permutation], atol=1e-9)
    matrices = np.array([s.matrix for s in symmetries])
    for a, b in itertools.product(symmetries, repeat=2):  # closed under composition
        assert np.abs(matrices - a.matrix @ b.matrix).max(axis=(1, 2)).min() < 1e-9


def test_original_viewspace_has_8_rotations_about_up_and_their_mirrors():
    positions = get_viewspace("original")
    symmetries = viewspace_symmetries(positions)
    assert len(symmetries) == 16 and symmetries[0].is_identity
    dets = np.round([np.linalg.det(s.matrix) for s in symmetries])
    assert (dets == 1).sum() == 8 and (dets == -1).sum() == 8
    for s in symmetries:
        np.testing.assert_allclose(s.matrix @ [0, 1, 0], [0, 1, 0], atol=1e-9)  # up axis kept
        assert s.permutation[0] == 0  # the pole stays
    _check_group(positions, symmetries)


def test_known_groups_and_none():
    cube = np.array(list(itertools.product([-1.0, 1.0], repeat=3)))
    _check_group(cube, group := viewspace_symmetries(cube))
    assert len(group) == 48  # the full octahedral group
    square = np.array([[1.0, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]])
    assert len(viewspace_symmetries(square)) == 16  # D4 in the plane, times the plane's mirror
    assert [s.is_identity for s in viewspace_symmetries(get_viewspace("permuted"))] == [True]
    with pytest.raises(ValueError, match="one line through the centre"):
        viewspace_symmetries(np.array([[0, 0, 1.0], [0, 0, -2.0]]))


def test_signature_of_the_mapped_cloud_from_the_stored_one():
    rng = np.random.default_rng(0)
    cloud = rng.normal(size=(800, 3)) * [0.3, 0.2, 0.1] + [0.1, 0.0, 0.05]
    for s in viewspace_symmetries(get_viewspace("original"))[1:]:
        mapped = map_signature(signature(cloud), signature_map(s.matrix, 3), 3)
        np.testing.assert_allclose(mapped, signature(cloud @ s.matrix.T), atol=1e-5)


def _views(mesh: trimesh.Trimesh, gt: np.ndarray, poses, camera):
    depth = render_raycast(mesh.vertices, mesh.faces, poses, camera)
    return view_data(depth, poses, camera, gt, 0.03, 0, np.random.default_rng(0))


@pytest.mark.slow
def test_augmented_sample_equals_the_sample_of_the_mapped_object():
    """An object without symmetry, rendered from the original views; the same object mapped by
    each symmetry, rendered again: its per-view gains are the original's, permuted."""
    parts = [
        trimesh.creation.box((0.5, 0.2, 0.3)),
        trimesh.creation.icosphere(2, 0.15).apply_translation([0.2, 0.15, 0.1]),
        trimesh.creation.cylinder(0.05, 0.4).apply_translation([-0.15, 0.0, 0.2]),
    ]
    mesh = trimesh.util.concatenate(parts)
    gt = sample_surface(mesh, 1500, np.random.default_rng(0))
    positions = get_viewspace("original")
    poses = viewspace_poses(positions)
    camera = Intrinsics.centred(96, 72, 72.0)
    base = _views(mesh, gt, poses, camera)
    state = np.zeros(len(positions), bool)
    state[[3, 12, 20]] = True
    target = coverage_gains(base.coverage, state, len(gt))
    assert target.max() > 0.05
    symmetries = viewspace_symmetries(positions)
    for s in symmetries[1:]:
        moved = mesh.copy().apply_transform(np.block([[s.matrix, np.zeros((3, 1))], [0, 0, 0, 1]]))
        again = _views(moved, gt @ s.matrix.T, poses, camera)
        expected = coverage_gains(again.coverage, permute_views(state, s), len(gt))
        got = permute_views(target, s)
        # Equal but for the pole's camera, whose roll the map changes (its pixels sample the
        # surface elsewhere), and a few points at the eps boundary of the others.
        np.testing.assert_allclose(got, expected, atol=0.01)
        assert np.abs(got - expected).mean() < 1e-3
        # The test can fail: the unpermuted gains are not those of the mapped object.
        assert np.abs(target - expected).max() > 0.05
    # The batch augmentation maps each sample by one of these.
    aug = Augmentation(positions, 3)
    cloud = np.concatenate(
        [base.points[base.offsets[v] : base.offsets[v + 1]] for v in (3, 12, 20)]
    )
    points, states, targets = aug.apply(
        np.repeat(cloud[None], 40, 0), np.repeat(state[None], 40, 0),
        np.repeat(target[None], 40, 0), np.random.default_rng(1),
    )  # fmt: skip
    used = set()
    for p, v, t in zip(points, states, targets, strict=True):
        k = next(
            i for i, s in enumerate(symmetries) if np.allclose(p, cloud @ s.matrix.T, atol=1e-6)
        )
        used.add(k)
        np.testing.assert_array_equal(v, permute_views(state, symmetries[k]))
        np.testing.assert_array_equal(t, permute_views(target, symmetries[k]))
    assert len(used) > 8
    again = aug.apply(np.repeat(cloud[None], 40, 0), np.repeat(state[None], 40, 0),
                      np.repeat(target[None], 40, 0), np.random.default_rng(1))  # fmt: skip
    np.testing.assert_array_equal(again[0], points)  # seeded: the same arrays
