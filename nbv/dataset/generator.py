"""Dataset generation: render every model of a shard, score its views, write the shard file.

The work of one shard:

1. list the source's models and keep those with ``index % num_shards == shard``;
2. skip the models already complete (in the shard file or in a part file of an interrupted run);
3. for the rest, one at a time as a renderer process asks for its next mesh: normalise the mesh,
   sample the ground truth, render both viewspaces; then, as each model's depth arrives,
   back-project, compute coverage bits from the full-resolution views, subsample the clouds,
   write the model's part file atomically;
4. assemble the shard file from the parts (atomically) and remove the parts.

Every random draw of a model comes from a generator seeded by ``(seed, key)``, so an interrupted
and resumed run writes the same arrays as an uninterrupted one.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from nbv.assets.mesh_sources import MESH_SOURCES
from nbv.assets.meshes import MeshError, sample_surface
from nbv.dataset.generator_settings import GeneratorSettings
from nbv.dataset.records import ModelData
from nbv.dataset.samples import SampleSettings, samples_path, samples_up_to_date, write_samples
from nbv.dataset.schema import SCHEMA_VERSION, assemble_shard, config_json, write_part
from nbv.dataset.sources import SourceModel, list_models, load_normalised
from nbv.dataset.views import view_data
from nbv.geometry.camera import viewspace_poses
from nbv.geometry.hull import QhullFailure, hull_volume
from nbv.geometry.viewspace import get_viewspace
from nbv.render.backends import render
from nbv.render.job import RenderError, RenderJob
from nbv.render.noise import noisy_depth
from nbv.render.preflight import check_blender
from nbv.utils.atomic import write_text
from nbv.utils.fields import ConfigError
from nbv.utils.lock import one_writer
from nbv.utils.seeding import named_rng

__all__ = [
    "Summary",
    "exit_status",
    "generate",
    "nothing_made",
    "report",
    "run",
    "shard_name",
    "view_data",
]

log = logging.getLogger(__name__)


@dataclass
class Summary:
    """What one run of a shard did."""

    shard_file: Path
    total: int = 0
    skipped: int = 0
    produced: int = 0
    failures: list[tuple[str, str]] = field(default_factory=list)

    @property
    def complete(self) -> int:
        return self.skipped + self.produced

    def __str__(self) -> str:
        lines = [
            f"{self.shard_file}: {self.complete}/{self.total} models "
            f"({self.produced} made now, {self.skipped} already done, {len(self.failures)} failed)"
        ]
        lines += [f"  failed {key}: {reason}" for key, reason in self.failures]
        return "\n".join(lines)


def shard_name(shard: int, num_shards: int) -> str:
    """File name of a shard: ``shard-00003-of-00008.h5``."""
    return f"shard-{shard:05d}-of-{num_shards:05d}.h5"


def _completed_keys(shard_file: Path, parts_dir: Path) -> tuple[dict[str, Path], list]:
    """Models already complete (key -> file holding them) and the failures recorded before."""
    done: dict[str, Path] = {}
    failures: list = []
    if shard_file.exists():
        with h5py.File(shard_file, "r") as handle:
            done.update({key: shard_file for key in handle.get("models", {})})
            if "failures" in handle:
                failures = [tuple(s.decode() for s in row) for row in handle["failures"][()]]
    if parts_dir.exists():
        done.update({p.stem: p for p in sorted(parts_dir.glob("*.h5"))})
    return done, failures


def _check_identity(settings: GeneratorSettings, shard_file: Path, parts_dir: Path) -> None:
    """Refuse to mix data made with other settings into an existing shard."""
    wanted = config_json(settings.data_identity())
    found = None
    if shard_file.exists():
        with h5py.File(shard_file, "r") as handle:
            found = handle.attrs.get("config")
    elif (parts_dir / "config.json").exists():
        found = (parts_dir / "config.json").read_text()
    if found is not None and found != wanted:
        old, new = json.loads(found), json.loads(wanted)
        differ = {k: (old.get(k), new.get(k)) for k in new if old.get(k) != new.get(k)}
        raise ConfigError(
            f"{settings.out_dir} holds data made with other settings {differ} (old, new); "
            "use another out_dir or delete that folder"
        )
    parts_dir.mkdir(parents=True, exist_ok=True)
    write_text(parts_dir / "config.json", wanted)


def _root_attrs(settings: GeneratorSettings) -> dict:
    return {
        "schema_version": SCHEMA_VERSION,
        "eps": settings.eps,
        "n_gt": settings.n_gt,
        **settings.intrinsics.as_dict(),
        "seed": settings.seed,
        "licence": MESH_SOURCES[settings.source].licence,
        "config": config_json(settings.data_identity()),
    }


@dataclass
class _Prepared:
    model: SourceModel
    center: np.ndarray
    scale: float
    gt_points: np.ndarray
    rng: np.random.Generator


def _prepare(model: SourceModel, settings: GeneratorSettings, poses: np.ndarray):
    """Normalise the mesh and sample the ground truth: (render job, prepared) of one model."""
    rng = named_rng(settings.seed, model.key)
    mesh, center, scale = load_normalised(model, settings.seed)
    gt = sample_surface(mesh, settings.n_gt, rng)
    job = RenderJob(model.key, mesh.vertices, mesh.faces, poses)
    return job, _Prepared(model, center, scale, gt, rng)


def _finish(
    prep: _Prepared, depth: np.ndarray, poses: dict, settings: GeneratorSettings
) -> ModelData:
    """Turn one model's rendered depth (all viewspaces stacked) into its dataset record (the
    sensor model of ``settings.noise`` applied first, seeded by the seed and the model)."""
    if settings.noise is not None:
        rng = named_rng(settings.seed, "depth-noise", prep.model.key)
        depth = noisy_depth(depth, settings.intrinsics, settings.noise, rng)
    views, start = {}, 0
    for name, vs_poses in poses.items():
        stop = start + len(vs_poses)
        views[name] = view_data(
            depth[start:stop],
            vs_poses,
            settings.intrinsics,
            prep.gt_points,
            settings.eps,
            settings.points_per_view,
            prep.rng,
            settings.keep_depth,
        )
        start = stop
    m = prep.model
    try:
        gt_volume, gt_error = hull_volume(prep.gt_points), ""
    except QhullFailure as err:
        gt_volume, gt_error = float("nan"), str(err)
        log.warning("%s: the ground truth's hull is unknown (VIG undefined): %s", m.key, err)
    return ModelData(
        key=m.key,
        category=m.category,
        split=m.split,
        source=m.source,
        source_path=m.source_path,
        center=prep.center,
        scale=prep.scale,
        seed=settings.seed,
        gt_points=prep.gt_points,
        gt_hull_volume=gt_volume,
        views=views,
        gt_hull_error=gt_error,
    )


def _shard_models(settings: GeneratorSettings) -> list:
    """The models of the source that this shard makes, in order: those of ``models`` when it is
    set, every ``num_shards``-th from ``shard`` on, the first ``limit`` of them."""
    models = list_models(
        settings.source,
        settings.root,
        list(settings.categories) if settings.categories else None,
        settings.synthetic.counts,
        settings.split_fractions,
        settings.seed,
    )
    if settings.models is not None:
        wanted = set(settings.models)
        models = [m for m in models if m.key in wanted]
    mine = models[settings.shard :: settings.num_shards]
    return mine if settings.limit is None else mine[: settings.limit]


def generate(settings: GeneratorSettings) -> Summary:
    """Generate (or resume) one shard of a dataset; see the module docstring.

    Returns:
        The run's :class:`Summary`; per-model failures are recorded, not raised.
    """
    mine = _shard_models(settings)
    renderer = settings.renderer
    if renderer.backend == "blender" and renderer.blender is not None and mine:
        # A cluster's binary is tried once on a tiny scene, before anything is written: without
        # numpy, of another version or rendering nothing it would fail every model one by one.
        check_blender(renderer.blender, renderer.threads, renderer.device)
    out_dir = Path(settings.out_dir)
    name = shard_name(settings.shard, settings.num_shards)
    shard_file = out_dir / name
    parts_dir = out_dir / f".parts-{name[:-3]}"
    # A second process on this shard (a requeued SLURM task whose first copy still runs) is
    # refused, naming the first; a killed one's lock goes with it.
    with one_writer(shard_file, "dataset shard"):
        return _generate(settings, mine, shard_file, parts_dir)


def _generate(
    settings: GeneratorSettings, mine: list, shard_file: Path, parts_dir: Path
) -> Summary:
    """:func:`generate`'s work, under the shard's lock."""
    out_dir, name = shard_file.parent, shard_file.name
    _check_identity(settings, shard_file, parts_dir)
    viewspaces = {n: get_viewspace(v) for n, v in settings.viewspaces.items()}
    poses = {n: viewspace_poses(vs) for n, vs in viewspaces.items()}
    all_poses = np.concatenate(list(poses.values()))
    root_attrs = _root_attrs(settings)

    render_options = settings.render_options(len(os.sched_getaffinity(0)))
    done, old_failures = _completed_keys(shard_file, parts_dir)
    summary = Summary(shard_file, total=len(mine), skipped=sum(m.key in done for m in mine))
    todo = [m for m in mine if m.key not in done]
    bar = tqdm(
        total=len(mine),
        initial=summary.skipped,
        desc=name,
        unit="model",
        disable=not settings.progress,
    )
    prepared: dict[str, _Prepared] = {}
    unprepared: dict[str, str] = {}

    def jobs() -> Iterator[RenderJob]:
        """Each model's render job, prepared when a renderer process asks for its next mesh."""
        for model in todo:
            try:
                job, prepared[model.key] = _prepare(model, settings, all_poses)
            except (MeshError, ValueError) as err:
                unprepared[model.key] = str(err)
                bar.update()
                continue
            yield job

    failed: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix="nbv-render-") as workdir:
        results = render(
            jobs(), settings.intrinsics, settings.renderer.backend, Path(workdir), **render_options
        )
        for key, depth in results:
            try:
                if isinstance(depth, Exception):
                    raise depth
                record = _finish(prepared.pop(key), depth, poses, settings)
                part = parts_dir / f"{key}.h5"
                write_part(part, root_attrs, viewspaces, record)
                done[key] = part
                summary.produced += 1
            except RenderError as err:
                failed[key] = str(err)
            bar.update()
    bar.close()
    # In model order: the processes finish models in an order that varies from run to run.
    failed |= unprepared
    summary.failures = [(m.key, failed[m.key]) for m in todo if m.key in failed]
    summary.failures += [(k, r) for k, r in old_failures if k not in done and k not in failed]
    sources = [(done[m.key], m.key) for m in mine if m.key in done]
    if sources or summary.failures:
        out_dir.mkdir(parents=True, exist_ok=True)
        assemble_shard(shard_file, root_attrs, viewspaces, sources, summary.failures)
    shutil.rmtree(parts_dir, ignore_errors=True)
    return summary


def run(settings: GeneratorSettings, sample_settings: SampleSettings | None) -> int:
    """Generate the shard, then its training samples; log the summary; return the exit status.

    Raises:
        ValueError: no model of the shard could be made (:func:`nothing_made` says why, in one
            line: a folder of unreadable meshes is bad input, refused like a bad setting).

    numpy's BLAS runs one thread here and in the samples' workers (forked, they inherit it): the
    renderer processes or the other workers already keep every core busy, and an idle OpenBLAS
    thread spins (``sched_yield``) after each product, taking a core's share from them.
    """
    with threadpool_limits(limits=1, user_api="blas"):
        summary = generate(settings)
        if exit_status(summary):
            raise ValueError(nothing_made(summary))
        report(summary)
        if sample_settings is not None and summary.shard_file.exists() and summary.complete:
            if samples_up_to_date(summary.shard_file, sample_settings):
                log.info("%s: up to date", samples_path(summary.shard_file))
            else:
                out, skipped = write_samples(summary.shard_file, sample_settings, settings.progress)
                log.info("%s: written", out)
                for key, score, reason in skipped:
                    log.info("  skipped %s (%s): %s", key, score, reason)
    return exit_status(summary)


def exit_status(summary: Summary) -> int:
    """0 when the shard holds a model (or had nothing to do); 1 when nothing could be made."""
    return 1 if summary.total > 0 and summary.complete == 0 else 0


def nothing_made(summary: Summary, shown: int = 3) -> str:
    """One line: none of the shard's models could be made, with the first ``shown`` reasons."""
    reasons = "; ".join(f"{key}: {why}" for key, why in summary.failures[:shown])
    more = len(summary.failures) - shown
    tail = f"; and {more} more" if more > 0 else ""
    name, total = summary.shard_file.name, summary.total
    return f"{name}: none of its {total} models could be made ({reasons}{tail})"


def report(summary: Summary) -> None:
    """Log the run's summary for a person (a warning when models failed)."""
    log.log(logging.WARNING if summary.failures else logging.INFO, "%s", summary)
