"""The settings of ``python -m nbv.dataset``: :class:`Settings`, the one declaration of
``conf/dataset.yaml``'s keys (the hydra schema ``dataset_schema`` is derived from it by
:mod:`nbv.config.settings`).

The generation's keys are the library's :class:`~nbv.dataset.generator_settings.GeneratorSettings`;
this module adds only what the command has beyond them: the YAML form of the camera (the shared
``conf/camera/`` group) and the ``samples:`` group, which it turns into the library's
:class:`~nbv.dataset.samples.SampleSettings`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from nbv.config.schema import CameraConfig, ConfigError, PathsConfig, ProtocolConfig
from nbv.config.settings import Entry, setting
from nbv.dataset.generator_settings import GeneratorSettings, Renderer
from nbv.dataset.samples import SampleSettings
from nbv.geometry.camera import Intrinsics
from nbv.utils.fields import fields_of

__all__ = ["ENTRY", "ConfigError", "Samples", "Settings"]


@dataclass(frozen=True)
class _Switch:
    """The ``enabled`` key of :class:`Samples` (documented there)."""

    enabled: bool = True


# _Switch comes last among the bases so that its field comes first: the YAML's order.
@dataclass(frozen=True)
class Samples(SampleSettings, _Switch):
    """``samples:``: the training samples written beside each shard (``samples-shard-*.h5``).

    The fields of :class:`~nbv.dataset.samples.SampleSettings` (:mod:`nbv.dataset.samples`) but
    ``seed`` (the top-level ``seed``), and:

    Attributes:
        enabled: write the samples after the shard.
    """

    # The samples' seed is the dataset's: not a key of this group.
    seed: int = field(default=0, init=False, repr=False)


@dataclass(frozen=True)
class Settings(GeneratorSettings):
    """Everything ``python -m nbv.dataset`` needs: the generation's settings, camera and samples.

    The fields of :class:`~nbv.dataset.generator_settings.GeneratorSettings`, and:

    Attributes:
        intrinsics: the camera, key ``camera``: ``{width, height, focal}`` (pixels) of
            ``conf/camera/`` (``camera=small`` for smoke runs; ``camera.width=...`` for one
            value), principal point at the image centre.
        samples: the training samples (:class:`Samples`).
    """

    intrinsics: Intrinsics = setting(
        factory=Intrinsics.centred,
        key="camera",
        config=CameraConfig,
        convert=Intrinsics.from_config,
    )
    renderer: Renderer = field(default_factory=Renderer)
    samples: Samples = field(default_factory=Samples)

    def sample_settings(self) -> SampleSettings | None:
        """The ``samples:`` group as the samples' settings (seeded by ``seed``); None when
        disabled."""
        if not self.samples.enabled:
            return None
        values = {
            f.name: getattr(self.samples, f.name)
            for f in fields_of(SampleSettings)
            if f.name != "seed"
        }
        return SampleSettings(**values, seed=self.seed)


ENTRY = Entry(
    "dataset_schema",
    Settings,
    extra=(("protocol", ProtocolConfig), ("paths", PathsConfig)),
)
