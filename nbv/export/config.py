"""The settings of ``python -m nbv.export``: :class:`ExportSettings`, the one declaration of
``conf/export.yaml``'s keys (the hydra schema ``export_schema`` is derived from it by
:mod:`nbv.config.settings`).

The files the source names are checked by :mod:`nbv.export.sources` before anything is written.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nbv.config.schema import ConfigError, PathsConfig, names
from nbv.config.settings import Entry, check_ranges, setting
from nbv.utils.fields import at_least, or_null


def _names_of(key: str) -> Any:
    """A field that takes null, a name or a list of names (YAML) as a tuple of names."""
    return setting((), key=key, config=Any, config_default=None,
                   convert=lambda value: names(value, key))  # fmt: skip


@dataclass(frozen=True)
class ExportSettings:
    """What to export and where (see ``conf/export.yaml``).

    Attributes:
        out_dir: the export folder.
        eval_run: a finished ``python -m nbv.eval`` run folder (its ``results.json``), or None.
        data_dir: a dataset folder or shard file (views and ground truth only), or None.
        viewspaces: viewspaces to export (key ``viewspace``); empty = all of the source's.
        methods: methods to export (eval_run only); empty = all of the run's.
        limit: at most this many models of each dataset; None = all.
        ascii: ASCII PCD files instead of binary ones.
        progress: show a progress bar.
    """

    eval_run: Path | None = None
    data_dir: Path | None = None
    viewspaces: tuple[str, ...] = _names_of("viewspace")
    methods: tuple[str, ...] = _names_of("methods")
    limit: int | None = setting(None, allows=or_null(at_least(1)))
    ascii: bool = False
    progress: bool = True
    out_dir: Path = field(kw_only=True)

    def __post_init__(self) -> None:
        if (self.eval_run is None) == (self.data_dir is None):
            given = "both" if self.eval_run is not None else "neither"
            raise ConfigError(
                f"eval_run and data_dir: {given} given; give exactly one "
                "(eval_run=<outputs/eval/run folder> or data_dir=<dataset folder>)"
            )
        if self.methods and self.eval_run is None:
            raise ConfigError(f"methods={list(self.methods)}: only an eval_run has methods")
        check_ranges(self)
        for key, listed in (("viewspace", self.viewspaces), ("methods", self.methods)):
            if len(set(listed)) != len(listed):
                raise ConfigError(f"{key} lists a name twice: {list(listed)}")


ENTRY = Entry("export_schema", ExportSettings, extra=(("paths", PathsConfig),))
