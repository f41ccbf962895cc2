import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from nbv.assets.categories import CATEGORIES, TRAIN_CATEGORIES, UNSEEN_CATEGORIES
from nbv.assets.synthetic import (
    DEFAULT_COUNTS,
    SyntheticEntry,
    build,
    catalogue,
    make_model,
    model_rng,
    preview,
    render_tile,
)

ROOT = Path(__file__).resolve().parents[1]


def _entry(category: str, index: int) -> SyntheticEntry:
    return SyntheticEntry(f"{category}_{index:04d}", category, "test", index)


def _extents(vertices: np.ndarray) -> np.ndarray:
    return vertices.max(axis=0) - vertices.min(axis=0)


def _digest(vertices: np.ndarray, faces: np.ndarray) -> str:
    return hashlib.sha256(vertices.tobytes() + faces.tobytes()).hexdigest()


def test_category_names_and_order():
    assert TRAIN_CATEGORIES == (
        "airplane", "cabinet", "car", "chair", "lamp", "sofa", "table", "vessel",
    )  # fmt: skip
    assert UNSEEN_CATEGORIES == (
        "bus", "bed", "bookshelf", "bench", "guitar", "motorbike", "skateboard", "pistol",
    )  # fmt: skip
    assert CATEGORIES == TRAIN_CATEGORIES + UNSEEN_CATEGORIES
    assert len(set(CATEGORIES)) == 16


@pytest.mark.parametrize("category", CATEGORIES)
def test_every_category_builds_valid_normalised_meshes(category):
    for seed in (0, 1, 2):
        for index in (0, 1):
            v, f = build(_entry(category, index), seed)
            assert v.dtype == np.float64 and v.ndim == 2 and v.shape[1] == 3
            assert f.dtype == np.int64 and f.ndim == 2 and f.shape[1] == 3
            assert np.isfinite(v).all()
            assert f.min() >= 0 and f.max() < len(v)
            assert 12 <= len(f) <= 20_000
            areas = trimesh.triangles.area(v[f])
            assert (areas > 0).all(), "no degenerate triangles"
            # ShapeNetCore v2 normalisation: bounding box centred, diagonal 1.
            lo, hi = v.min(axis=0), v.max(axis=0)
            np.testing.assert_allclose((lo + hi) / 2, 0.0, atol=1e-12)
            assert np.linalg.norm(hi - lo) == pytest.approx(1.0, abs=1e-12)
            assert np.linalg.norm(v, axis=1).max() <= 0.5 + 1e-12
    # Parts share no vertices, so each connected piece is one primitive: a closed solid with
    # outward normals (positive signed volume).
    pieces = trimesh.Trimesh(v, f, process=False).split(only_watertight=False)
    assert len(pieces) >= 3
    assert all(p.is_watertight and p.volume > 0 for p in pieces)


def test_same_seed_same_arrays_and_other_index_or_seed_differs():
    for category in ("chair", "guitar"):
        v1, f1 = build(_entry(category, 3), 5)
        v2, f2 = build(_entry(category, 3), 5)
        np.testing.assert_array_equal(v1, v2)
        np.testing.assert_array_equal(f1, f2)
        v3, _ = build(_entry(category, 4), 5)
        v4, _ = build(_entry(category, 3), 6)
        for other in (v3, v4):
            assert other.shape != v1.shape or not np.allclose(other, v1)
    # The split does not enter the generator: only (seed, category, index) do.
    a = build(SyntheticEntry("x", "car", "train", 2), 1)[0]
    b = build(SyntheticEntry("y", "car", "valid", 2), 1)[0]
    np.testing.assert_array_equal(a, b)
    # make_model draws everything from the generator it is given.
    c = make_model("car", model_rng("car", 2, 1))[0]
    np.testing.assert_array_equal(a, c)


@pytest.mark.slow
def test_identical_arrays_in_another_process_with_another_hash_seed():
    code = (
        "import hashlib; from nbv.assets.synthetic import SyntheticEntry, build; "
        "v, f = build(SyntheticEntry('lamp_0002', 'lamp', 'train', 2), 11); "
        "print(hashlib.sha256(v.tobytes() + f.tobytes()).hexdigest())"
    )
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    assert out.stdout.strip() == _digest(*build(_entry("lamp", 2), 11))


def test_model_rng_rejects_bad_input():
    with pytest.raises(ValueError, match="unknown synthetic category 'spoon'"):
        model_rng("spoon", 0, 0)
    with pytest.raises(ValueError, match="unknown synthetic category 'spoon'"):
        make_model("spoon", np.random.default_rng(0))
    with pytest.raises(ValueError, match=">= 0"):
        model_rng("car", -1, 0)


@pytest.mark.parametrize("category", CATEGORIES)
@pytest.mark.slow
def test_shapes_vary_within_a_category(category):
    ext = np.array([_extents(build(_entry(category, i), 0)[0]) for i in range(6)])
    # Every pair of models differs in its proportions.
    gaps = np.abs(ext[:, None, :] - ext[None, :, :]).max(axis=2)
    assert gaps[~np.eye(6, dtype=bool)].min() > 1e-3
    assert ext.std(axis=0).max() > 0.01


def test_frame_long_objects_along_z_upright_objects_along_y():
    for i in range(5):
        for category in ("car", "bus", "vessel", "motorbike", "skateboard"):
            ex, ey, ez = _extents(build(_entry(category, i), 0)[0])
            assert ez > ex and ez > ey, category
        ex, ey, ez = _extents(build(_entry("guitar", i), 0)[0])
        assert ey > ex > ez
        for category in ("sofa", "bench"):
            ex, _, ez = _extents(build(_entry(category, i), 0)[0])
            assert ex > ez, category
        # A chair's back is at the rear: its highest point lies behind the seat's centre.
        v, _ = build(_entry("chair", i), 0)
        assert v[np.argmax(v[:, 1]), 2] < 0


def test_categories_differ():
    per = 6
    desc = np.array([_extents(build(_entry(c, i), 0)[0]) for c in CATEGORIES for i in range(per)])
    labels = np.repeat(np.arange(len(CATEGORIES)), per)
    # Airplanes are flat and long, bookshelves tall and shallow.
    plane = desc[labels == CATEGORIES.index("airplane")].mean(axis=0)
    shelf = desc[labels == CATEGORIES.index("bookshelf")].mean(axis=0)
    assert plane[1] / plane[2] < 0.5 < 2.0 < shelf[1] / shelf[2]
    # Leave-one-out nearest centroid on the bounding-box extents alone beats chance (1/16).
    hits = 0
    for k in range(len(desc)):
        keep = np.arange(len(desc)) != k
        centroids = np.array(
            [desc[keep & (labels == c)].mean(axis=0) for c in range(len(CATEGORIES))]
        )
        hits += np.argmin(np.linalg.norm(centroids - desc[k], axis=1)) == labels[k]
    assert hits / len(desc) > 0.5


def test_default_catalogue():
    entries = catalogue()
    assert entries == catalogue()
    assert len(entries) == 64
    assert len({e.key for e in entries}) == 64
    assert [e.category for e in entries[::2]][:3] == ["airplane"] * 3
    for category in CATEGORIES:
        mine = [e for e in entries if e.category == category]
        assert [e.index for e in mine] == list(range(len(mine)))
        assert all(e.key == f"{category}_{e.index:04d}" for e in mine)
        splits = [e.split for e in mine]
        if category in TRAIN_CATEGORIES:
            assert splits == ["test"] + ["valid"] + ["train"] * 4
        else:
            assert splits == ["test"] * DEFAULT_COUNTS["unseen"]
    assert [e.category for e in entries] == sorted(
        (e.category for e in entries), key=CATEGORIES.index
    )


def test_catalogue_counts_and_stable_test_models():
    small = catalogue({"train": 1, "valid": 2, "test": 3, "unseen": 0})
    assert len(small) == 8 * 6
    assert {e.category for e in small} == set(TRAIN_CATEGORIES)
    table = [e for e in small if e.category == "table"]
    assert [e.split for e in table] == ["test"] * 3 + ["valid"] * 2 + ["train"]
    bigger = catalogue({"train": 10, "valid": 2, "test": 3, "unseen": 0})
    held_out = [e for e in small if e.split != "train"]
    assert held_out == [e for e in bigger if e.split != "train"]
    only_unseen = catalogue({"train": 0, "valid": 0, "test": 0, "unseen": 3})
    assert len(only_unseen) == 24 and {e.split for e in only_unseen} == {"test"}
    # Missing keys take the defaults.
    assert len(catalogue({"unseen": 0})) == 8 * 6


def test_catalogue_rejects_bad_counts():
    with pytest.raises(ValueError, match="'training'.*allowed: train, valid, test, unseen"):
        catalogue({"training": 3})
    with pytest.raises(ValueError, match=r"counts\['train'\] = -1"):
        catalogue({"train": -1})
    with pytest.raises(ValueError, match=r"counts\['test'\] = 1.5"):
        catalogue({"test": 1.5})


def test_render_tile_orientation():
    # Camera on +z looking at the origin, Y up: +x shows on the right, +y at the top.
    for offset, expect in (((0.3, 0, 0), "right"), ((0, 0.3, 0), "top")):
        box = trimesh.creation.box((0.1, 0.1, 0.1))
        box.apply_translation(offset)
        img = render_tile(box.vertices, box.faces, 64, azimuth=0.0, elevation=0.0)
        assert img.shape == (64, 64, 3) and img.dtype == np.uint8
        rows, cols = np.nonzero(img.sum(axis=2) < 3 * 250)
        assert len(rows) > 0
        if expect == "right":
            assert cols.min() > 32 and abs(rows.mean() - 31.5) < 2
        else:
            assert rows.max() < 32 and abs(cols.mean() - 31.5) < 2
    assert (img[0, 0] == 255).all()


def test_preview_writes_the_grid(tmp_path):
    path = tmp_path / "sheet" / "preview.png"
    preview(path, seed=0, per_category=1, tile=24, label_width=40)
    image = np.asarray(Image.open(path).convert("RGB"))
    assert image.shape == (16 * 24, 40 + 24, 3)
    # Every row shows a model: coloured pixels (the caption is grey, the background white).
    for row in range(16):
        tile = image[row * 24 : (row + 1) * 24, 40:].astype(int)
        assert (tile.max(axis=2) - tile.min(axis=2) > 30).sum() > 5, CATEGORIES[row]
    with pytest.raises(ValueError, match="per_category >= 1"):
        preview(tmp_path / "x.png", per_category=0)


@pytest.mark.slow
def test_command_line(tmp_path):
    """``python -m nbv.preview``: the options are keys; a bad one refuses the run (status 2)."""
    path = tmp_path / "cli.png"
    run = [
        sys.executable,
        "-m",
        "nbv.preview",
        f"preview={path}",
        f"hydra.run.dir={tmp_path / 'run'}",
    ]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([*run, "seed=3", "per_category=1", "tile=16"], env=env, cwd=ROOT)
    assert done.returncode == 0
    assert Image.open(path).size == (150 + 16, 16 * 16)
    bad = subprocess.run(
        [*run, "per_category=0"], env=env, cwd=ROOT, capture_output=True, text=True
    )
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines()[-1] == (
        "nbv.preview: per_category=0: must be an integer >= 1"
    )
