"""The settings of ``python -m nbv.dataset``: the schema of ``conf/dataset.yaml`` and the settings
objects built from it.

:class:`DatasetConfig` is registered as ``dataset_schema``, the first entry of the config's
defaults list: hydra refuses an unknown key or a value of the wrong type while composing.
:class:`Settings` and :class:`~nbv.dataset.samples.SampleSettings` keep the checks of ranges and
of fields that go together.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

from omegaconf import MISSING

from nbv.config.schema import (
    CameraConfig,
    ConfigError,
    PathsConfig,
    ProtocolConfig,
    register,
    schema_of,
    validated,
)
from nbv.dataset.samples import SampleSettings
from nbv.dataset.schema import SCHEMA_VERSION
from nbv.dataset.sources import SOURCES
from nbv.geometry.camera import Intrinsics
from nbv.geometry.scores import DEFAULT_EPS
from nbv.render.noise import DepthNoise

__all__ = [
    "BACKENDS",
    "ConfigError",
    "DatasetConfig",
    "Settings",
    "sample_settings_from_config",
    "settings_from_config",
]

BACKENDS = ("blender", "raycast")


@dataclass(frozen=True)
class Settings:
    """Everything ``python -m nbv.dataset`` needs, validated (see ``conf/dataset.yaml``)."""

    out_dir: Path
    source: str = "synthetic"
    root: str | None = None
    categories: tuple[str, ...] | None = None
    counts: dict[str, int] | None = None
    split_fractions: dict[str, float] = field(default_factory=dict)
    seed: int = 0
    shard: int = 0
    num_shards: int = 1
    limit: int | None = None
    viewspaces: dict[str, str] = field(
        default_factory=lambda: {"original": "original", "permuted": "permuted"}
    )
    intrinsics: Intrinsics = field(default_factory=Intrinsics.centred)
    n_gt: int = 16384
    eps: float = DEFAULT_EPS
    points_per_view: int = 2048
    keep_depth: bool = False
    backend: str = "blender"
    blender: str | None = None
    threads: int = 0
    device: str = "CPU"
    chunk: int = 16
    noise: DepthNoise | None = None
    progress: bool = True

    def __post_init__(self) -> None:
        checks = [
            ("source", self.source in SOURCES, f"one of {', '.join(SOURCES)}"),
            ("num_shards", self.num_shards >= 1, "an integer >= 1"),
            ("shard", 0 <= self.shard < self.num_shards, f"in 0..{self.num_shards - 1}"),
            ("n_gt", self.n_gt >= 1, "an integer >= 1"),
            ("eps", self.eps > 0, "a positive distance"),
            ("points_per_view", self.points_per_view >= 0, "an integer >= 0 (0 = all)"),
            ("renderer.backend", self.backend in BACKENDS, f"one of {', '.join(BACKENDS)}"),
            ("renderer.chunk", self.chunk >= 1, "an integer >= 1"),
            ("limit", self.limit is None or self.limit >= 0, "null or an integer >= 0"),
            ("viewspaces", len(self.viewspaces) >= 1, "at least one name: viewspace entry"),
        ]
        for key, ok, allowed in checks:
            if not ok:
                raise ConfigError(
                    f"{key}={getattr(self, key.split('.')[-1], '?')!r}: must be {allowed}"
                )

    def data_identity(self) -> dict:
        """The settings that determine the arrays (must match to resume into a folder)."""
        return {
            "schema_version": SCHEMA_VERSION,
            "source": self.source,
            "root": self.root,
            "categories": list(self.categories) if self.categories else None,
            "counts": self.counts,
            "split_fractions": self.split_fractions,
            "seed": self.seed,
            "num_shards": self.num_shards,
            "viewspaces": self.viewspaces,
            "camera": asdict(self.intrinsics),
            "n_gt": self.n_gt,
            "eps": self.eps,
            "points_per_view": self.points_per_view,
            "keep_depth": self.keep_depth,
            "backend": self.backend,
            # Only when on: datasets made before the option keep their identity.
            **({"noise": asdict(self.noise)} if self.noise is not None else {}),
        }


# The schema of conf/dataset.yaml: which keys exist and their types (the values are there).


@dataclass
class SyntheticConfig:
    """``synthetic:``: models per split for each training category, and per unseen category."""

    counts: dict[str, int] = MISSING


@dataclass
class NoiseConfig(schema_of(DepthNoise, "NoiseFields")):
    """``renderer.noise:``: ``enabled`` and the fields of :class:`nbv.render.noise.DepthNoise`."""

    enabled: bool = MISSING


@dataclass
class RendererConfig:
    """``renderer:``."""

    backend: str = MISSING
    blender: str | None = MISSING
    threads: int = MISSING
    device: str = MISSING
    chunk: int = MISSING
    noise: NoiseConfig = field(default_factory=NoiseConfig)


@dataclass
class SamplesConfig:
    """``samples:``: the fields of :class:`~nbv.dataset.samples.SampleSettings` but the seed
    (the top-level ``seed``), and ``enabled``."""

    enabled: bool = MISSING
    trajectories: int = MISSING
    steps: int = MISSING
    n_points: int = MISSING
    lmax: int = MISSING
    random_step_prob: float = MISSING
    scores: list[str] = MISSING
    viewspace: str = MISSING


@dataclass
class DatasetConfig:
    """``conf/dataset.yaml``."""

    source: str = MISSING
    root: str | None = MISSING
    categories: list[str] | None = MISSING
    synthetic: SyntheticConfig = field(default_factory=SyntheticConfig)
    split_fractions: dict[str, float] = MISSING
    seed: int = MISSING
    out_dir: str = MISSING
    shard: int = MISSING
    num_shards: int = MISSING
    limit: int | None = MISSING
    viewspaces: dict[str, str] = MISSING
    camera: CameraConfig = field(default_factory=CameraConfig)
    n_gt: int = MISSING
    eps: float = MISSING
    points_per_view: int = MISSING
    keep_depth: bool = MISSING
    renderer: RendererConfig = field(default_factory=RendererConfig)
    progress: bool = MISSING
    samples: SamplesConfig = field(default_factory=SamplesConfig)
    protocol: ProtocolConfig = field(default_factory=ProtocolConfig)
    paths: PathsConfig = field(default_factory=PathsConfig)


register("dataset_schema", DatasetConfig)


def settings_from_config(cfg) -> Settings:
    """Build :class:`Settings` from the hydra config of ``conf/dataset.yaml``.

    Raises:
        ConfigError: an unknown key, a value of the wrong type or out of range (the message
            names the key).
    """
    c = validated(DatasetConfig, cfg)
    camera, renderer = c["camera"], c["renderer"]
    return Settings(
        out_dir=Path(c["out_dir"]),
        source=c["source"],
        root=c["root"],
        categories=tuple(c["categories"]) if c["categories"] else None,
        counts=dict(c["synthetic"]["counts"]),
        split_fractions=dict(c["split_fractions"]),
        seed=c["seed"],
        shard=c["shard"],
        num_shards=c["num_shards"],
        limit=c["limit"],
        viewspaces=dict(c["viewspaces"]),
        intrinsics=Intrinsics.centred(camera["width"], camera["height"], camera["focal"]),
        n_gt=c["n_gt"],
        eps=c["eps"],
        points_per_view=c["points_per_view"],
        keep_depth=c["keep_depth"],
        backend=renderer["backend"],
        blender=renderer["blender"],
        threads=renderer["threads"],
        device=renderer["device"],
        chunk=renderer["chunk"],
        noise=_noise(renderer["noise"]),
        progress=c["progress"],
    )


def _noise(values: dict) -> DepthNoise | None:
    """``renderer.noise`` as a :class:`DepthNoise`, None when off (its values are checked
    either way)."""
    values = dict(values)
    enabled = values.pop("enabled")
    try:
        noise = DepthNoise(**values)
    except ValueError as err:
        raise ConfigError(str(err)) from None
    return noise if enabled else None


def sample_settings_from_config(cfg) -> SampleSettings | None:
    """The ``samples:`` block of ``conf/dataset.yaml`` (None when disabled).

    Raises:
        ConfigError: as :func:`settings_from_config`, for the ``samples:`` keys.
    """
    c = validated(DatasetConfig, cfg)
    samples = dict(c["samples"])
    if not samples.pop("enabled"):
        return None
    samples["scores"] = tuple(samples["scores"])
    try:
        return SampleSettings(**samples, seed=c["seed"])
    except ValueError as err:  # SampleSettings names the samples.<key> it refuses
        raise ConfigError(str(err)) from None
