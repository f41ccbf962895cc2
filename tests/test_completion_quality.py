"""Completion quality: the metrics against brute force, the oracle mirror, the rows, the summary
and the command's refusals (no dataset, no network)."""

from dataclasses import dataclass

import numpy as np
import pytest

from nbv.eval.completion_quality import (
    KINDS,
    MIRROR_NORMALS,
    cd_l1,
    fscore,
    main,
    mirror_completion,
    quality_rows,
    summarise,
    summary_markdown,
    view_order,
)


def brute(pred: np.ndarray, gt: np.ndarray, d: float) -> tuple[float, float]:
    """(CD-L1, F-score at d) from the full distance matrix."""
    dist = np.linalg.norm(pred[:, None, :] - gt[None, :, :], axis=-1)
    a, b = dist.min(axis=1), dist.min(axis=0)
    p, r = np.mean(a < d), np.mean(b < d)
    return (a.mean() + b.mean()) / 2, 0.0 if p + r == 0 else 2 * p * r / (p + r)


def grid(n: int = 5, spacing: float = 1.0) -> np.ndarray:
    """(n**3, 3) points of a cubic grid."""
    axis = np.arange(n) * spacing
    return np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)


@pytest.mark.parametrize("n, m, d", [(50, 80, 0.1), (200, 30, 0.3), (1, 7, 0.5)])
def test_metrics_match_brute_force(n, m, d):
    rng = np.random.default_rng(n)
    pred, gt = rng.uniform(-0.5, 0.5, (n, 3)), rng.uniform(-0.5, 0.5, (m, 3))
    cd, f = brute(pred, gt, d)
    assert cd_l1(pred, gt) == pytest.approx(cd, rel=1e-12)
    assert fscore(pred, gt, d) == pytest.approx(f, rel=1e-12)
    assert 0 < f < 1  # both sides' shares matter at these thresholds


def test_known_values():
    gt, d = grid(), 0.01
    assert cd_l1(gt, gt) == 0.0 and fscore(gt, gt, d) == 1.0
    shifted = gt + [0.5 * d, 0, 0]  # each point's nearest is its own copy (spacing 1)
    assert cd_l1(shifted, gt) == pytest.approx(0.5 * d) and fscore(shifted, gt, d) == 1.0
    assert fscore(gt + [2 * d, 0, 0], gt, d) == 0.0
    half = gt[: len(gt) // 2]  # precision 1, recall 1/2 (62 of 125: 62/125)
    r = len(half) / len(gt)
    assert fscore(half, gt, d) == pytest.approx(2 * r / (1 + r))
    assert fscore(gt, half, d) == pytest.approx(2 * r / (1 + r))  # the sides swap
    with pytest.raises(ValueError, match="pred"):
        cd_l1(np.zeros((0, 3)), gt)


@pytest.mark.parametrize("plane", [0, 3, 7, 12])
def test_mirror_recovers_a_symmetric_shape(plane):
    n = MIRROR_NORMALS[plane]
    rng = np.random.default_rng(plane)
    half = rng.uniform(-0.4, 0.4, (600, 3))
    half = half[half @ n > 0.01]
    whole = np.concatenate([half, half - 2 * (half @ n)[:, None] * n])
    completed = mirror_completion(half, whole)
    assert completed.shape == (2 * len(half), 3) and completed.dtype == np.float32
    assert cd_l1(completed, whole) < 1e-6
    assert cd_l1(half, whole) > 0.01  # the half alone is far from the whole
    np.testing.assert_allclose(completed[: len(half)], half, atol=1e-7)


def test_mirror_normals():
    assert MIRROR_NORMALS.shape == (13, 3)
    np.testing.assert_allclose(np.linalg.norm(MIRROR_NORMALS, axis=1), 1.0)
    np.testing.assert_allclose(MIRROR_NORMALS[:12, 1], 0.0)
    np.testing.assert_allclose(MIRROR_NORMALS[2], [np.cos(np.pi / 6), 0, np.sin(np.pi / 6)])
    np.testing.assert_allclose(MIRROR_NORMALS[12], [0, 1, 0])


def sphere(n: int, radius: float) -> np.ndarray:
    """(n, 3) Fibonacci points on a sphere."""
    i = np.arange(n) + 0.5
    y, phi = 1 - 2 * i / n, np.pi * (1 + 5**0.5) * i
    r = np.sqrt(1 - y**2)
    return radius * np.stack([r * np.cos(phi), y, r * np.sin(phi)], 1)


@dataclass
class Captured:
    poses: np.ndarray
    parts: list

    def view_points(self, v: int) -> np.ndarray:
        return self.parts[v]


@dataclass
class Model:
    category: str
    gt_points: np.ndarray
    positions: np.ndarray

    def captured(self, viewspace: str) -> Captured:
        assert viewspace == "original"
        poses = np.tile(np.eye(4), (len(self.positions), 1, 1))
        poses[:, :3, 3] = self.positions
        dirs = self.positions / np.linalg.norm(self.positions, axis=1, keepdims=True)
        # A view sees the cap of the ground truth facing it.
        parts = [self.gt_points[self.gt_points @ u > 0.25].astype(np.float32) for u in dirs]
        return Captured(poses, parts)


class Dataset:
    def __init__(self):
        views = sphere(33, 1.5)
        self.models = {f"m{i}": Model("ball", sphere(400 + 100 * i, 0.4), views) for i in range(2)}

    def model(self, key: str) -> Model:
        return self.models[key]


class Oracle:
    """A completer that returns the ground truth of the model of each cloud."""

    def __init__(self, gt: np.ndarray):
        self.gt = gt

    def batch(self, clouds: list[np.ndarray]) -> np.ndarray:
        return np.stack([self.gt] * len(clouds)).astype(np.float32)


@pytest.mark.slow
def test_quality_rows_with_a_perfect_completer():
    ds = Dataset()
    rows = []
    for key in ds.models:
        rows += quality_rows(ds, [key], "original", Oracle(ds.models[key].gt_points), seed=3)
    assert len(rows) == 2 * 4 * 5
    assert {r["start"] for r in rows} == {1, 7, 15, 27} and {r["k"] for r in rows} == set(
        range(1, 6)
    )
    for r in rows:
        views = [int(v) for v in r["views"].split()]
        gt = ds.models[r["key"]].gt_points
        assert views[0] == r["start"] and len(set(views)) == r["k"] == len(views)
        captured = ds.models[r["key"]].captured("original")
        assert r["n_points"] == sum(len(captured.view_points(v)) for v in views)
        assert r["cd_network"] == pytest.approx(0, abs=1e-7) and r["f_network"] == 1.0
        assert r["cd_union"] == pytest.approx(0, abs=1e-7) and r["f_union"] == 1.0
        assert r["cd_partial"] > 0.005 and r["f_partial"] < 1  # caps miss part of it
        partial = np.concatenate([captured.view_points(v) for v in views])
        assert r["cd_partial"] == pytest.approx(cd_l1(partial, gt), rel=1e-9)
        assert r["f_partial"] == pytest.approx(fscore(partial, gt), rel=1e-9)
        mirrored = mirror_completion(partial, gt)
        assert r["cd_mirror"] == pytest.approx(cd_l1(mirrored, gt), rel=1e-5)
        # A centred sphere: every plane is a symmetry; one view leaves most of it to complete.
        assert r["k"] > 1 or r["cd_mirror"] < r["cd_partial"]
        assert set(r) >= {f"{m}_{kind}" for m in ("cd", "f") for kind in KINDS}
    # The k views are the first k of one order per model and start view.
    by = {(r["key"], r["start"], r["k"]): r["views"] for r in rows}
    for (key, start, k), views in by.items():
        if k > 1:
            assert views.startswith(by[key, start, k - 1] + " ")
    # More views: the partial cloud gets closer.
    for key in ds.models:
        cds = [np.mean([r["cd_partial"] for r in rows if r["key"] == key and r["k"] == k])
               for k in range(1, 6)]  # fmt: skip
        assert cds[-1] < cds[0]


def test_view_order_is_the_spread_order():
    positions = sphere(33, 1.5)
    order = view_order(positions, 7, 5, np.random.default_rng(0))
    assert order[0] == 7 and len(set(order)) == 5
    # The second view is the farthest in angle from the start.
    assert order[1] == int(np.argmin(positions @ positions[7]))


def test_summary_averages_start_views_within_a_model_first():
    def row(key, k, cd_partial, cd_union):
        base = {f"{m}_{kind}": 0.5 for m in ("cd", "f") for kind in KINDS}
        return base | {"key": key, "k": k, "cd_partial": cd_partial, "cd_union": cd_union}

    rows = [row("a", 1, 1.0, 0.0), row("a", 1, 3.0, 0.0), row("a", 1, 2.0, 0.0)]
    rows += [row("b", 1, 6.0, 1.0), row("c", 1, 4.0, 2.0), row("a", 2, 1.0, 1.0)]
    s = summarise(rows)
    assert [x.k for x in s] == [1, 2] and [x.models for x in s] == [3, 1]
    assert s[0].means["cd_partial"] == pytest.approx((2 + 6 + 4) / 3)  # not the row mean 3.2
    d = s[0].diffs["cd_union-partial"]
    assert d.mean == pytest.approx(((0 - 2) + (1 - 6) + (2 - 4)) / 3) and d.low <= d.mean <= d.high
    assert s[0].diffs["cd_union-mirror"].mean == pytest.approx((-0.5 + 0.5 + 1.5) / 3)
    assert np.isnan(s[1].diffs["f_union-partial"].low)  # one model: no interval
    page = summary_markdown(s, "t")
    assert "CD-L1, normalised frame (radius 0.5)" in page and "F-score at d = 0.01" in page
    assert "| 1 | 3 | 4.0000 | 0.5000 | 0.5000 | 1.0000 | -3.0000 [" in page


@pytest.mark.parametrize(
    "argv, message",
    [
        (["dataset"], "bad argument 'dataset'"),
        (["colour=red", "out=x"], "bad argument 'colour=red'"),
        (["dataset=x"], "out=<folder> is required"),
        (["models=some", "out=x"], "models='some'"),
        (["dataset={tmp}/none", "out={tmp}/out"], "no such dataset"),
    ],
)
def test_command_refuses_bad_arguments(argv, message, tmp_path, capsys):
    assert main([a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()
