"""The fitting check: can the network learn to rank the views of a few models it is trained on?

A network that cannot rank the views of the samples it trains on cannot rank them anywhere else.
:func:`fit_check` trains a fresh network with the same steps as ``python -m train``
(:func:`train.loop.train_epoch`: the loss, the weight penalty, the learning-rate schedule of the
settings) on a handful of models' samples and reports, after every epoch, the Spearman
correlation of its predictions with the true gains on those same samples (unaugmented, the
clouds as evaluation reads them). ``scripts/fit_check.py`` runs it on a dataset folder.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from nbv.dataset.samples import SampleSet
from train.augment import Augmentation
from train.config import TrainSettings
from train.loop import choose_device, fresh_training, predict, ranking_metrics, train_epoch

__all__ = ["first_models", "fit_check"]


def first_models(samples: SampleSet, count: int, split: str = "train") -> SampleSet:
    """The samples of the first ``count`` models of ``split`` (in the order the samples hold
    them).

    Raises:
        ValueError: fewer than ``count`` models in that split.
    """
    keys = list(dict.fromkeys(samples.key[samples.split == split].tolist()))
    if len(keys) < count:
        raise ValueError(f"{count} {split} models wanted, the samples hold {len(keys)}")
    return samples.select(np.isin(samples.key, keys[:count]))


def fit_check(
    samples: SampleSet,
    settings: TrainSettings,
    augmentation: Augmentation | None = None,
    on_epoch: Callable[[dict], None] | None = None,
) -> list[dict[str, float]]:
    """Train a fresh network of ``settings.model`` (seeded by ``settings.seed``) for
    ``settings.epochs`` epochs on ``samples`` and score it on them after each epoch.

    Args:
        samples: the few models' samples, all of one viewspace.
        settings: the training settings (``dataset`` and ``out_dir`` are not read; nothing is
            written). ``threads`` > 0 sets torch's threads.
        augmentation: map each training sample by a random symmetry (None: unaugmented).
        on_epoch: called with each epoch's row as it is made (e.g. to print it).

    Returns:
        One row an epoch: ``epoch``, ``lr`` (of the next epoch), ``train_loss`` and
        ``train_spearman`` (``_early``, ``_late``) and ``train_best_view_hits`` on ``samples``.
    """
    if settings.threads:
        torch.set_num_threads(settings.threads)
    device = choose_device(settings.device)
    model, optimizer, scheduler = fresh_training(settings, samples.view_state.shape[1], device)
    rows = []
    for epoch in range(settings.epochs):
        stats = train_epoch(model, optimizer, samples, settings, epoch, device, augmentation)
        scheduler.step()
        pred, _ = predict(model, samples, settings, device)
        row = {"epoch": epoch + 1, "lr": optimizer.param_groups[0]["lr"],
               "train_loss": stats["train_loss"]}  # fmt: skip
        row.update(ranking_metrics(pred, samples, "train"))
        rows.append(row)
        if on_epoch is not None:
            on_epoch(row)
    return rows
