"""The training models a trainer uses when told to use fewer (``max_models``): a learning
curve's training sets, nested and balanced over the categories.

Shared by :mod:`train.conditioned` and :mod:`train.scorer`, so that their curves' sizes hold the
same models.
"""

from __future__ import annotations

import numpy as np


def subset(keys: list[str], categories: list[str], max_models: int, seed: int) -> list[str]:
    """The first ``max_models`` of ``keys`` taking the categories in turn, each category's
    models in an order seeded by ``seed`` (all of them for 0): a learning curve's smaller
    training sets are nested and balanced.

    Args:
        keys: the training models' keys.
        categories: the category of each key (same length).
        max_models: how many to keep; 0 (or at least ``len(keys)``) keeps them all, in order.
        seed: the run's seed.
    """
    if not max_models or max_models >= len(keys):
        return list(keys)
    rng = np.random.default_rng([seed, 7])
    queues = {c: [k for k, kc in zip(keys, categories, strict=True) if kc == c]
              for c in sorted(set(categories))}  # fmt: skip
    for c in queues:
        queues[c] = [queues[c][i] for i in rng.permutation(len(queues[c]))]
    out: list[str] = []
    while len(out) < max_models:
        for c in queues:
            if queues[c] and len(out) < max_models:
                out.append(queues[c].pop(0))
    return out
