"""One training run: leave-one-category-out, checkpoints, metrics, resumption.

Per epoch: a seeded shuffle of the training samples, batches of ``batch_size``, each cloud a seeded
random subset of ``train_points`` of its stored points (the signature is used whole), each
sample mapped by a random symmetry of its viewspace (``augment``, :mod:`train.augment`), loss =
``loss`` (:mod:`train.losses`, mean over the batch) + ``l2`` times the squared weights of
``l2_scope``. Then Spearman correlation (overall, at early steps 0-1 and at late steps 2 and
later: :func:`train.metrics.spearman_by_stage`) and best-view hits on a fixed 300 of the
training samples (unaugmented), and the validation loss, Spearman correlations and best-view hits
on the samples of the *valid* split of the fold's training categories, beside the same Spearman
correlations of two baselines there, computed once at the start
(:mod:`train.ranking_baselines`: a ridge regression fitted on the training samples, and the
spread rule's angle), and every ``eval_every`` epochs (and at the last) the reconstruction
metric there: coverage by view and AUC of the network's episodes from ``start_views`` on those
models. The held-out category takes no part in training or in choosing the checkpoint: it is
scored once, at the end, with the chosen one (:mod:`train.heldout`).

``out_dir`` gets ``last.pt`` (every epoch, with the optimizer state and the run's identity, for
resuming: :mod:`train.resume`), ``best.pt`` (``select=valid``: the best validation AUC;
``select=last``: the last epoch), ``metrics.csv`` (with the baselines' Spearman as constant
columns: ``ridge_val_spearman``, ``spread_val_spearman_late``, ...), ``baselines.json``,
``heldout.json`` (the held-out category's episodes of best.pt, random, spread and the oracle)
and TensorBoard logs in ``tb/``. Every random draw of an epoch comes from ``(seed, epoch)``, so a
resumed run continues exactly as an uninterrupted one would.
"""

from __future__ import annotations

import json
import logging
import time

import numpy as np
import torch
from tqdm import tqdm

import nbv.dataset
from nbv.dataset.samples import SampleSet, load_samples
from nbv.models.checkpoints import load_checkpoint, save_checkpoint
from nbv.models.inference import for_inference
from nbv.models.networks import fresh_network
from nbv.models.pcnbv import PCNBV
from nbv.models.precision import autocast, flush_denormals
from nbv.policies.episode import auc, run_episode
from nbv.policies.network import NetworkPolicy
from nbv.utils.atomic import write_text
from train.augment import Augmentation
from train.config import TrainSettings, stored_settings
from train.folds import fold_keys, split_samples
from train.heldout import heldout_result
from train.losses import batch_loss, weight_penalty
from train.metrics import SPEARMAN_FILE, ranking_metrics, spearman_by_model
from train.ranking_baselines import write_baselines
from train.resume import (
    checkpoint_extra,
    clear_run,
    resume_state,
    run_identity,
    samples_identity,
    save_last,
)
from train.run_log import append_csv_rows, dataset_identity

log = logging.getLogger(__name__)


def choose_device(name: str) -> torch.device:
    """``auto`` -> CUDA when present, else the CPU."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("device=cuda: no CUDA device here; use device=auto or device=cpu")
    return torch.device(name)


def batch_inputs(
    samples: SampleSet,
    index: np.ndarray,
    settings: TrainSettings,
    rng: np.random.Generator | None,
    augmentation: Augmentation | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(points (B, N, 3), view_state (B, V) float, target (B, V)) tensors of some samples.

    Clouds are reduced to ``train_points`` by a random subset per sample (``rng``), or to their
    first ``train_points`` farthest-point-sampled points when ``rng`` is None (validation). With
    an ``augmentation`` (and ``rng``) each sample is then mapped by a random symmetry of the
    viewspace.
    """
    if settings.model.input == "signature":
        points = samples.signature[index]
    else:
        points = samples.points[index]
        n = min(settings.train_points, points.shape[1])
        if rng is None:
            points = points[:, :n]
        else:
            pick = np.argsort(rng.random(points.shape[:2]), axis=1)[:, :n]
            points = np.take_along_axis(points, pick[..., None], axis=1)
    view_state, target = samples.view_state[index], samples.target[index]
    if augmentation is not None and rng is not None:
        points, view_state, target = augmentation.apply(
            points, view_state, target, rng, signature=settings.model.input == "signature"
        )
    return (
        torch.from_numpy(np.ascontiguousarray(points, dtype=np.float32)),
        torch.from_numpy(view_state.astype(np.float32)),
        torch.from_numpy(target.astype(np.float32)),
    )


def loss_fn(
    model: PCNBV,
    pred: torch.Tensor,
    target: torch.Tensor,
    view_state: torch.Tensor,
    settings: TrainSettings,
) -> torch.Tensor:
    """``settings.loss`` of the batch (:mod:`train.losses`) plus ``l2`` times
    :func:`weight_penalty` of ``l2_scope``."""
    penalty = weight_penalty(model, settings.l2_scope) if settings.l2 else 0.0
    return batch_loss(settings.loss, pred, target, view_state) + settings.l2 * penalty


def predict(
    model: PCNBV, samples: SampleSet, settings: TrainSettings, device: torch.device
) -> tuple[np.ndarray, float]:
    """Predicted gains of every sample (S, V) and the mean ``settings.loss`` (no penalty), in
    eval mode."""
    model.eval()
    preds = []
    with torch.no_grad():
        for start in range(0, len(samples), settings.batch_size):
            index = np.arange(start, min(start + settings.batch_size, len(samples)))
            x, s, _ = (a.to(device) for a in batch_inputs(samples, index, settings, None))
            with autocast(settings.precision, device):
                pred = model(x, s)
            preds.append(pred.float().cpu().numpy())
    pred = np.concatenate(preds)
    loss = batch_loss(
        settings.loss,
        torch.from_numpy(pred),
        torch.from_numpy(samples.target.astype(np.float32)),
        torch.from_numpy(samples.view_state.astype(np.float32)),
    )
    return pred, float(loss)


def fresh_training(
    settings: TrainSettings, n_views: int, device: torch.device
) -> tuple[PCNBV, torch.optim.Optimizer, torch.optim.lr_scheduler.StepLR]:
    """A fresh network of ``settings.model`` (its declared ``network``) with ``n_views``
    outputs (initialised from ``settings.seed``), its Adam optimiser at ``lr`` and the step decay
    of the learning rate."""
    torch.manual_seed(settings.seed)
    model = fresh_network(settings.model.network, n_views=n_views, **settings.model.net)
    model = model.to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=settings.lr)
    scheduler = torch.optim.lr_scheduler.StepLR(
        optimizer, settings.lr_step_epochs, settings.lr_decay
    )
    return model, optimizer, scheduler


def train_epoch(
    model: PCNBV,
    optimizer: torch.optim.Optimizer,
    train: SampleSet,
    settings: TrainSettings,
    epoch: int,
    device: torch.device,
    augmentation: Augmentation | None = None,
) -> dict[str, float]:
    """One epoch of training steps on ``train`` (a seeded shuffle from ``(seed, epoch)``,
    batches of ``batch_size``, :func:`loss_fn`); the learning rate is the caller's.

    Returns:
        ``{"train_loss"`` (mean over the batches), ``"samples_per_s"``, ``"load_fraction"``
        (of the time spent building batches)``}``.
    """
    rng = np.random.default_rng([settings.seed, epoch])
    torch.manual_seed(settings.seed * 100003 + epoch)
    model.train()
    order = rng.permutation(len(train))
    size = settings.batch_size
    batches = [order[i : i + size] for i in range(0, len(order), size)]
    load_time = step_time = 0.0
    losses = []
    bar = tqdm(batches, desc=f"epoch {epoch + 1}/{settings.epochs}", disable=not settings.progress)
    prepared = _batches(train, batches, settings, rng, augmentation, epoch, device)
    for index, tensors in zip(bar, prepared, strict=True):
        t0 = time.perf_counter()
        x, s, t = (a.to(device, non_blocking=True) for a in tensors)
        t1 = time.perf_counter()
        optimizer.zero_grad()
        with autocast(settings.precision, device):
            pred = model(x, s)
        loss = loss_fn(model, pred, t, s, settings)
        loss.backward()
        optimizer.step()
        t2 = time.perf_counter()
        load_time += t1 - t0
        step_time += t2 - t1
        losses.append(loss.item())
        bar.set_postfix(loss=f"{np.mean(losses[-20:]):.4f}", sps=f"{len(index) / (t2 - t0):.0f}")
    return {
        "train_loss": float(np.mean(losses)),
        "samples_per_s": len(train) / max(load_time + step_time, 1e-9),
        "load_fraction": load_time / max(load_time + step_time, 1e-9),
    }


def episodes_metric(dataset, keys: list[str], policy, start_views) -> np.ndarray:
    """(E, 10) coverage curves of ``policy`` on the original viewspace, every model and start."""
    out = []
    for key in keys:
        model = dataset.model(key, ("original",))
        for start in start_views:
            out.append(run_episode(model, "original", int(start), policy).coverage)
    return np.array(out)


def _batches(train, batches, settings: TrainSettings, rng, augmentation, epoch: int, device):
    """The epoch's input tensors, batch after batch.

    ``loader_workers=0``: built here, in order, from the epoch's generator ``rng``. Otherwise
    that many threads build them ahead, each batch from its own generator ``(seed, epoch,
    batch)`` (the same arrays for any number of workers, another draw than with 0). On CUDA with
    ``pin_memory`` the tensors are pinned, so the copy to the device overlaps the step.
    """
    pin = settings.pin_memory and device.type == "cuda"

    def build(index: np.ndarray, generator) -> tuple:
        tensors = batch_inputs(train, index, settings, generator, augmentation)
        return tuple(a.pin_memory() for a in tensors) if pin else tensors

    if settings.loader_workers == 0:
        for index in batches:
            yield build(index, rng)
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(settings.loader_workers) as pool:
        ahead = 2 * settings.loader_workers
        futures = []
        for i, index in enumerate(batches):
            generator = np.random.default_rng([settings.seed, epoch, i])
            futures.append(pool.submit(build, index, generator))
            if len(futures) > ahead:
                yield futures.pop(0).result()
        for future in futures:
            yield future.result()


def _augmentation(settings: TrainSettings, dataset, samples: SampleSet, lmax: int):
    """The samples' viewspace symmetries when ``augment`` is on and it has any, else None."""
    if not settings.augment:
        return None
    name = str(samples.attrs.get("viewspace", "original"))
    augmentation = Augmentation(dataset.viewspaces[name], lmax)
    log.info("augmentation: %d symmetries of the %s viewspace", len(augmentation), name)
    return augmentation if len(augmentation) > 1 else None


def run(settings: TrainSettings) -> dict:
    """Train one fold; returns the final metrics (see the module docstring).

    Subnormal floats count as zero meanwhile (:func:`nbv.models.precision.flush_denormals`): they
    appear as the weights train and slow every CPU step down several times.
    """
    with flush_denormals():
        return _train(settings)


def _network_policy(model: PCNBV, settings: TrainSettings, lmax: int) -> NetworkPolicy:
    return NetworkPolicy(
        for_inference(model, settings.precision), settings.model.input, settings.eval_points, lmax,
        settings.precision,
    )  # fmt: skip


def _ranking_row(model, val, probe, baselines: dict, settings: TrainSettings, device,
                 epoch: int) -> dict:  # fmt: skip
    """An epoch's validation loss and ranking, its ranking on the training probe, and the
    baselines' validation ranking (constant columns, for curves drawn against them); the
    validation Spearman by model is appended to its own file."""
    row: dict = {}
    if len(val):
        pred, val_loss = predict(model, val, settings, device)
        row.update(val_loss=val_loss, **ranking_metrics(pred, val, "val"))
        by_model = spearman_by_model(pred, val.target, val.view_state, val.key)
        append_csv_rows(settings.out_dir / SPEARMAN_FILE,
                        [{"epoch": epoch + 1, **r} for r in by_model])  # fmt: skip
    pred, _ = predict(model, probe, settings, device)
    row.update(ranking_metrics(pred, probe, "train"))
    for name, stages in baselines.items():
        row.update({f"{name}_val_{k}": v for k, v in stages.items()})
    return row


def _open_run(settings: TrainSettings, identity: dict, model, optimizer, scheduler) -> tuple:
    """The run folder ready: made, cleared with ``resume=false``, the training state resumed
    from its ``last.pt`` and ``settings.json`` written; (first epoch to train, best AUC)."""
    out_dir = settings.out_dir
    out_dir.mkdir(parents=True, exist_ok=True)
    if not settings.resume:
        deleted = clear_run(out_dir)
        if deleted:
            log.info("resume=false: deleted %s of %s", ", ".join(deleted), out_dir)
    first_epoch, best_auc = resume_state(out_dir, identity, model, optimizer, scheduler)
    if first_epoch:
        log.info("resuming %s at epoch %d", out_dir, first_epoch + 1)
    plain = {**stored_settings(settings), "held_out": settings.held_out}
    write_text(out_dir / "settings.json", json.dumps(plain, indent=1))
    return first_epoch, best_auc


def _train(settings: TrainSettings) -> dict:
    if settings.threads:
        torch.set_num_threads(settings.threads)
    device = choose_device(settings.device)
    samples = load_samples(settings.dataset, settings.score.name)
    train, val = split_samples(samples, settings)
    dataset = nbv.dataset.open(settings.dataset)
    selection_keys, heldout_keys = fold_keys(dataset, settings)
    dataset.verify([*selection_keys, *heldout_keys])  # a bad model refuses before any write
    identity = run_identity(
        settings, dataset_identity(settings.dataset), samples_identity(settings)
    )
    n_views = samples.view_state.shape[1]
    lmax = int(samples.attrs.get("lmax", 3))
    augmentation = _augmentation(settings, dataset, samples, lmax)
    # A fixed subset of the training samples, unaugmented, shows whether the ranking is learnt
    # on the data it is trained on.
    probe_rows = np.random.default_rng(settings.seed).permutation(len(train))[:300]
    probe = train.select(np.sort(probe_rows))

    model, optimizer, scheduler = fresh_training(settings, n_views, device)
    out_dir = settings.out_dir
    first_epoch, best_auc = _open_run(settings, identity, model, optimizer, scheduler)

    from torch.utils.tensorboard import SummaryWriter

    writer = SummaryWriter(str(out_dir / "tb"))
    extra_base = checkpoint_extra(settings, identity, lmax, device, selection_keys)
    baselines = {}
    if len(val):
        viewspace = str(train.attrs.get("viewspace", "original"))
        baselines = write_baselines(out_dir, train, val, dataset.viewspaces[viewspace], viewspace)
    row: dict = {}
    for epoch in range(first_epoch, settings.epochs):
        stats = train_epoch(model, optimizer, train, settings, epoch, device, augmentation)
        scheduler.step()
        row = {"epoch": epoch + 1, "lr": optimizer.param_groups[0]["lr"], **stats}
        row.update(_ranking_row(model, val, probe, baselines, settings, device, epoch))
        last_epoch = epoch + 1 == settings.epochs
        if selection_keys and ((epoch + 1) % settings.eval_every == 0 or last_epoch):
            policy = _network_policy(model, settings, lmax)
            curve = episodes_metric(dataset, selection_keys, policy, settings.start_views)
            curve = curve.mean(axis=0)
            row["val_auc"] = auc(curve)
            row.update({f"val_cov_{i + 1}": float(c) for i, c in enumerate(curve)})
        chosen = last_epoch if settings.select == "last" else row.get("val_auc", -np.inf) > best_auc
        if settings.select == "valid" and "val_auc" in row:
            best_auc = max(best_auc, row["val_auc"])
        if chosen:
            save_checkpoint(
                out_dir / "best.pt", model, {**extra_base, "epoch": epoch, "metrics": row}
            )
        for name, value in row.items():
            if name != "epoch":
                writer.add_scalar(name, value, epoch + 1)
        append_csv_rows(out_dir / "metrics.csv", [row])
        extra = {**extra_base, "epoch": epoch, "metrics": row, "best_auc": best_auc}
        save_last(out_dir, model, optimizer, scheduler, extra)
    writer.close()
    if settings.held_out is None:  # fold=-1: no category left to score
        _, extra = load_checkpoint(out_dir / "best.pt", n_views=n_views)
        selected, means = int(extra["epoch"]) + 1, {}
    else:
        heldout = heldout_result(out_dir, dataset, heldout_keys, settings, n_views)
        selected = heldout["checkpoint"]["epoch"] + 1
        means = {m: float(np.mean(v)) for m, v in heldout["auc"].items()}
    return {
        "best_val_auc": best_auc if np.isfinite(best_auc) else None,
        "selected_epoch": selected,
        "last": row,
        "heldout_auc": means,
    }
