"""The settings of ``python -m nbv.preview``: :class:`PreviewSettings`, the one declaration of
``conf/preview.yaml``'s keys (the hydra schema ``preview_schema`` is derived from it)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from nbv.config.schema import PathsConfig
from nbv.config.settings import Entry, check_ranges, setting
from nbv.utils.fields import at_least


@dataclass(frozen=True)
class PreviewSettings:
    """The contact sheet of the synthetic shapes that ``python -m nbv.preview`` draws.

    One row per category, ``per_category`` models of each (:func:`nbv.assets.synthetic.preview`).

    Attributes:
        preview: the PNG file to write (required).
        seed: the dataset seed whose models are drawn (the models ``python -m nbv.dataset
            seed=...`` makes).
        per_category: models per row.
        tile: the size of one model's picture, pixels.
    """

    preview: Path = field(kw_only=True)
    seed: int = setting(0, allows=at_least(0))
    per_category: int = setting(4, allows=at_least(1))
    tile: int = setting(160, allows=at_least(8))

    def __post_init__(self) -> None:
        check_ranges(self)


ENTRY = Entry("preview_schema", PreviewSettings, extra=(("paths", PathsConfig),))
