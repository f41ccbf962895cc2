"""The sizes of a PCNBV network (plain dataclass, no torch)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

#: Arithmetic of forward passes: ``"auto"`` (bf16 where the hardware runs it natively, else
#: fp32), ``"fp32"`` or ``"bf16"`` (bfloat16 autocast; :mod:`nbv.models.precision`). Here, with
#: the config and without torch, so that settings can be checked before torch is loaded.
PRECISIONS = ("auto", "fp32", "bf16")


@dataclass(frozen=True)
class PCNBVConfig:
    """Sizes of a :class:`PCNBV` network. The defaults are PC-NBV's (264 channels a point, 561
    after concatenation with 33 views).

    Attributes:
        n_views: V, the number of candidate views (length of the view state and the output).
        k: neighbours of each point in a dense EdgeConv block (the point itself included).
        growth: channels each dense layer adds.
        dense_layers: layers in a dense block.
        blocks: dense blocks in the feature extractor.
        first_channels: width of the first 1x1 conv and the input width of every dense block.
        attention_channels: width of the attention query and key.
        conv_channels: widths of the 1x1 convs after the attention.
        fc_channels: widths of the hidden fully connected layers.
        batch_norm: batch norm after every hidden conv (the PyTorch port's choice); without it
            the convs carry a bias instead.
        normalize_input: centre each cloud at its centroid and scale it to unit max radius.
            Turn it off for inputs whose position and scale carry information.
    """

    n_views: int = 33
    k: int = 16
    growth: int = 12
    dense_layers: int = 3
    blocks: int = 4
    first_channels: int = 24
    attention_channels: int = 140
    conv_channels: tuple[int, ...] = (1024, 1024)
    fc_channels: tuple[int, ...] = (512, 256)
    batch_norm: bool = True
    normalize_input: bool = True

    def __post_init__(self) -> None:
        for name in (
            "n_views",
            "k",
            "growth",
            "dense_layers",
            "blocks",
            "first_channels",
            "attention_channels",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"PCNBVConfig.{name} must be a positive int, got {value!r}")
        for name in ("conv_channels", "fc_channels"):
            value = getattr(self, name)
            if not isinstance(value, tuple | list) or not all(
                isinstance(c, int) and not isinstance(c, bool) and c >= 1 for c in value
            ):
                raise ValueError(
                    f"PCNBVConfig.{name} must be a sequence of positive ints, got {value!r}"
                )
            # Lists come back from checkpoints and hydra; store a tuple so configs compare equal.
            object.__setattr__(self, name, tuple(value))
        if not self.conv_channels:
            raise ValueError("PCNBVConfig.conv_channels must hold at least one width, got ()")
        for name in ("batch_norm", "normalize_input"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"PCNBVConfig.{name} must be a bool, got {getattr(self, name)!r}")

    @property
    def block_out_channels(self) -> int:
        """Channels a dense block outputs: ``dense_layers * growth + first_channels`` (60)."""
        return self.dense_layers * self.growth + self.first_channels

    @property
    def point_channels(self) -> int:
        """Channels a point has after the feature extractor (264)."""
        return self.first_channels + self.blocks * self.block_out_channels

    @property
    def concat_channels(self) -> int:
        """Channels a point has after concatenating global feature and view state (561)."""
        return 2 * self.point_channels + self.n_views

    def to_dict(self) -> dict[str, Any]:
        """Plain-type dict (lists for tuples) that :meth:`from_dict` reads back."""
        return {
            f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v
            for f in dataclasses.fields(self)
        }

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> PCNBVConfig:
        """Build a config from :meth:`to_dict`'s output; unknown keys raise ``ValueError``."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ValueError(f"unknown PCNBVConfig keys {unknown}; allowed: {sorted(names)}")
        return cls(**dict(values))
