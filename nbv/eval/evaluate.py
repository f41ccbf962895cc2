"""The evaluation: every selected method on every selected model, viewspace and start view.

Order of work: the settings are already valid (:class:`nbv.eval.config.EvalSettings`); the
datasets are opened (and ``mesh_dir`` prepared) and checked against the viewspaces and start
views; the network checkpoints are loaded, a method whose checkpoint is missing or unusable is
skipped with the reason; then every episode runs under one progress bar, the methods first,
the disturbance checks after. Every finished model is logged (:mod:`nbv.eval.episode_log`),
so an interrupted evaluation resumes where it stopped. :func:`run` also writes the outputs
(:mod:`nbv.eval.report`) and the plots (:mod:`nbv.eval.plots`).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import nbv.dataset
from nbv.eval.config import EvalSettings
from nbv.eval.disturb import disturbed, noise_check
from nbv.eval.episode_log import LOG_NAME, EpisodeLog, identity
from nbv.eval.inputs import (
    DatasetInfo,
    EvalDataError,
    dataset_context,
    exclude_selection,
    open_inputs,
    with_shipped_weights,
)
from nbv.eval.metrics import ModelMetrics, fill_metrics
from nbv.eval.prepare import read_model
from nbv.eval.protocol import EpisodeRecord, episode_record, episode_rng
from nbv.infogain.gain_scorer import load_scorer
from nbv.policies.episode import Episode, run_episode
from nbv.policies.lockstep import EpisodeSpec, run_lockstep
from nbv.policies.method import MethodContext
from nbv.policies.registry import METHODS, SCORED, check_methods, networks_of

log = logging.getLogger(__name__)


@dataclass
class Evaluation:
    """Everything the report needs.

    Attributes:
        settings: the settings it ran with.
        records: every episode, the methods' and the checks'.
        skipped: method -> why it did not run (``<method> on <viewspace>`` for a method that
            ran on other viewspaces).
        datasets: the evaluated datasets.
        seconds: wall time of the episodes run by this call.
        resumed: how many of the records were read back from the episode log of an earlier,
            interrupted run instead of run again.
    """

    settings: EvalSettings
    records: list[EpisodeRecord]
    skipped: dict[str, str]
    datasets: list[DatasetInfo]
    seconds: float
    resumed: int = 0


class Job(NamedTuple):
    """One episode to run on every model: the method, its disturbance (``kind``: the check,
    ``check``: its record name, ``sigma``: a position noise), viewspace, start view and repeat."""

    method: str
    check: str | None
    kind: str | None
    viewspace: str
    start: int
    repeat: int = 0
    sigma: float = 0.0


def _jobs(settings: EvalSettings, runnable: list[str], skip: dict[str, str]) -> list[Job]:
    """The episodes to run on every model: the methods (a stochastic one ``random_repeats``
    times), then the checks (position noise once per sigma); none of a method on a viewspace
    ``skip`` names (``<method> on <viewspace>``)."""
    jobs = [
        Job(m, None, None, vs, start, r)
        for vs in settings.viewspaces
        for m in runnable
        if f"{m} on {vs}" not in skip
        for start in settings.start_views
        for r in range(settings.random_repeats if METHODS[m].stochastic else 1)
    ]
    for vs in settings.check_viewspaces:
        for check in settings.disturb.checks:
            sigmas = settings.disturb.noise if check == "position_noise" else (0.0,)
            for sigma in sigmas:
                name = noise_check(sigma) if check == "position_noise" else check
                jobs += [
                    Job(m, name, check, vs, start, 0, sigma)
                    for m in check_methods(check)
                    if m in runnable and f"{m} on {vs}" not in skip
                    for start in settings.check_start_views
                ]
    return jobs


class ModelTask(NamedTuple):
    """One model's episodes, as a worker process runs them (everything in it pickles)."""

    settings: EvalSettings
    dataset: str
    path: Path
    key: str
    jobs: list[Job]
    ctx: MethodContext
    rendered: Path | None = None


class ModelResult(NamedTuple):
    """What a worker returns for one model: its records and its ground truth's hull."""

    dataset: str
    key: str
    records: list[EpisodeRecord]
    gt_hull_error: str
    gt_hull_volume: float


def playable_jobs(jobs: list, gt_hull_volume: float, key: str) -> list:
    """The jobs a model can play: those of a method greedy by the true VIG (``oracle_vig``) need
    a ground truth with a hull volume, which a flat object lacks (its VIG is undefined); they
    are left out for it, with a warning, as its VIG curves are left out of the VIG tables."""
    if math.isfinite(gt_hull_volume) and gt_hull_volume > 0:
        return list(jobs)
    needs = {m for m in {j.method for j in jobs}
             if METHODS[m].ground_truth and METHODS[m].score == "vig"}  # fmt: skip
    if needs:
        log.warning("%s: %s left out: the ground truth's hull has no volume, VIG is undefined",
                    key, ", ".join(sorted(needs)))  # fmt: skip
    return [j for j in jobs if j.method not in needs]


def run_model(task: ModelTask) -> ModelResult:
    """Every job's episode on one model (in a worker process, or in this one), with its metrics
    (:mod:`nbv.eval.metrics`: the ground truth's KD-tree and each view's distances computed once
    for all the model's episodes).

    With ``settings.batched`` the episodes of each method (its checks included) run in lockstep
    (:func:`nbv.policies.lockstep.run_lockstep`): a network decides for all of them in one
    batched forward pass. The episodes are those of one-at-a-time runs."""
    settings, ds = task.settings, nbv.dataset.open(task.path)
    model = read_model(ds, task.rendered, task.key, settings.viewspaces)
    metrics = ModelMetrics(model, task.ctx.eps)
    jobs = playable_jobs(task.jobs, model.gt_hull_volume, task.key)
    policies = []
    for job in jobs:
        # Repeat 0 keeps the generator of a single run: one seed's numbers stay.
        names = (job.method, job.check or "", task.key, job.viewspace, job.start)
        rng = episode_rng(settings.seed, *names, *([job.repeat] if job.repeat else []))
        policy = METHODS[job.method].build(task.ctx, rng)
        if job.kind is not None:
            policy = disturbed(job.kind, policy, rng, settings.disturb.radius, job.sigma)
        policies.append(policy)
    episodes: list[Episode | None] = [None] * len(jobs)
    if settings.batched:
        by_method: dict[str, list[int]] = {}
        for i, job in enumerate(jobs):
            by_method.setdefault(job.method, []).append(i)
        for indices in by_method.values():
            specs = [EpisodeSpec(jobs[i].viewspace, jobs[i].start, policies[i])
                     for i in indices]  # fmt: skip
            for i, episode in zip(indices, run_lockstep(model, specs, settings.n_views),
                                  strict=True):  # fmt: skip
                episodes[i] = episode
    else:
        episodes = [run_episode(model, job.viewspace, job.start, policy, settings.n_views)
                    for job, policy in zip(jobs, policies, strict=True)]  # fmt: skip
    records = []
    for job, policy, episode in zip(jobs, policies, episodes, strict=True):
        record = episode_record(model, job.viewspace, job.start, job.method, policy,
                                task.dataset, episode, job.check, job.repeat)  # fmt: skip
        record.metrics = metrics.episode(job.viewspace, record.views, record.coverage)
        records.append(record)
    return ModelResult(task.dataset, task.key, records, model.gt_hull_error, model.gt_hull_volume)


def _worker_start(threads: int) -> None:
    import torch
    from threadpoolctl import threadpool_limits

    torch.set_num_threads(threads)
    # numpy's BLAS too: with its default pool a worker ran 2 BLAS threads beside torch's on a
    # core, and PCNBV-sph's signature step took 8x as long (0.062 s an episode, 0.008 s so).
    threadpool_limits(limits=threads, user_api="blas")


def worker_count(settings: EvalSettings) -> int:
    """Worker processes of a run: ``settings.workers``, or one per available core (at most 8)
    when it is 0."""
    if settings.workers:
        return settings.workers
    return max(1, min(8, len(os.sched_getaffinity(0))))


def _gather(opened: list, done_before: dict, results: dict) -> tuple[list[EpisodeRecord], int]:
    """Every model's records in the datasets' order, read back or just run, noting in each
    dataset's info the models whose ground-truth hull failed or is flat.

    Returns:
        ``(records, filled)``: ``filled`` episodes read back got their metrics computed.
    """
    records: list[EpisodeRecord] = []
    filled = 0
    for info, ds in opened:
        for key in info.keys:
            if (info.name, key) in done_before:
                done = done_before[(info.name, key)]
                # A log written before the metrics existed: compute them from the views read
                # back (they are functions of the views and the dataset alone).
                lacking = sorted({r.viewspace for r in done if not r.metrics})
                model = read_model(ds, info.rendered, key, tuple(lacking))
                filled += fill_metrics(done, model, float(ds.attrs["eps"]))
                records += done
                error, volume = model.gt_hull_error, model.gt_hull_volume
            else:
                result = results[(info.name, key)]
                records += result.records
                error, volume = result.gt_hull_error, result.gt_hull_volume
            if error:
                info.qhull_failures.append((key, error))
            elif not volume > 0:
                info.flat.append(key)
    return records, filled


def evaluate(settings: EvalSettings) -> Evaluation:
    """Run every episode of the settings (see the module docstring)."""
    from tqdm import tqdm

    opened, networks, skipped, skip_on = open_inputs(settings)
    for method, reason in skipped.items():
        log.warning("skipping %s: %s", method, reason)
    for info, ds in opened:
        exclude_selection(info, ds, networks)
    if settings.threads:
        import torch

        torch.set_num_threads(settings.threads)
    runnable = [m for m in settings.methods if m not in skipped]
    jobs = _jobs(settings, runnable, skip_on)
    if not jobs or not any(info.keys for info, _ in opened):
        why = "; ".join(f"{m}: {r}" for m, r in skipped.items()) or "no model to run on"
        raise EvalDataError(f"methods={list(settings.methods)}: no episode can run ({why})")
    scorer_file = settings.scorer_file() if set(SCORED) & set(runnable) else None
    scorer = load_scorer(scorer_file) if scorer_file else None
    ident = identity(
        settings,
        [Path(settings.checkpoints[m]) for m in networks_of(runnable)]
        + ([scorer_file] if scorer_file else []),
        [info.path for info, _ in opened],
    )
    episodes = EpisodeLog(settings.out_dir / LOG_NAME, ident)
    if episodes.done:
        log.info("resuming: %d models done in %s", len(episodes.done), episodes.path)
    total = sum(len(info.keys) for info, _ in opened) * len(jobs)
    tasks, done_before = [], {}
    for info, ds in opened:
        ctx = dataset_context(settings, ds, networks, scorer)
        for key in info.keys:
            done = episodes.done.get((info.name, key))
            if done is None:
                tasks.append(
                    ModelTask(settings, info.name, info.path, key, jobs, ctx, info.rendered)
                )
            else:
                done_before[(info.name, key)] = done
    bar = tqdm(total=total, desc="episodes", unit="ep", disable=not settings.progress)
    bar.update(sum(len(d) for d in done_before.values()))
    t0 = time.perf_counter()
    results: dict[tuple[str, str], ModelResult] = {}
    with _pool(worker_count(settings), settings.threads or 1, len(tasks)) as pool:
        for n, result in enumerate(pool(run_model, tasks), 1):
            episodes.append(result.dataset, result.key, result.records)
            results[(result.dataset, result.key)] = result
            bar.update(len(result.records))
            log.info("%s/%s done (%d of %d models, %.0f s so far)", result.dataset, result.key,
                     n, len(tasks), time.perf_counter() - t0)  # fmt: skip
    bar.close()
    seconds = time.perf_counter() - t0
    records, filled = _gather(opened, done_before, results)
    resumed = sum(len(d) for d in done_before.values())
    if filled:
        log.info("computed the metrics of %d episodes read back without them", filled)
    return Evaluation(settings, records, skipped, [info for info, _ in opened], seconds, resumed)


@contextlib.contextmanager
def _pool(workers: int, threads: int, tasks: int):
    """``map(fn, items)`` with the results in the order they finish: in this process (the items'
    order), or over ``workers`` spawned processes, with ``threads`` torch and BLAS threads each
    either way (spawned: forking a process that ran OpenMP is unsafe).

    Finish order, not the items' order: the caller logs each model as it ends, so that a run
    killed while one slow model is still running keeps every model that finished after it."""
    if workers <= 1 or tasks <= 1:
        # The workers' thread limits here too: with the default pools a run of workers=1 took
        # 1-2 minutes a YCB model beside other jobs, its BLAS and torch threads oversubscribing.
        _worker_start(threads)
        yield map
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(
        min(workers, tasks), mp_context=context, initializer=_worker_start, initargs=(threads,)
    ) as executor:

        def finished(fn, items):
            return (f.result() for f in as_completed([executor.submit(fn, i) for i in items]))

        yield finished


def run(settings: EvalSettings) -> Path:
    """Evaluate, then write results.json, summary.csv, report.md and the plots.

    Returns:
        The output folder.
    """
    from nbv.eval.report import write_outputs

    evaluation = evaluate(with_shipped_weights(settings))
    # The numbers first: a failure while drawing must not lose them. report.md is written
    # again after the plots, to show them.
    body = write_outputs(evaluation)
    if settings.plots:
        from nbv.eval.plots import draw_all

        draw_all(evaluation)
        write_outputs(evaluation, report_only=True, body=body)
    return settings.out_dir
