"""The training settings, validated from the hydra config (``conf/train.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from nbv.assets.categories import TRAIN_CATEGORIES
from nbv.models.precision import PRECISIONS

SCORES = ("coverage", "vig")
INPUTS = ("points", "signature")
DEVICES = ("auto", "cpu", "cuda")


class TrainConfigError(ValueError):
    """A setting that cannot be used; the message names the key and what is allowed."""


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
    start_views: tuple[int, ...] = (1, 3, 7, 10, 15, 24, 27, 30)
    device: str = "auto"
    threads: int = 0
    progress: bool = True
    categories: tuple[str, ...] = TRAIN_CATEGORIES

    def __post_init__(self) -> None:
        n = len(self.categories)
        checks = [
            ("fold", 0 <= self.fold < n, f"an integer in 0..{n - 1} (the held-out category)"),
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
        ]
        for key, ok, allowed in checks:
            if not ok:
                value = getattr(self, key.split(".")[-1])
                raise TrainConfigError(f"{key}={value!r}: must be {allowed}")

    @property
    def held_out(self) -> str:
        """The validation category of this fold."""
        return self.categories[self.fold]


def settings_from_config(cfg) -> TrainSettings:
    """Build :class:`TrainSettings` from the composed hydra config."""
    from omegaconf import OmegaConf

    c = OmegaConf.to_container(cfg, resolve=True)
    c.pop("hydra", None)
    model, score = c.pop("model"), c.pop("score")
    known = set(TrainSettings.__dataclass_fields__) - {"score", "model_name", "input", "net"}
    unknown = sorted(set(c) - known)
    if unknown:
        raise TrainConfigError(f"unknown keys {unknown}; allowed: {sorted(known)}")
    c["dataset"], c["out_dir"] = Path(c["dataset"]), Path(c["out_dir"])
    c["start_views"] = tuple(c.get("start_views", ()))
    return TrainSettings(
        **c,
        score=score["name"],
        model_name=model["name"],
        input=model.get("input", "points"),
        net=dict(model.get("net", {})),
    )
