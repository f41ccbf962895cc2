"""Small datasets for tests: a folder of meshes written on the spot, tiny cameras, ray casting."""

from __future__ import annotations

from pathlib import Path

import trimesh

from nbv.dataset.generator import generate
from nbv.dataset.generator_settings import GeneratorSettings, Renderer, Synthetic
from nbv.dataset.samples import SampleSettings, write_samples
from nbv.geometry.camera import Intrinsics
from nbv.infogain.settings import InfoGainSettings

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


def small_settings(tmp_path: Path, **overrides) -> GeneratorSettings:
    """The folder source of :func:`write_meshes`, ray cast with the small camera; ``overrides``
    are fields of :class:`GeneratorSettings`."""
    base = dict(
        out_dir=tmp_path / "out",
        source="folder",
        root=str(write_meshes(tmp_path / "meshes")),
        intrinsics=SMALL_CAMERA,
        n_gt=1000,
        points_per_view=50,
        renderer=Renderer(backend="raycast"),
        progress=False,
    )
    base.update(overrides)
    return GeneratorSettings(**base)


def make_train_dataset(out: Path) -> Path:
    """One train and one valid synthetic model per training category, ray cast at 48 x 36, with
    coverage samples."""
    settings = GeneratorSettings(
        out_dir=out,
        synthetic=Synthetic(counts={"train": 1, "valid": 1, "test": 0, "unseen": 0}),
        intrinsics=Intrinsics.centred(48, 36, 36.0),
        n_gt=1024,
        points_per_view=64,
        renderer=Renderer(backend="raycast"),
        progress=False,
    )
    summary = generate(settings)
    assert summary.produced == 16
    write_samples(
        summary.shard_file,
        SampleSettings(trajectories=2, steps=4, n_points=64, lmax=2, scores=("coverage",)),
        progress=False,
    )
    return out


def make_tiny_dataset(out: Path, models: int = 2, keep_depth: bool = False) -> Path:
    """The first ``models`` synthetic models of the unseen categories (split test), ray cast
    with a 64 x 48 camera, 1000 ground-truth points, 50 stored points a view (and the
    full-resolution depth with ``keep_depth``)."""
    summary = generate(
        GeneratorSettings(
            out_dir=out,
            synthetic=Synthetic(counts={"train": 0, "valid": 0, "test": 0, "unseen": 1}),
            limit=models,
            intrinsics=SMALL_CAMERA,
            n_gt=1000,
            points_per_view=50,
            keep_depth=keep_depth,
            renderer=Renderer(backend="raycast"),
            progress=False,
        )
    )
    assert summary.produced == models, summary
    return out


#: The information-gain planner on the small camera: coarse voxels, 4-pixel background blocks.
INFOGAIN = InfoGainSettings(resolution=0.04, columns=8, block=4)
