"""The settings of ``python -m train.conditioned``: :class:`ConditionedSettings`, the one
declaration of ``conf/train_conditioned.yaml``'s keys (the hydra schema
``train_conditioned_schema`` is derived from it), and the command's :data:`ENTRY`."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nbv.assets.categories import TRAIN_CATEGORIES
from nbv.config.schema import ConfigError, PathsConfig, ProtocolConfig, schema_of
from nbv.config.settings import Entry, check_ranges, setting
from nbv.models.view_conditioned import (
    ConditionedConfig,
)
from nbv.policies.episode import DEFAULT_START_VIEWS
from nbv.utils.fields import at_least, between, one_of, positive
from train.losses import LOSSES

#: The viewspaces the network trains on.
VIEWSPACES = ("original", "permuted")

#: ``net``: the widths of :class:`ConditionedConfig` (each null: its default); the number of map
#: features follows ``map_features``.
NetFields = schema_of(ConditionedConfig, "NetFields", optional=True, exclude=("map_features",))


def _widths(net: Mapping[str, Any]) -> dict[str, Any]:
    """The ``net`` widths the YAML gives (lists as tuples); a null one keeps the default."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in net.items() if v is not None}


@dataclass(frozen=True)
class ConditionedSettings:
    """Training of the viewspace-conditioned network (``python -m train.conditioned``).

    Attributes:
        dataset: a dataset folder with both viewspaces (``make dataset``).
        out_dir: where ``best.pt``, ``last.pt``, ``metrics.csv`` and
            ``val_spearman_by_model.csv`` go; rerunning resumes (more epochs extend the run).
        seed: seeds the network's initialisation and every epoch's samples (with the epoch).
        epochs: training epochs; each draws new samples.
        trajectories: trajectories per training model and epoch, each on its own viewspace of
            ``candidates`` directions drawn from the model's 66 stored views (both
            viewspaces), turned by a random rotation about the up axis (and mirrored half the
            time).
        steps: samples per trajectory (one before each pick).
        candidates: directions of a trajectory's viewspace.
        random_step_prob: a trajectory takes a random unvisited view instead of the oracle's
            with this probability.
        batch_size: samples per step.
        lr: Adam's learning rate (constant).
        loss: ``squared``, ``normalised``, ``listwise`` or ``pairwise`` (:mod:`train.losses`).
        train_points: points of a training cloud (a random subset of the visited views' stored
            points).
        eval_points: points of an evaluation cloud (farthest point sampled).
        threads: torch's CPU threads; 0 = torch's choice.
        max_models: train on this many of the training models (the categories in turn, a
            seeded order in each; smaller sets are nested in larger ones): the learning curve's
            sizes. 0 = all.
        map_features: the head also reads each candidate's map features (what its rays would
            see on ig's occupancy map of the visited views): the ``vcnbv_map`` variant. Give it
            its own out_dir, e.g. ``out_dir=${paths.outputs}/train/vcnbv_map``.
        start_views: the validation episodes' start views (``conf/protocol/``).
        categories: the training categories (not a key: always
            :data:`~nbv.assets.categories.TRAIN_CATEGORIES`; runs store it).
        select_categories: training categories held out of training to choose the checkpoint
            on, e.g. ``[cabinet,lamp]``: the validation models (AUC, Spearman, the choice of
            best.pt) are then every model of these categories, which the network never sees,
            instead of the valid split of all of them. ``[]`` = the valid split.
        net: the network's widths (:class:`nbv.models.view_conditioned.ConditionedConfig`), e.g.
            ``net.head_channels=[256,128]``; a null one keeps the default.
    """

    dataset: Path
    out_dir: Path
    seed: int = 0
    epochs: int = setting(6, allows=at_least(1))
    trajectories: int = setting(12, allows=at_least(1))
    steps: int = setting(9, allows=at_least(1))
    candidates: int = setting(33, allows=at_least(2))
    random_step_prob: float = setting(0.3, allows=between(0, 1))
    batch_size: int = setting(32, allows=at_least(1))
    lr: float = setting(1e-3, allows=positive())
    loss: str = setting("listwise", allows=one_of(LOSSES))
    train_points: int = 256
    eval_points: int = 256
    threads: int = 0
    max_models: int = setting(0, allows=at_least(0, note="0: every training model"))
    map_features: bool = False
    start_views: tuple[int, ...] = DEFAULT_START_VIEWS
    # Not a key (the schema has no such key): every run trains on the same categories.
    categories: tuple[str, ...] = field(default=TRAIN_CATEGORIES, init=False)
    select_categories: tuple[str, ...] = ()
    # The YAML's widths come as a mapping, made a ConditionedConfig in __post_init__: its own
    # checks then name their key (net.head_channels=...) as they did.
    net: ConditionedConfig = setting(
        factory=ConditionedConfig, config=NetFields, convert=_widths, config_default={}
    )

    def __post_init__(self) -> None:
        if isinstance(self.net, Mapping):
            object.__setattr__(self, "net", ConditionedConfig(**self.net))
        check_ranges(self)
        chosen = set(self.select_categories)
        if not chosen <= set(self.categories) or chosen >= set(self.categories):
            raise ConfigError(
                f"select_categories={list(self.select_categories)}: must be some, not all, of "
                f"the training categories {', '.join(self.categories)}"
            )


ENTRY = Entry(
    "train_conditioned_schema",
    ConditionedSettings,
    extra=(("protocol", ProtocolConfig), ("paths", PathsConfig)),
)
