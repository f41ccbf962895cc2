"""Data the evaluation renders itself, through the dataset pipeline, cached by content.

:func:`prepare_meshes`: a folder of meshes (or a real source: YCB, the scans) turned into a
dataset. :func:`rendered_viewspaces`:
the views of a viewspace a dataset lacks (``protocol=hemisphere_30`` on the default dataset),
rendered for its models with the settings it recorded.

A mesh folder is rendered from both viewspaces and scored exactly like a generated dataset
(:func:`nbv.dataset.generator.generate` with ``source="folder"``). The result lives in
``<cache_dir>/<hash>/``, where the hash covers the mesh files (relative path, size, modification
time) and every setting that shapes the data, ``eps`` and the coverage test included; a later
evaluation with the same folder and settings reuses it instead of rendering again.
"""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path

import numpy as np

import nbv.dataset
from nbv.assets.meshes import MESH_SUFFIXES
from nbv.dataset.generator import generate
from nbv.dataset.generator_settings import GeneratorSettings, Renderer
from nbv.dataset.reader import Dataset
from nbv.dataset.records import ModelData
from nbv.eval.config import PrepareSettings
from nbv.geometry.scores import COVERAGE_TEST
from nbv.geometry.viewspace import is_named
from nbv.utils.atomic import write_text

log = logging.getLogger(__name__)

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


def identity(mesh_dir: Path, settings: PrepareSettings, source: str = "folder") -> dict:
    """What determines a prepared dataset: the files of ``mesh_dir``, the source that lists them
    and the settings."""
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
        # Only for the named sources: the caches of mesh folders made before keep their hash.
        **({"source": source} if source != "folder" else {}),
    }


def prepared_dir(mesh_dir: Path, settings: PrepareSettings, source: str = "folder") -> Path:
    """``<settings.dir>/<16 hex digits of the identity's hash>``."""
    text = json.dumps(identity(mesh_dir, settings, source), sort_keys=True)
    return Path(settings.dir) / hashlib.sha256(text.encode()).hexdigest()[:16]


def prepare_meshes(
    mesh_dir: Path, settings: PrepareSettings, progress: bool = True, source: str = "folder"
) -> tuple[Path, list[tuple[str, str]]]:
    """Render and score every mesh of ``mesh_dir``, or reuse the cached result.

    Args:
        mesh_dir: folder of mesh files (searched recursively).
        settings: how to render and score.
        progress: show the generator's progress bar.
        source: the dataset source that lists the meshes of ``mesh_dir`` (their keys and
            categories): ``folder``, ``ycb`` or ``scans``.

    Returns:
        ``(folder, failures)``: the dataset folder (open it with ``nbv.dataset.open``) and
        ``(key, reason)`` of each mesh that could not be used (unreadable, empty render).
    """
    out = prepared_dir(mesh_dir, settings, source)
    done = out / DONE_FILE
    if done.exists():
        return out, [tuple(f) for f in json.loads(done.read_text())["failures"]]
    summary = generate(
        GeneratorSettings(
            out_dir=out,
            source=source,
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
    record = {"identity": identity(mesh_dir, settings, source), "failures": summary.failures}
    write_text(done, json.dumps(record, indent=1))
    return out, [tuple(f) for f in summary.failures]


def stored_name(viewspace: str) -> str:
    """The name a rendered viewspace has in its dataset: a generated or shipped name as it is,
    a file ``file-<12 hex digits of its path's hash>`` (an HDF5 group name has no ``/``)."""
    if is_named(viewspace):
        return viewspace
    return "file-" + hashlib.sha256(str(Path(viewspace).resolve()).encode()).hexdigest()[:12]


def viewspace_sources(names: list[str]) -> dict[str, str]:
    """stored name (:func:`stored_name`) -> what :func:`nbv.geometry.viewspace.get_viewspace`
    reads: a generated or shipped name as it is, a file by its absolute path."""
    return {stored_name(n): n if is_named(n) else str(Path(n).resolve()) for n in names}


def rendered_viewspaces(
    dataset_dir: Path,
    config: dict,
    names: list[str],
    keys: list[str],
    cache_dir: Path,
    progress: bool = True,
) -> Path:
    """The views of ``names`` that a dataset lacks, rendered for its models ``keys`` with the
    settings it recorded (its renderer, camera, seed, ground truth, eps, points kept), or the
    cached result of an earlier call.

    The ground truth of every model is the dataset's (the same seed draws it), so the new
    viewspaces' coverage bits score against the same points; the caller checks that.

    Args:
        dataset_dir: the dataset's folder (for messages).
        config: the generation settings it recorded (root attribute ``config``, parsed).
        names: viewspace names or files.
        keys: the models to render.
        cache_dir: where rendered viewspaces are kept (``prepare.dir``).
        progress: show the generator's progress bar.

    Returns:
        The folder of a dataset holding those viewspaces of those models, each under its
        :func:`stored_name`.

    Raises:
        ValueError: a dataset whose settings were not recorded, of another schema, or models
            that could not be rendered (named).
    """
    if not config:
        raise ValueError(
            f"{dataset_dir}: the dataset records no generation settings, so its views of "
            f"{', '.join(names)} cannot be rendered; make a dataset with them "
            f"(python -m nbv.dataset viewspaces=[{','.join(names)}])"
        )
    sources = viewspace_sources(names)
    files = {n: hashlib.sha256(Path(p).read_bytes()).hexdigest() for n, p in sources.items()
             if not is_named(p)}  # fmt: skip
    ident = {"dataset": config, "viewspaces": sources, "files": files, "models": sorted(keys),
             "coverage_test": COVERAGE_TEST}  # fmt: skip
    text = json.dumps(ident, sort_keys=True)
    out = Path(cache_dir) / f"viewspaces-{hashlib.sha256(text.encode()).hexdigest()[:16]}"
    done = out / DONE_FILE
    if done.exists():
        return out
    log.info("rendering viewspaces %s for %d models of %s (once; cached in %s)",
             ", ".join(names), len(keys), dataset_dir, out)  # fmt: skip
    settings = GeneratorSettings.from_identity(
        config, out, viewspaces=sources, models=tuple(sorted(keys)), progress=progress
    )
    summary = generate(settings)
    if summary.failures:
        reasons = "; ".join(f"{k}: {r}" for k, r in summary.failures)
        raise ValueError(
            f"{dataset_dir}: rendering viewspaces {', '.join(names)} failed ({reasons})"
        )
    write_text(done, json.dumps({"identity": ident, "failures": []}, indent=1))
    return out


def read_model(
    ds: Dataset, rendered: Path | None, key: str, viewspaces: tuple[str, ...]
) -> ModelData:
    """One model with the views of ``viewspaces``: from the dataset, and those it lacks from
    the viewspaces the evaluation rendered (``rendered``), under the names the settings give.

    Raises:
        ValueError: the rendered views' ground truth is not the dataset's (the dataset was
            made again since they were rendered, under other settings).
    """
    own = tuple(vs for vs in viewspaces if vs in ds.viewspaces)
    model = ds.model(key, viewspaces=own)
    lacking = [vs for vs in viewspaces if vs not in ds.viewspaces]
    if lacking:
        extra = nbv.dataset.open(rendered).model(key, tuple(stored_name(v) for v in lacking))
        if not np.array_equal(extra.gt_points, model.gt_points):
            raise ValueError(
                f"{rendered}: model {key!r}: the rendered viewspaces' ground truth is not the "
                "dataset's; delete that folder to render them again"
            )
        model.views.update({vs: extra.views[stored_name(vs)] for vs in lacking})
    return model
