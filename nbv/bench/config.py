"""The settings of ``python -m nbv.bench``: :class:`BenchSettings`, the one declaration of
``conf/bench.yaml``'s keys (the hydra schema ``bench_schema`` is derived from it by
:mod:`nbv.config.settings`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nbv.config.schema import ConfigError, PathsConfig
from nbv.config.settings import Entry
from nbv.policies.registry import PCNBV
from nbv.scan.shipped import resolve_weights


@dataclass(frozen=True)
class BenchSettings:
    """What the benchmark runs (``conf/bench.yaml``).

    Attributes:
        checkpoint: trained PCNBV weights the 9-view episode row times; null = fold 0's
            ``best.pt`` (``paths.checkpoints.pcnbv``) when it exists, else the weights the
            package ships. A path given must be a file. (The PCNBV-sph episode row times the
            shipped PCNBV-sph weights.)
        network: time the PCNBV and PCNBV-sph episode rows.
        render: time the rows of Blender against ray casting (the slowest part).
        dataset: dataset folder of the check that a 512-point ground truth has nearly the hull
            volume of the full one (skipped when the folder does not exist; ``paths.dataset``).
        json: also write the rows as JSON to this file; null = no file.
    """

    checkpoint: Path | None = None
    network: bool = True
    render: bool = True
    dataset: Path = Path("data/generated/synthetic")
    json: Path | None = None

    def __post_init__(self) -> None:
        if self.checkpoint is not None and not Path(self.checkpoint).is_file():
            raise ConfigError(
                f"checkpoint={str(self.checkpoint)!r}: no such file (a best.pt of python -m train)"
            )


class BenchEntry(Entry):
    """``bench_schema``; :meth:`build` also finds the default checkpoint."""

    def build(self, cfg: Any) -> BenchSettings:
        """The settings of a composed ``conf/bench.yaml``; ``checkpoint=null`` becomes the
        weights of PCNBV (:func:`nbv.scan.shipped.resolve_weights`): fold 0's
        ``best.pt`` when it exists, else the shipped ones."""
        settings = super().build(cfg)
        if settings.checkpoint is None:
            fold0 = cfg["paths"]["checkpoints"].get(PCNBV.name)
            settings = dataclasses.replace(settings, checkpoint=resolve_weights(PCNBV.name, fold0))
        return settings


ENTRY = BenchEntry("bench_schema", BenchSettings, extra=(("paths", PathsConfig),))
