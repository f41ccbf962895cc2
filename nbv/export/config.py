"""The settings of ``python -m nbv.export``: the schema of ``conf/export.yaml`` and the settings
built from it.

:class:`ExportConfig` is registered as ``export_schema``, the first entry of the config's
defaults list: hydra refuses an unknown key or a value of the wrong type while composing.
:class:`ExportSettings` checks the values and that exactly one source is given; the files the
source names are checked by :mod:`nbv.export.sources` before anything is written.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omegaconf import MISSING

from nbv.config.schema import ConfigError, PathsConfig, names, register, validated


@dataclass(frozen=True)
class ExportSettings:
    """What to export and where (see ``conf/export.yaml``).

    Attributes:
        out_dir: the export folder.
        eval_run: a finished ``python -m nbv.eval`` run folder (its ``results.json``), or None.
        data_dir: a dataset folder or shard file (views and ground truth only), or None.
        viewspaces: viewspaces to export; empty = all of the source's.
        methods: methods to export (eval_run only); empty = all of the run's.
        limit: at most this many models of each dataset; None = all.
        ascii: ASCII PCD files instead of binary ones.
        progress: show a progress bar.
    """

    out_dir: Path
    eval_run: Path | None = None
    data_dir: Path | None = None
    viewspaces: tuple[str, ...] = ()
    methods: tuple[str, ...] = ()
    limit: int | None = None
    ascii: bool = False
    progress: bool = True

    def __post_init__(self) -> None:
        if (self.eval_run is None) == (self.data_dir is None):
            given = "both" if self.eval_run is not None else "neither"
            raise ConfigError(
                f"eval_run and data_dir: {given} given; give exactly one "
                "(eval_run=<outputs/eval/run folder> or data_dir=<dataset folder>)"
            )
        if self.methods and self.eval_run is None:
            raise ConfigError(f"methods={list(self.methods)}: only an eval_run has methods")
        if self.limit is not None and self.limit < 1:
            raise ConfigError(f"limit={self.limit!r}: must be null or an integer >= 1")
        for key, listed in (("viewspace", self.viewspaces), ("methods", self.methods)):
            if len(set(listed)) != len(listed):
                raise ConfigError(f"{key} lists a name twice: {list(listed)}")


@dataclass
class ExportConfig:
    """``conf/export.yaml``."""

    eval_run: str | None = MISSING
    data_dir: str | None = MISSING
    viewspace: Any = MISSING
    methods: Any = MISSING
    limit: int | None = MISSING
    ascii: bool = MISSING
    progress: bool = MISSING
    out_dir: str = MISSING
    paths: PathsConfig = field(default_factory=PathsConfig)


register("export_schema", ExportConfig)


def settings_from_config(cfg) -> ExportSettings:
    """Build :class:`ExportSettings` from the composed hydra config of ``conf/export.yaml``.

    Raises:
        ConfigError: an unknown key, a value of the wrong type or out of range, no source or
            two (the message names the key).
    """
    c = validated(ExportConfig, cfg)
    return ExportSettings(
        out_dir=Path(c["out_dir"]),
        eval_run=Path(c["eval_run"]) if c["eval_run"] else None,
        data_dir=Path(c["data_dir"]) if c["data_dir"] else None,
        viewspaces=names(c["viewspace"], "viewspace"),
        methods=names(c["methods"], "methods"),
        limit=c["limit"],
        ascii=c["ascii"],
        progress=c["progress"],
    )
