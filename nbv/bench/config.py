"""The settings of ``python -m nbv.bench``: the schema of ``conf/bench.yaml`` and the settings
built from it.

:class:`BenchConfig` is registered as ``bench_schema``, the first entry of the config's defaults
list: hydra refuses an unknown key or a value of the wrong type while composing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from omegaconf import MISSING

from nbv.assets.weights import shipped_weights
from nbv.config.schema import ConfigError, PathsConfig, register, validated


@dataclass(frozen=True)
class BenchSettings:
    """What the benchmark runs (see ``conf/bench.yaml``).

    Attributes:
        checkpoint: trained PCNBV weights the episode row times; None = untrained weights.
            (The PCNBV-sph episode row times the shipped PCNBV-sph weights.)
        network: time the PCNBV episode row.
        render: time the rendering rows (Blender against ray casting).
        dataset: dataset folder of the 512-point ground-truth hull check (skipped when absent).
        json: also write the rows there as JSON; None = no file.
    """

    checkpoint: Path | None = None
    network: bool = True
    render: bool = True
    dataset: Path = Path("data/generated/synthetic")
    json: Path | None = None


@dataclass
class BenchConfig:
    """``conf/bench.yaml``."""

    checkpoint: str | None = MISSING
    network: bool = MISSING
    render: bool = MISSING
    dataset: str = MISSING
    json: str | None = MISSING
    paths: PathsConfig = field(default_factory=PathsConfig)


register("bench_schema", BenchConfig)


def settings_from_config(cfg) -> BenchSettings:
    """Build :class:`BenchSettings` from the composed hydra config of ``conf/bench.yaml``.

    ``checkpoint=null`` times fold 0's ``best.pt`` (``paths.checkpoints.pcnbv``) when it exists,
    else the shipped PCNBV weights; a checkpoint given by name must exist.

    Raises:
        ConfigError: an unknown key, a value of the wrong type, a checkpoint that is not there.
    """
    c = validated(BenchConfig, cfg)
    if c["checkpoint"] is None:
        fold0 = Path(c["paths"]["checkpoints"]["pcnbv"])
        checkpoint = fold0 if fold0.is_file() else shipped_weights("pcnbv")
    else:
        checkpoint = Path(c["checkpoint"])
        if not checkpoint.is_file():
            raise ConfigError(
                f"checkpoint={c['checkpoint']!r}: no such file (a best.pt of python -m train)"
            )
    return BenchSettings(
        checkpoint=checkpoint,
        network=c["network"],
        render=c["render"],
        dataset=Path(c["dataset"]),
        json=Path(c["json"]) if c["json"] else None,
    )
