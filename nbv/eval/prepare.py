"""A folder of meshes turned into a dataset through the dataset pipeline, cached by content.

The folder is rendered from both viewspaces and scored exactly like a generated dataset
(:func:`nbv.dataset.generate.generate` with ``source="folder"``). The result lives in
``<cache_dir>/<hash>/``, where the hash covers the mesh files (relative path, size, modification
time) and every setting that shapes the data, ``eps`` and the coverage test included; a later
evaluation with the same folder and settings reuses it instead of rendering again.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from nbv.assets.meshes import MESH_SUFFIXES
from nbv.dataset.generate import generate
from nbv.dataset.generation import GenerationSettings, Renderer
from nbv.eval.config import PrepareSettings
from nbv.geometry.scores import COVERAGE_TEST

#: Written in a prepared folder once the dataset is complete.
DONE_FILE = "prepared.json"


def _mesh_files(folder: Path) -> list[Path]:
    return sorted(
        p
        for p in folder.rglob("*")
        if p.is_file()
        and p.suffix.lower() in MESH_SUFFIXES
        and not any(part.startswith(".") for part in p.relative_to(folder).parts)
    )


def identity(mesh_dir: Path, settings: PrepareSettings) -> dict:
    """What determines a prepared dataset: the files of ``mesh_dir`` and the settings."""
    folder = Path(mesh_dir).resolve()
    files = []
    for p in _mesh_files(folder):
        stat = p.stat()
        files.append([str(p.relative_to(folder)), stat.st_size, stat.st_mtime_ns])
    return {
        "mesh_dir": str(folder),
        "files": files,
        "backend": settings.backend,
        "camera": [settings.camera.width, settings.camera.height, settings.camera.fx],
        "n_gt": settings.n_gt,
        # eps and the test itself: a cache made under another criterion is never reused.
        "eps": settings.eps,
        "coverage_test": COVERAGE_TEST,
        "points_per_view": settings.points_per_view,
        "seed": settings.seed,
    }


def prepared_dir(mesh_dir: Path, settings: PrepareSettings) -> Path:
    """``<settings.dir>/<16 hex digits of the identity's hash>``."""
    text = json.dumps(identity(mesh_dir, settings), sort_keys=True)
    return Path(settings.dir) / hashlib.sha256(text.encode()).hexdigest()[:16]


def prepare_meshes(
    mesh_dir: Path, settings: PrepareSettings, progress: bool = True
) -> tuple[Path, list[tuple[str, str]]]:
    """Render and score every mesh of ``mesh_dir``, or reuse the cached result.

    Args:
        mesh_dir: folder of mesh files (searched recursively).
        settings: how to render and score.
        progress: show the generator's progress bar.

    Returns:
        ``(folder, failures)``: the dataset folder (open it with ``nbv.dataset.open``) and
        ``(key, reason)`` of each mesh that could not be used (unreadable, empty render).
    """
    out = prepared_dir(mesh_dir, settings)
    done = out / DONE_FILE
    if done.exists():
        return out, [tuple(f) for f in json.loads(done.read_text())["failures"]]
    summary = generate(
        GenerationSettings(
            out_dir=out,
            source="folder",
            root=str(mesh_dir),
            seed=settings.seed,
            intrinsics=settings.camera,
            n_gt=settings.n_gt,
            eps=settings.eps,
            points_per_view=settings.points_per_view,
            renderer=Renderer(backend=settings.backend, blender=settings.blender),
            progress=progress,
        )
    )
    if summary.complete == 0:
        reasons = "; ".join(f"{k}: {r}" for k, r in summary.failures) or "no mesh files"
        raise ValueError(f"mesh_dir={str(mesh_dir)!r}: no mesh could be prepared ({reasons})")
    record = {"identity": identity(mesh_dir, settings), "failures": summary.failures}
    done.write_text(json.dumps(record, indent=1))
    return out, [tuple(f) for f in summary.failures]
