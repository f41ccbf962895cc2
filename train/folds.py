"""A fold of the cross-validation: its training and validation samples
(:func:`split_samples`) and its models (:func:`fold_keys`): those whose episodes choose the
checkpoint and the held-out category's."""

from __future__ import annotations

import numpy as np

from nbv.dataset.reader import DatasetError
from nbv.dataset.samples import SampleSet
from train.config import TrainSettings


def split_samples(samples: SampleSet, settings: TrainSettings) -> tuple[SampleSet, SampleSet]:
    """(training, validation) samples of a fold: the train and the valid split of the fold's
    training categories. The held-out category is in neither.

    Raises:
        DatasetError: no training samples, or no validation samples with ``select=valid``.
    """
    known = np.isin(samples.category, settings.categories)
    if settings.held_out is not None:
        known &= samples.category != settings.held_out
    train = samples.select(known & (samples.split == "train"))
    val = samples.select(known & (samples.split == "valid"))
    if len(train) == 0 or (len(val) == 0 and settings.select == "valid"):
        raise DatasetError(
            f"{settings.dataset}: fold {settings.fold} has {len(train)} training and {len(val)} "
            f"validation samples (train and valid splits of the training categories but "
            f"{settings.held_out!r}; categories present: {sorted(set(samples.category))}); make "
            "a dataset with the training categories and a valid split, or set select=last"
        )
    return train, val


def fold_keys(dataset, settings: TrainSettings) -> tuple[list[str], list[str]]:
    """(selection, held-out) model keys of a fold: the valid split of the training categories
    but the held-out one (episodes that choose best.pt), and every model of the held-out
    category (scored once at the end)."""
    selection = [
        k
        for k in dataset.keys(split="valid")
        if dataset.index[k][1] in settings.categories and dataset.index[k][1] != settings.held_out
    ]
    held_out = [] if settings.held_out is None else dataset.keys(category=settings.held_out)
    return selection, held_out
