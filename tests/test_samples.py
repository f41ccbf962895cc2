"""Training samples: oracle walks, targets against brute force, the samples file."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from datagen import small_settings
from scipy.spatial import ConvexHull, cKDTree

import nbv.dataset
from nbv.dataset.generator import generate
from nbv.dataset.samples import (
    SampleSettings,
    load_samples,
    model_samples,
    samples_path,
    samples_up_to_date,
    walk,
    write_samples,
)
from nbv.geometry.clouds import farthest_points


def test_walk_follows_the_oracle_and_random_steps_are_seeded():
    weights = np.arange(8, dtype=float)

    def gains(state):
        return np.where(state, 0.0, weights)

    states = walk(gains, 8, start=2, steps=5, rng=np.random.default_rng(0))
    visited = [np.flatnonzero(s).tolist() for s, _ in states]
    assert visited == [[2], [2, 7], [2, 6, 7], [2, 5, 6, 7], [2, 4, 5, 6, 7]]
    rand = [walk(gains, 8, 2, 6, np.random.default_rng(3), 1.0) for _ in range(2)]
    assert [s.tolist() for s, _ in rand[0]] == [s.tolist() for s, _ in rand[1]]
    assert [np.flatnonzero(s).tolist() for s, _ in rand[0]] != visited[:1] + visited[1:]
    assert all(s.sum() == i + 1 for i, (s, _) in enumerate(rand[0]))


def test_farthest_points_spreads_and_pads():
    rng = np.random.default_rng(0)
    cloud = np.concatenate([rng.normal(0, 0.01, (5000, 3)), [[1.0, 0, 0], [-1.0, 0, 0]]])
    picked = farthest_points(cloud.astype(np.float32), 16)
    assert picked.shape == (16, 3)
    # The two far outliers are among the first picks of farthest point sampling.
    assert np.isclose(picked[:, 0], 1.0).any() and np.isclose(picked[:, 0], -1.0).any()
    small = farthest_points(cloud[:3], 7)
    assert small.shape == (7, 3) and {tuple(p) for p in small} == {tuple(p) for p in cloud[:3]}


@pytest.fixture(scope="module")
def dataset_dir(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("samples")
    generate(small_settings(tmp, points_per_view=80))
    return tmp / "out"


@pytest.mark.slow
def test_targets_equal_brute_force_gains(dataset_dir):
    ds = nbv.dataset.open(dataset_dir)
    model = ds[ds.keys()[0]]
    view = model.views["original"]
    n_gt = len(model.gt_points)
    bits = np.unpackbits(view.coverage, axis=1)[:, :n_gt].astype(bool)
    settings = SampleSettings(trajectories=2, steps=4, n_points=64, lmax=2)
    for score in ("coverage", "vig"):
        s = model_samples(model, score, settings)
        assert s["points"].shape == (8, 64, 3) and s["signature"].shape == (8, 36, 3)
        assert s["view_state"].sum(axis=1).tolist() == [1, 2, 3, 4] * 2
        hulls = view.view_hulls()
        for state, target, value in zip(s["view_state"], s["target"], s["value"], strict=True):
            assert np.all(target[state] == 0)
            if score == "coverage":
                base = bits[state].any(axis=0).mean()
                brute = [
                    bits[state | np.eye(33, dtype=bool)[v]].any(axis=0).mean() for v in range(33)
                ]
            else:
                hull = np.concatenate([hulls[v] for v in np.flatnonzero(state)])
                vol = ConvexHull(model_hull_points := hull).volume
                assert model_hull_points.shape[1] == 3
                base = vol / model.gt_hull_volume
                brute = [
                    ConvexHull(np.concatenate([hull, hulls[v]])).volume / model.gt_hull_volume
                    for v in range(33)
                ]
            assert value == pytest.approx(base, abs=1e-6)
            expected = np.where(state, 0.0, np.array(brute) - base)
            np.testing.assert_allclose(target, expected, atol=1e-6)
        # The oracle's next view is the best unvisited view of the previous target.
        for i in (0, 1, 2):
            new = np.flatnonzero(s["view_state"][i + 1] & ~s["view_state"][i])
            assert new.tolist() == [
                int(np.argmax(np.where(s["view_state"][i], -1, s["target"][i])))
            ]
        # Sample clouds are made of the visited views' points.
        cloud = np.concatenate([view.view_points(v) for v in np.flatnonzero(s["view_state"][5])])
        dist, _ = cKDTree(cloud).query(s["points"][5])
        assert dist.max() < 1e-6


@pytest.mark.slow
def test_samples_file_round_trip_and_staleness(dataset_dir):
    shard = dataset_dir / "shard-00000-of-00001.h5"
    settings = SampleSettings(trajectories=2, steps=3, n_points=32, lmax=1, seed=0)
    out, skipped = write_samples(shard, settings, progress=False)
    assert out == samples_path(shard) and skipped == []
    assert samples_up_to_date(shard, settings)
    assert not samples_up_to_date(shard, SampleSettings(trajectories=3, steps=3, n_points=32))
    cov = load_samples(dataset_dir, "coverage")
    ds = nbv.dataset.open(dataset_dir)
    assert len(cov) == len(ds) * 2 * 3
    assert set(cov.key) == set(ds) and set(cov.split) == {"test"}
    assert cov.points.shape == (len(cov), 32, 3) and cov.view_state.shape == (len(cov), 33)
    assert cov.signature.shape == (len(cov), 16, 3)
    # Deterministic: the same settings give the same arrays.
    write_samples(shard, settings, progress=False)
    again = load_samples(dataset_dir, "coverage")
    np.testing.assert_array_equal(again.points, cov.points)
    np.testing.assert_array_equal(again.target, cov.target)
    part = cov.select(cov.key == cov.key[0])
    assert len(part) == 6 and set(part.key) == {cov.key[0]}
    with pytest.raises(ValueError, match="score"):
        load_samples(dataset_dir, "loudness")


def test_samples_of_a_shard_with_another_eps_are_stale_and_refused(dataset_dir, tmp_path):
    folder = tmp_path / "copy"
    folder.mkdir()
    shard = folder / "shard-00000-of-00001.h5"
    shutil.copy(dataset_dir / shard.name, shard)
    settings = SampleSettings(trajectories=1, steps=2, n_points=16, lmax=1, seed=0)
    write_samples(shard, settings, progress=False)
    with h5py.File(samples_path(shard), "r") as handle, h5py.File(shard, "r") as f:
        assert handle.attrs["dataset_eps"] == f.attrs["eps"]
    assert samples_up_to_date(shard, settings)
    assert len(load_samples(folder, "coverage")) > 0
    # The shard remade with another eps (its targets would then come from other bits).
    with h5py.File(shard, "r+") as f:
        made = float(f.attrs["eps"])
        f.attrs["eps"] = made * 1.5
    assert not samples_up_to_date(shard, settings)
    with pytest.raises(nbv.dataset.DatasetError, match=rf"eps={made!r}, but .* has eps="):
        load_samples(folder, "coverage")
    # A samples file from before dataset_eps was recorded is remade, never trusted.
    with h5py.File(shard, "r+") as f:
        f.attrs["eps"] = made
    with h5py.File(samples_path(shard), "r+") as handle:
        del handle.attrs["dataset_eps"]
    assert not samples_up_to_date(shard, settings)


def test_flat_models_are_skipped_for_vig(tmp_path):
    folder = tmp_path / "flat"
    folder.mkdir()
    # A tilted square: flat, so its hull has no volume, yet seen by most cameras.
    (folder / "sheet.obj").write_text(
        "v 0 0 0\nv 1 0.2 0.1\nv 1.2 1 0.5\nv 0.2 0.8 0.4\nf 1 2 3 4\n"
    )
    generate(small_settings(tmp_path, root=str(folder)))
    shard = tmp_path / "out" / "shard-00000-of-00001.h5"
    _, skipped = write_samples(shard, SampleSettings(trajectories=1, steps=2, n_points=16))
    assert skipped == [("sheet", "vig", "ground-truth hull has no volume: VIG undefined")]
    assert len(load_samples(tmp_path / "out", "coverage")) == 2
    with pytest.raises(ValueError, match="no vig samples"):
        load_samples(tmp_path / "out", "vig")
