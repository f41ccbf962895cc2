"""Small datasets for tests: a folder of meshes written on the spot, tiny cameras, ray casting."""

from __future__ import annotations

from pathlib import Path

import trimesh

from nbv.camera import Intrinsics
from nbv.dataset.generate import Settings

SMALL_CAMERA = Intrinsics.centred(64, 48, 48.0)


def write_meshes(folder: Path, bad: bool = True) -> Path:
    """A folder source: a box, a sphere, a two-part mesh and (optionally) a broken file."""
    folder.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box((0.6, 0.3, 0.9)).export(folder / "box.ply")
    trimesh.creation.icosphere(3, 0.7).export(folder / "ball.obj")
    two = trimesh.util.concatenate(
        [trimesh.creation.box((1, 1, 1)), trimesh.creation.cylinder(0.3, 2.0, sections=16)]
    )
    two.apply_translation([5.0, -2.0, 1.0])
    two.export(folder / "parts.stl")
    if bad:
        (folder / "broken.obj").write_text("v 0 0 0\nv nan 1 0\nv 1 0 0\nf 1 2 3\n")
    return folder


def small_settings(tmp_path: Path, **overrides) -> Settings:
    base = dict(
        out_dir=tmp_path / "out",
        source="folder",
        root=str(write_meshes(tmp_path / "meshes")),
        intrinsics=SMALL_CAMERA,
        n_gt=1000,
        points_per_view=50,
        backend="raycast",
        progress=False,
    )
    base.update(overrides)
    return Settings(**base)
