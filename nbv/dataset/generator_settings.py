"""The settings of dataset generation (:func:`nbv.dataset.generator.generate`), nested like
``conf/dataset.yaml``: :class:`GeneratorSettings` with its groups :class:`Synthetic`,
:class:`Renderer` and :class:`Noise`.

These are the library's settings: code makes them directly (tests, the evaluator's prepared
meshes), and ``python -m nbv.dataset`` builds them from its YAML (:mod:`nbv.dataset.config` adds
the YAML form of the camera and the ``samples:`` group). Each field is declared here once, with
its default and allowed range (:func:`nbv.utils.fields.setting`); a bad value raises
:class:`~nbv.utils.fields.ConfigError` naming its key path, from code as from a config.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from nbv.assets.mesh_sources import MESH_SOURCES
from nbv.dataset.schema import SCHEMA_VERSION
from nbv.geometry.camera import Intrinsics
from nbv.geometry.scores import DEFAULT_EPS, DEFAULT_N_GT, DEFAULT_POINTS_PER_VIEW
from nbv.render.job import BACKENDS
from nbv.render.noise import DepthNoise
from nbv.utils.fields import (
    ConfigError,
    at_least,
    check,
    check_ranges,
    fields_of,
    one_of,
    or_null,
    positive,
    setting,
)

__all__ = ["BACKENDS", "GeneratorSettings", "Noise", "Renderer", "Synthetic"]


@dataclass(frozen=True)
class Synthetic:
    """``synthetic:``: the synthetic source's size.

    Attributes:
        counts: models per split for each training category (keys ``train``, ``valid``,
            ``test``) and per unseen category (``unseen``); missing keys (or null) take
            :data:`nbv.assets.synthetic.DEFAULT_COUNTS`. Synthetic source only.
    """

    counts: dict[str, int] | None = None


@dataclass(frozen=True)
class Noise(DepthNoise):
    """``renderer.noise:``: a depth-sensor model applied to every rendered view, off by default.

    The fields of :class:`nbv.render.noise.DepthNoise` (checked even when off), and:

    Attributes:
        a, b, z0: the axial noise's constant and quadratic terms (world units, read as metres):
            sigma = a + b (z - z0)^2 + c / sqrt(z) * t^2 / (pi/2 - t)^2, z the planar depth, t the
            incidence angle (Nguyen et al. 2012's Kinect fit).
        c: the angle-dependent term's scale (0 turns it off).
        dropout_start: incidence angle, degrees, where dropout begins: a pixel is lost with
            probability rising from 0 there to 1 at 90 (silhouette pixels count as grazing).
        max_angle: incidence angle, degrees, where the angular term is capped.
        enabled: apply the model (seeded by ``seed`` and the model).
    """

    enabled: bool = False

    @property
    def model(self) -> DepthNoise | None:
        """The sensor model when enabled, else None."""
        if not self.enabled:
            return None
        return DepthNoise(**{f.name: getattr(self, f.name) for f in fields_of(DepthNoise)})


@dataclass(frozen=True)
class Renderer:
    """``renderer:``: how depth images are made.

    Attributes:
        backend: ``blender`` (Cycles, the reference) or ``raycast`` (Open3D Embree, 3-4x faster
            here, the same camera model).
        blender: path (or command on the PATH) of a Blender 3.4-5.0 binary, checked once by a
            tiny render before any model (:mod:`nbv.render.preflight`); null = the bpy module
            of this environment.
        threads: render threads of each renderer process (0 = the cores shared evenly among
            the processes).
        device: Blender's device: ``CPU``, ``GPU`` or ``AUTO``.
        processes: Blender processes rendering at once, each taking the next mesh when it
            finishes one (0 = one per core on the CPU device, one on ``GPU`` and ``AUTO``).
            The depth is the same bit for bit: on 2 cores two processes of one thread rendered
            17 % faster than one of two (:func:`nbv.render.blender.render_blender`).
        chunk: meshes a Blender process renders before a new one takes over; bounds what a
            long run leaves in one Blender's memory.
        noise: the depth-sensor model (:class:`Noise`).
    """

    backend: str = setting("blender", allows=one_of(BACKENDS))
    blender: str | None = None
    threads: int = 0
    device: str = "CPU"
    processes: int = setting(0, allows=at_least(0))
    chunk: int = setting(16, allows=at_least(1))
    noise: Noise = field(default_factory=Noise)


def viewspace_map(value: Any) -> dict[str, str]:
    """``viewspaces`` as a config gives it: a list of names (each name its own source, as
    ``conf/protocol/`` lists them), a map name -> source, or null (the default two).

    Raises:
        ValueError: neither a list nor a map.
    """
    if value is None:
        return dict(DEFAULT_VIEWSPACES)
    if isinstance(value, Mapping):
        return {str(k): str(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return {str(v): str(v) for v in value}
    raise ValueError(f"viewspaces={value!r}: must be a list of names or a map name: source")


#: The viewspaces every dataset renders unless told otherwise.
DEFAULT_VIEWSPACES = {"original": "original", "permuted": "permuted"}


@dataclass(frozen=True)
class GeneratorSettings:
    """Everything :func:`nbv.dataset.generator.generate` needs (``conf/dataset.yaml``'s keys but
    ``samples:``).

    Attributes:
        source: where meshes come from: ``synthetic``, ``shapenet``, ``stanford``, ``linemod``,
            ``homebrew``, ``folder``, or the real objects ``make real-data`` installs, ``ycb``
            and ``scans``.
        root: folder of the source's meshes (every source but synthetic; ``ycb`` and ``scans``
            default to where ``make real-data`` puts them).
        categories: ShapeNet only: category names or synset ids; null = the 8 training and 8
            unseen categories (those the folder holds); ``[all]`` = every synset folder.
        synthetic: the synthetic source's size (:class:`Synthetic`).
        split_fractions: real sources: fractions of each training category's models that go to
            ``valid`` and ``test``.
        seed: every random choice (synthetic shapes, ground truth, subsampling, splits) derives
            from it.
        out_dir: output folder: one HDF5 file per shard, ``shard-SSSSS-of-NNNNN.h5``.
        shard: this process renders the models ``i`` with ``i % num_shards == shard`` (one SLURM
            array task per shard); in ``0 .. num_shards - 1``.
        num_shards: the number of shards (>= 1).
        limit: stop after this many models of the shard; null = all.
        models: only the models of these keys (in the source's order); null = all. The
            evaluator renders a viewspace a dataset lacks for its models this way.
        viewspaces: the viewspaces to render: a list of names (``original``, ``permuted``,
            ``sphere_<n>``, ``hemisphere_<n>``; ``conf/protocol/`` gives this list), or a map
            name -> one of those or the path of a viewspace text file (rows ``x y z``); at least
            one.
        intrinsics: the camera (YAML key ``camera``: ``conf/camera/``, ``camera=small`` for
            smoke runs).
        n_gt: ground-truth points sampled uniformly on each normalised mesh (>= 1).
        eps: coverage distance, world units (> 0; objects fit in a sphere of radius 0.5).
        points_per_view: points kept of each view, a seeded random subset (0 = all).
        keep_depth: also keep the full-resolution depth images (half floats, compressed): about
            10x larger files.
        renderer: how depth images are made (:class:`Renderer`).
        progress: show a progress bar.
    """

    source: str = setting("synthetic", allows=one_of(MESH_SOURCES))
    root: str | None = None
    categories: tuple[str, ...] | None = None
    synthetic: Synthetic = field(default_factory=Synthetic)
    split_fractions: dict[str, float] = field(default_factory=dict)
    seed: int = 0
    out_dir: Path = field(kw_only=True)
    shard: int = 0
    num_shards: int = setting(1, allows=at_least(1))
    limit: int | None = setting(None, allows=or_null(at_least(0)))
    models: tuple[str, ...] | None = None
    viewspaces: dict[str, str] = setting(
        factory=lambda: dict(DEFAULT_VIEWSPACES),
        check=lambda v: len(v) >= 1,
        allowed="at least one viewspace",
        config=Any,
        convert=viewspace_map,
        # null in the schema: a list (conf/protocol/) or a map may replace it.
        config_default=None,
    )
    intrinsics: Intrinsics = field(default_factory=Intrinsics.centred)
    n_gt: int = setting(DEFAULT_N_GT, allows=at_least(1))
    eps: float = setting(DEFAULT_EPS, allows=positive("distance"))
    points_per_view: int = setting(DEFAULT_POINTS_PER_VIEW, allows=at_least(0, note="0 = all"))
    keep_depth: bool = False
    renderer: Renderer = field(default_factory=Renderer)
    progress: bool = True

    def __post_init__(self) -> None:
        check_ranges(self)
        if not 0 <= self.shard < self.num_shards:
            raise ConfigError(f"shard={self.shard!r}: must be in 0..{self.num_shards - 1}")
        # A group made in code is checked here, its keys named by their path as from a config.
        for f in fields_of(Renderer):
            check(f, getattr(self.renderer, f.name), "renderer.")

    @property
    def noise(self) -> DepthNoise | None:
        """The depth-sensor model applied to every view, or None."""
        return self.renderer.noise.model

    def render_options(self, cores: int) -> dict:
        """The renderer's options for :func:`nbv.render.backends.render` on ``cores`` cores:
        ``threads`` (and for Blender ``blender``, ``device``, ``processes``) with the zeros
        resolved (:class:`Renderer`)."""
        r = self.renderer
        if r.backend != "blender":
            return {"threads": r.threads}
        processes = r.processes or (max(1, cores) if r.device == "CPU" else 1)
        threads = r.threads or max(1, cores // processes)
        return {
            "threads": threads,
            "blender": r.blender,
            "device": r.device,
            "processes": processes,
            "chunk": r.chunk,
        }

    @classmethod
    def from_identity(cls, identity: dict, out_dir: Path, **changes: Any) -> GeneratorSettings:
        """The settings a dataset recorded (its :meth:`data_identity`, the root attribute
        ``config``), to render more of the same data: ``changes`` replace fields (e.g.
        ``viewspaces``, ``models``); ``num_shards`` is 1 and ``progress`` as given.

        Raises:
            ValueError: an identity of another schema version (the message names both).
        """
        if identity.get("schema_version") != SCHEMA_VERSION:
            raise ValueError(
                f"the dataset's schema version {identity.get('schema_version')!r} is not this "
                f"code's {SCHEMA_VERSION!r}: make the dataset again"
            )
        noise = identity.get("noise")
        values: dict[str, Any] = {
            "source": identity["source"],
            "root": identity["root"],
            "categories": tuple(identity["categories"]) if identity["categories"] else None,
            "synthetic": Synthetic(identity["counts"]),
            "split_fractions": identity["split_fractions"],
            "seed": identity["seed"],
            "viewspaces": identity["viewspaces"],
            "intrinsics": Intrinsics(**identity["camera"]),
            "n_gt": identity["n_gt"],
            "eps": identity["eps"],
            "points_per_view": identity["points_per_view"],
            "keep_depth": identity["keep_depth"],
            "renderer": Renderer(
                backend=identity["backend"],
                noise=Noise(**noise, enabled=True) if noise is not None else Noise(),
            ),
            "models": tuple(identity["models"]) if "models" in identity else None,
        }
        return cls(out_dir=out_dir, **{**values, **changes})

    def data_identity(self) -> dict:
        """The settings that determine the arrays (must match to resume into a folder)."""
        noise = self.noise
        return {
            "schema_version": SCHEMA_VERSION,
            "source": self.source,
            "root": self.root,
            "categories": list(self.categories) if self.categories else None,
            "counts": self.synthetic.counts,
            "split_fractions": self.split_fractions,
            "seed": self.seed,
            "num_shards": self.num_shards,
            "viewspaces": self.viewspaces,
            "camera": asdict(self.intrinsics),
            "n_gt": self.n_gt,
            "eps": self.eps,
            "points_per_view": self.points_per_view,
            "keep_depth": self.keep_depth,
            "backend": self.renderer.backend,
            # Only when on: datasets made before the option keep their identity.
            **({"noise": asdict(noise)} if noise is not None else {}),
            **({"models": list(self.models)} if self.models is not None else {}),
        }
