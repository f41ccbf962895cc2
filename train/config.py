"""The settings of ``python -m train``: :class:`TrainSettings`, the one declaration of
``conf/train.yaml``'s keys (the hydra schema ``train_schema`` is derived from it by
:mod:`nbv.config.settings`; ``model.net`` holds the fields of
:class:`nbv.models.config.PCNBVConfig`, but ``n_views``, which comes from the dataset).

This module loads without torch, so that a refused run answers at once. Runs store their settings
flat, as they always have (:func:`stored_settings`): checkpoints, ``settings.json`` and the run
identity that resuming compares.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nbv.assets.categories import TRAIN_CATEGORIES
from nbv.config.schema import ConfigError, PathsConfig, ProtocolConfig, check_views, schema_of
from nbv.config.settings import Entry, check_ranges
from nbv.dataset.reader import SHARD_GLOB
from nbv.geometry.viewspace import get_viewspace
from nbv.models.config import PRECISIONS, PCNBVConfig
from nbv.models.networks import NETWORKS
from nbv.policies.episode import DEFAULT_START_VIEWS
from nbv.utils.fields import Allows, at_least, check, fields_of, one_of, positive, setting

SCORES = ("coverage", "vig")
#: The training losses (:mod:`train.losses`), named here so that settings load without torch.
LOSSES = ("squared", "normalised", "listwise", "pairwise")
#: The weights the L2 penalty takes (``l2_scope``): every weight matrix, or the point encoder's.
L2_SCOPES = ("all", "encoder")
INPUTS = ("points", "signature")
DEVICES = ("auto", "cpu", "cuda")
#: How the evaluated checkpoint (best.pt) is chosen: by the validation AUC on the valid split of
#: the fold's training categories, or the last epoch. Never on the held-out category.
SELECTIONS = ("valid", "last")

#: The error of a setting that cannot be used (one class for every entry point).
TrainConfigError = ConfigError

#: ``model.net``: the fields of PCNBVConfig; a null (or absent) one keeps PCNBVConfig's default.
NetConfig = schema_of(PCNBVConfig, "NetConfig", optional=True, exclude=("n_views",))


def _given(net: dict) -> dict:
    """The ``model.net`` keys the YAML gives (a null one keeps PCNBVConfig's default)."""
    return {k: v for k, v in net.items() if v is not None}


def validation_views(dataset: Path) -> int:
    """Views of the viewspace the validation episodes run on: the ``original`` viewspace of the
    dataset's first shard when it can be read, else the 33 of PC-NBV's original viewspace."""
    import h5py

    shards = sorted(Path(dataset).glob(SHARD_GLOB)) if Path(dataset).is_dir() else []
    for shard in shards[:1]:
        # A shard that cannot be read is refused, naming it, when the run reads the dataset.
        with contextlib.suppress(OSError, KeyError, TypeError):
            with h5py.File(shard, "r") as handle:
                return len(handle["viewspaces/original"])
    return len(get_viewspace("original"))


@dataclass(frozen=True)
class ScoreSettings:
    """``score``: the targets the network learns (the group ``conf/score/``).

    Attributes:
        name: ``coverage`` (the coverage each view would add, PC-NBV's) or ``vig`` (the
            volumetric information gain, the convex-hull volume ratio each view would add).
    """

    name: str = setting("coverage", allows=one_of(SCORES, " (score=...)"))


@dataclass(frozen=True)
class ModelSettings:
    """``model``: the network (the group ``conf/model/``: pcnbv, pcnbv_sph, tiny).

    Attributes:
        name: the network's name (the run folder's and ``train.summary``'s).
        input: ``points`` (the accumulated cloud, farthest point sampled) or ``signature`` (its
            spherical-harmonics signature, 4 (lmax+1)^2 points).
        net: the network's sizes, the fields of :class:`nbv.models.config.PCNBVConfig` but
            ``n_views`` (the dataset's); a null or absent key keeps PCNBVConfig's default. Held
            as the keys given, as checkpoints store them.
        network: the declared network it trains (:data:`nbv.models.networks.NETWORKS`; one
            that ``python -m train`` trains).
    """

    name: str = "pcnbv"
    input: str = setting("points", allows=one_of(INPUTS))
    net: dict = setting(factory=dict, config=NetConfig, convert=_given, config_default={})
    network: str = setting(
        "pcnbv",
        allows=Allows(
            lambda v: v in NETWORKS and NETWORKS[v].trainer == "train",
            "a declared network that python -m train trains (nbv/models/networks.py: pcnbv)",
        ),
    )

    def __post_init__(self) -> None:
        declared = NETWORKS.get(self.network)
        if declared is None:
            raise ConfigError(
                f"model.network={self.network!r}: not declared; declared: {', '.join(NETWORKS)}"
            )
        if declared.trainer != "train":
            raise ConfigError(
                f"model.network={self.network}: trained by python -m {declared.trainer}"
            )


@dataclass(frozen=True)
class TrainSettings:
    """One leave-one-category-out training run (``python -m train``).

    Fold k validates on the k-th training category of
    :data:`nbv.assets.categories.TRAIN_CATEGORIES` (0 airplane, 1 cabinet, 2 car, 3 chair,
    4 lamp, 5 sofa, 6 table, 7 vessel) and trains on the training split of the other seven.

    Attributes:
        dataset: a dataset folder made by ``make dataset`` (shards and samples files).
        out_dir: where checkpoints (``last.pt``, ``best.pt``), ``metrics.csv``, ``heldout.json``
            and TensorBoard logs go; rerunning resumes. In a sweep (``-m``) an out_dir not given
            on the command line is the job's own folder, so two sweeps never share one.
        fold: 0..7 as above; -1 holds no category out and trains on all eight (the weights
            that ship: no held-out score, ``heldout.json`` is not written).
        score: the targets (``score.name``).
        model: the network (``model.name``, ``model.input``, ``model.net``, ``model.network``).
        seed: seeds the network's initialisation and every draw of an epoch (with the epoch).
        epochs: training epochs. Four fit the 15-minute CPU budget of one fold on the default
            dataset (2 cores); raise it on a GPU.
        batch_size: samples per step.
        lr: Adam's learning rate (the PyTorch port of PC-NBV: 1e-3, step decay 0.7 every 20
            epochs; the authors of PCNBV-sph: 1e-4, decay 0.95 every epoch).
        lr_decay: the learning rate's factor every ``lr_step_epochs`` epochs (``lr_decay=0.95
            lr_step_epochs=1`` is the authors' exponential decay; 1 keeps it constant).
        lr_step_epochs: epochs between two decays of the learning rate.
        l2: the factor of the L2 penalty (the sum of the squared weights of ``l2_scope``) added
            to the loss.
        l2_scope: the weights the penalty takes, matrices only (biases, batch norm and the
            attention's gamma never): ``all`` (the point encoder's and the fully connected
            head's) or ``encoder`` (the point encoder's alone: the edge convolutions, the
            attention and the 1x1 convs before the max pool, as the authors of PCNBV-sph
            penalise; ``head`` of :class:`nbv.models.pcnbv.PCNBV` is left free).
        train_points: points per training cloud (a seeded random subset of the stored 1024).
        eval_points: points per evaluation cloud (farthest point sampled from the accumulated
            cloud; the number the network was trained on).
        precision: arithmetic of forward and backward passes: ``auto`` (bfloat16 autocast on
            CPUs with AMX or AVX512-BF16 and on CUDA devices that support it, else fp32),
            ``fp32`` or ``bf16``. The neighbour search and the fully connected head always run
            in fp32.
        eval_every: the validation reconstruction metric (coverage by view, AUC) every this many
            epochs (and at the last), on the valid split of the fold's seven training
            categories; the held-out category is scored once, at the end, with the chosen
            checkpoint (``heldout.json``).
        start_views: the validation episodes' start views (indices into the dataset's original
            viewspace; ``conf/protocol/``).
        device: ``auto`` (CUDA when present), ``cpu`` or ``cuda``.
        threads: torch's CPU threads; 0 = torch's choice.
        progress: show a progress bar.
        select: the checkpoint kept as ``best.pt`` (the one evaluation and ``train.summary``
            use): ``valid`` (best validation AUC on the valid split of the training categories)
            or ``last`` (the last epoch).
        resume: rerunning with the same out_dir continues from ``last.pt``; a changed setting,
            dataset or samples file stops the run, naming the changed keys. false deletes the
            run's files and starts afresh.
        random_repeats: the held-out report averages the random baseline over this many seeds
            per episode.
        loss: ``normalised`` (squared error against the gains divided by the sample's largest,
            summed over the V outputs: every sample's ranking weighs alike), ``squared`` (the
            paper's: the same on the raw gains, whose late steps weigh almost nothing),
            ``listwise`` (softmax cross-entropy over the unvisited views against the gains
            normalised to sum to 1) or ``pairwise`` (RankNet's logistic loss over pairs of
            unvisited views); :mod:`train.losses`. ``normalised`` ranked best and played the best
            episodes on the validation split (docs/training.md).
        augment: map each training sample by a random exact symmetry of its viewspace (the
            original 33 views have 16: 8 rotations about the up axis and their mirror images;
            :mod:`train.augment`). A viewspace without symmetry trains unaugmented.
        loader_workers: threads that build the next batches while the network steps (0 = built
            in turn, the draws of the epoch's one generator; > 0: each batch its own generator,
            the same for any count). On a GPU, 2-4 keep it fed.
        pin_memory: pinned host tensors on CUDA (ignored on the CPU).
        categories: the training categories (not a key: always
            :data:`~nbv.assets.categories.TRAIN_CATEGORIES`; runs store it).
    """

    dataset: Path
    out_dir: Path
    fold: int = setting(
        0,
        check=lambda v: -1 <= v < len(TRAIN_CATEGORIES),
        allowed=f"an integer in 0..{len(TRAIN_CATEGORIES) - 1} (the held-out category), or -1 "
        "(none held out)",
    )
    score: ScoreSettings = setting(factory=ScoreSettings)
    model: ModelSettings = setting(factory=ModelSettings)
    seed: int = 0
    epochs: int = setting(4, allows=at_least(1))
    batch_size: int = setting(32, allows=at_least(1))
    lr: float = setting(1e-3, allows=positive())
    lr_decay: float = setting(0.7, check=lambda v: 0 < v <= 1, allowed="a number in (0, 1]")
    lr_step_epochs: int = setting(20, allows=at_least(1))
    l2: float = setting(1e-4, allows=at_least(0, "a number"))
    l2_scope: str = setting("all", allows=one_of(L2_SCOPES))
    train_points: int = setting(512, allows=at_least(1))
    eval_points: int = setting(512, allows=at_least(1))
    precision: str = setting("auto", allows=one_of(PRECISIONS))
    eval_every: int = setting(2, allows=at_least(1))
    start_views: tuple[int, ...] = DEFAULT_START_VIEWS
    device: str = setting("auto", allows=one_of(DEVICES))
    threads: int = 0
    progress: bool = True
    select: str = setting("valid", allows=one_of(SELECTIONS))
    resume: bool = True
    random_repeats: int = setting(10, allows=at_least(1))
    loss: str = setting("normalised", allows=one_of(LOSSES))
    augment: bool = True
    loader_workers: int = setting(0, allows=at_least(0))
    pin_memory: bool = True
    # Not a key (the schema has no such key): every run trains on the same categories.
    categories: tuple[str, ...] = field(default=TRAIN_CATEGORIES, init=False)

    def __post_init__(self) -> None:
        check_ranges(self)
        # The groups' fields, named by their key path (a group's own object is not checked
        # alone: its message would lose the path).
        for group in ("score", "model"):
            for f in fields_of(type(getattr(self, group))):
                check(f, getattr(getattr(self, group), f.name), f"{group}.")
        check_views("start_views", self.start_views, "original", validation_views(self.dataset))

    @property
    def held_out(self) -> str | None:
        """The held-out category of this fold; None for ``fold=-1``, which trains on every
        training category (the weights that ship)."""
        return None if self.fold == -1 else self.categories[self.fold]


ENTRY = Entry(
    "train_schema", TrainSettings, extra=(("protocol", ProtocolConfig), ("paths", PathsConfig))
)


def stored_settings(settings: TrainSettings) -> dict:
    """The settings as a run stores them (checkpoints' ``settings``, ``settings.json``, the run
    identity): JSON values, flat, the groups' keys as the runs made before the groups had them
    (``score``, ``model_name``, ``input``, ``net``), so that those runs resume and read alike."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        if f.name == "score":
            out["score"] = value.name
        elif f.name == "model":
            out.update(model_name=value.name, input=value.input, net=dict(value.net))
            if value.network != "pcnbv":  # the runs made before networks were declared
                out["network"] = value.network
        else:
            out[f.name] = value
    return json.loads(json.dumps(out, default=str))
