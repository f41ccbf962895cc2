"""The training settings: the schema of ``conf/train.yaml`` and the settings built from it.

:class:`TrainConfig` is registered as ``train_schema``, the first entry of the config's defaults
list: hydra refuses an unknown key or a value of the wrong type while composing. The ``model.net``
keys are the fields of :class:`nbv.models.config.PCNBVConfig` (but ``n_views``, which comes from
the dataset). :class:`TrainSettings` keeps the checks of ranges and of fields that go together.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from omegaconf import MISSING

from nbv.assets.categories import TRAIN_CATEGORIES
from nbv.config.schema import (
    ConfigError,
    PathsConfig,
    ProtocolConfig,
    check_views,
    register,
    schema_of,
    validated,
)
from nbv.dataset.reader import SHARD_GLOB
from nbv.geometry.viewspace import get_viewspace
from nbv.models.config import PRECISIONS, PCNBVConfig
from nbv.policies.episode import DEFAULT_START_VIEWS

SCORES = ("coverage", "vig")
#: The training losses (:mod:`train.losses`), named here so that settings load without torch.
LOSSES = ("squared", "normalised", "listwise", "pairwise")
INPUTS = ("points", "signature")
DEVICES = ("auto", "cpu", "cuda")
#: How the evaluated checkpoint (best.pt) is chosen: by the validation AUC on the valid split of
#: the fold's training categories, or the last epoch. Never on the held-out category.
SELECTIONS = ("valid", "last")

#: The error of a setting that cannot be used (one class for every entry point).
TrainConfigError = ConfigError


def validation_views(dataset: Path) -> int:
    """Views of the viewspace the validation episodes run on: the ``original`` viewspace of the
    dataset's first shard when it can be read, else the 33 of PC-NBV's original viewspace."""
    import h5py

    shards = sorted(Path(dataset).glob(SHARD_GLOB)) if Path(dataset).is_dir() else []
    for shard in shards[:1]:
        try:
            with h5py.File(shard, "r") as handle:
                return len(handle["viewspaces/original"])
        except (OSError, KeyError):
            pass
    return len(get_viewspace("original"))


@dataclass(frozen=True)
class TrainSettings:
    """Everything one training run needs (see ``conf/train.yaml`` for the meaning of each)."""

    dataset: Path
    out_dir: Path
    fold: int = 0
    score: str = "coverage"
    model_name: str = "pcnbv"
    input: str = "points"
    net: dict = field(default_factory=dict)
    seed: int = 0
    epochs: int = 4
    batch_size: int = 32
    lr: float = 1e-3
    lr_decay: float = 0.7
    lr_step_epochs: int = 20
    l2: float = 1e-4
    train_points: int = 512
    eval_points: int = 512
    precision: str = "auto"
    eval_every: int = 2
    start_views: tuple[int, ...] = DEFAULT_START_VIEWS
    device: str = "auto"
    threads: int = 0
    progress: bool = True
    select: str = "valid"
    resume: bool = True
    random_repeats: int = 10
    loss: str = "squared"
    augment: bool = True
    loader_workers: int = 0
    pin_memory: bool = True
    categories: tuple[str, ...] = TRAIN_CATEGORIES

    def __post_init__(self) -> None:
        n = len(self.categories)
        checks = [
            (
                "fold",
                -1 <= self.fold < n,
                f"an integer in 0..{n - 1} (the held-out category), or -1 (none held out)",
            ),
            ("score", self.score in SCORES, f"one of {', '.join(SCORES)} (score=...)"),
            ("model.input", self.input in INPUTS, f"one of {', '.join(INPUTS)}"),
            ("epochs", self.epochs >= 1, "an integer >= 1"),
            ("batch_size", self.batch_size >= 1, "an integer >= 1"),
            ("lr", self.lr > 0, "a positive number"),
            ("train_points", self.train_points >= 1, "an integer >= 1"),
            ("eval_points", self.eval_points >= 1, "an integer >= 1"),
            ("eval_every", self.eval_every >= 1, "an integer >= 1"),
            ("device", self.device in DEVICES, f"one of {', '.join(DEVICES)}"),
            ("precision", self.precision in PRECISIONS, f"one of {', '.join(PRECISIONS)}"),
            ("select", self.select in SELECTIONS, f"one of {', '.join(SELECTIONS)}"),
            ("random_repeats", self.random_repeats >= 1, "an integer >= 1"),
            ("loss", self.loss in LOSSES, f"one of {', '.join(LOSSES)}"),
            ("loader_workers", self.loader_workers >= 0, "an integer >= 0"),
        ]
        for key, ok, allowed in checks:
            if not ok:
                value = getattr(self, key.split(".")[-1])
                raise TrainConfigError(f"{key}={value!r}: must be {allowed}")
        check_views("start_views", self.start_views, "original", validation_views(self.dataset))

    @property
    def held_out(self) -> str | None:
        """The held-out category of this fold; None for ``fold=-1``, which trains on every
        training category (the weights that ship)."""
        return None if self.fold == -1 else self.categories[self.fold]


# The schema of conf/train.yaml: which keys exist and their types (the values are there).

#: ``model.net``: the fields of PCNBVConfig; a null (or absent) one keeps PCNBVConfig's default.
NetConfig = schema_of(PCNBVConfig, "NetConfig", optional=True, exclude=("n_views",))


@dataclass
class ModelConfig:
    """``conf/model/``: the network's name, its input (``points`` or ``signature``), its sizes."""

    name: str = MISSING
    input: str = MISSING
    net: NetConfig = field(default_factory=NetConfig)


@dataclass
class ScoreConfig:
    """``conf/score/``: the targets the network learns (``coverage`` or ``vig``)."""

    name: str = MISSING


@dataclass
class TrainConfig:
    """``conf/train.yaml``."""

    dataset: str = MISSING
    fold: int = MISSING
    seed: int = MISSING
    epochs: int = MISSING
    batch_size: int = MISSING
    lr: float = MISSING
    lr_decay: float = MISSING
    lr_step_epochs: int = MISSING
    l2: float = MISSING
    train_points: int = MISSING
    eval_points: int = MISSING
    precision: str = MISSING
    eval_every: int = MISSING
    start_views: list[int] = MISSING
    device: str = MISSING
    threads: int = MISSING
    progress: bool = MISSING
    select: str = MISSING
    resume: bool = MISSING
    random_repeats: int = MISSING
    loss: str = MISSING
    augment: bool = MISSING
    loader_workers: int = MISSING
    pin_memory: bool = MISSING
    out_dir: str = MISSING
    score: ScoreConfig = field(default_factory=ScoreConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    protocol: ProtocolConfig = field(default_factory=ProtocolConfig)
    paths: PathsConfig = field(default_factory=PathsConfig)


register("train_schema", TrainConfig)


def settings_from_config(cfg) -> TrainSettings:
    """Build :class:`TrainSettings` from the composed hydra config.

    Raises:
        ConfigError: an unknown key, a value of the wrong type or out of range (the message
            names the key).
    """
    c = validated(TrainConfig, cfg)
    model, score = c.pop("model"), c.pop("score")
    del c["protocol"], c["paths"]
    c["dataset"], c["out_dir"] = Path(c["dataset"]), Path(c["out_dir"])
    c["start_views"] = tuple(c["start_views"])
    return TrainSettings(
        **c,
        score=score["name"],
        model_name=model["name"],
        input=model["input"],
        net={k: v for k, v in model["net"].items() if v is not None},
    )
