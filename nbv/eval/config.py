"""The settings of ``python -m nbv.eval``: :class:`EvalSettings`, the one declaration of
``conf/eval.yaml``'s keys, nested like it (the hydra schema ``eval_schema`` is derived from it by
:mod:`nbv.config.settings`).

The method names, the network methods' checkpoint inputs and the disturbance checks come from the
registry (:mod:`nbv.policies.registry`); the ``setcover:`` and ``infogain:`` groups are the
planners' own settings (:class:`~nbv.setcover.settings.SetCoverSettings`,
:class:`~nbv.infogain.settings.InfoGainSettings`). :class:`EvalSettings` keeps the checks of
names and of fields that go together, among them that every start view lies in every selected
viewspace. :meth:`EvalSettings.stored` is the flat layout ``results.json`` and the episode log
store the settings in.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nbv.assets.mesh_sources import MESH_SOURCES, prepared_datasets
from nbv.assets.weights import SHIPPED_SCORER
from nbv.config.schema import (
    CameraConfig,
    ConfigError,
    PathsConfig,
    ProtocolConfig,
    check_views,
)
from nbv.config.settings import Entry, check_ranges, setting
from nbv.eval.config_checks import (
    check_allowed,
    check_viewspaces,
    distinct_positive,
    group_ranges,
    names_setting,
    optional_path,
)
from nbv.geometry.camera import Intrinsics
from nbv.geometry.scores import DEFAULT_EPS, DEFAULT_N_GT, DEFAULT_POINTS_PER_VIEW
from nbv.geometry.viewspace import ViewspaceError, get_viewspace
from nbv.infogain.settings import InfoGainSettings
from nbv.policies.episode import DEFAULT_START_VIEWS, EPISODE_VIEWS
from nbv.policies.method import CHECKS
from nbv.policies.registry import DEFAULT_METHODS, METHODS, NETWORK_INPUTS, networks_of
from nbv.setcover.settings import SetCoverSettings
from nbv.utils.fields import at_least, or_null, positive

#: The datasets read from ``data_dir`` (a dataset of ``make dataset``); the others are prepared
#: from a mesh source's files (:func:`nbv.assets.mesh_sources.prepared_datasets`).
DATA_DIR_DATASETS = ("unseen", "test")


def datasets() -> tuple[str, ...]:
    """Every dataset name ``dataset=`` allows: ``unseen``, ``test``, then the prepared ones."""
    return (*DATA_DIR_DATASETS, *prepared_datasets())


#: The two viewspaces every dataset renders (the networks' and the permuted one).
VIEWSPACES = ("original", "permuted")
BACKENDS = ("raycast", "blender")
# TODO(issue 28): one shared constant for the points kept per view (also nbv/plan/config.py
# and nbv/dataset/generator_settings.py); conf/protocol/ sets the value users get.

#: The error of a setting that cannot be used (one class for every entry point).
EvalConfigError = ConfigError


@dataclass(frozen=True)
class PrepareSettings:
    """How ``mesh_dir`` becomes a dataset (:func:`nbv.dataset.generator.generate`,
    ``source=folder``). The result is cached in ``<dir>/<hash of the files and these settings>/``,
    so reruns reuse it.

    Attributes:
        dir: the cache folder of prepared mesh folders.
        backend: ``raycast`` (Open3D, 3-4x faster than Blender here, the same camera model) or
            ``blender`` (Cycles, the reference).
        blender: a Blender binary for ``backend=blender``; null = the bpy module of this
            environment.
        camera: the camera, from ``conf/camera/`` (``camera@prepare.camera=small``;
            ``prepare.camera.width=...`` for one value): ``width``, ``height`` (pixels) and
            ``focal`` (pixels, fx = fy, principal point at the image centre).
        n_gt: ground-truth points sampled uniformly on each normalised mesh.
        eps: coverage distance (world units; objects fit in a sphere of radius 0.5).
        points_per_view: points kept of each view (a seeded random subset); 0 keeps all.
        seed: the seed of the sampling.
    """

    dir: Path = Path("outputs/eval/prepared")
    backend: str = "raycast"
    blender: str | None = None
    camera: Intrinsics = setting(
        factory=Intrinsics.centred, config=CameraConfig, convert=Intrinsics.from_config
    )
    n_gt: int = setting(DEFAULT_N_GT, allows=at_least(1))
    eps: float = setting(DEFAULT_EPS, allows=positive("distance"))
    points_per_view: int = setting(DEFAULT_POINTS_PER_VIEW, allows=at_least(0, note="0 = all"))
    seed: int = 0

    def __post_init__(self) -> None:
        check_allowed("prepare.backend", (self.backend,), BACKENDS)
        group_ranges(self, "prepare")
        c = self.camera
        if c != Intrinsics.centred(c.width, c.height, c.fx):
            # The cache's identity holds width, height and focal: the camera conf/camera/ makes.
            raise EvalConfigError(
                f"prepare.camera={c}: must have fx = fy and the principal point at the centre"
            )


@dataclass(frozen=True)
class DisturbSettings:
    """The disturbance checks (the paper's Fig. 18), run on the selected methods they apply to
    (the registry's ``checks`` of each method).

    Attributes:
        checks: any of ``random_cloud`` (the networks get a random cloud, same size, uniform in
            a ball, and the true view state), ``permuted_state`` (the networks get the true
            cloud and a random view state with as many visited views; they still may not pick
            a visited view), ``random_hull`` (hull_sco plans on the hull of as many random
            points as the start view has), ``position_noise`` (the networks, the one-shot
            planners and ig see every captured point moved by Gaussian noise of each sigma in
            ``noise``); empty = none.
        viewspaces: the viewspaces to run them on (key ``viewspace``: a name or a list); those
            not evaluated (``viewspace``) are left out.
        start_views: the start views of the checks: those of ``start_views`` also in this list;
            null = all of them. Three by default (one per camera ring): the PCNBV forward pass
            (~0.09 s on 2 idle cores, 9 per episode) dominates the run time.
        radius: radius of the ball the random points are drawn in (objects fit in radius 0.5).
        noise: standard deviations of ``position_noise``, object frame units (the object fits
            in radius 0.5); distinct and positive.
    """

    checks: tuple[str, ...] = names_setting("disturb.checks", CHECKS)
    viewspaces: tuple[str, ...] = names_setting(
        "disturb.viewspace", VIEWSPACES[:1], key="viewspace"
    )
    start_views: tuple[int, ...] | None = (1, 10, 24)
    radius: float = setting(0.5, allows=positive("distance"))
    noise: tuple[float, ...] = setting(
        (0.002, 0.005, 0.01), check=distinct_positive,
        allowed="distinct positive standard deviations",
    )  # fmt: skip

    def __post_init__(self) -> None:
        check_allowed("disturb.checks", self.checks, CHECKS, empty_ok=True)
        check_viewspaces("disturb.viewspace", self.viewspaces, empty_ok=True)
        group_ranges(self, "disturb")


@dataclass(frozen=True)
class EvalSettings:
    """Everything one evaluation needs: ``conf/eval.yaml``, key by key.

    Attributes:
        run: the run's name: results go to ``<out_root>/<run>/`` (results.json, summary.csv,
            report.md, the PNG plots, hydra's ``.hydra/`` and ``eval.log``).
        out_root: the folder of the evaluation runs.
        methods: the methods to run (a name or a list), any of the registry's
            (:mod:`nbv.policies.registry`; ``docs/methods.md``); by default those it marks
            ``by_default``: every method but ``pcnbv_vig`` and ``oracle_vig``, each as costly
            as ``pcnbv``, the run's costliest (name them to run them). A network method whose
            checkpoint is missing runs on the weights the package ships (nbv/assets/weights/);
            one whose checkpoint cannot be used, or none shipped, is listed as skipped, and so
            is a method led by its network.
        datasets: the models to evaluate (key ``dataset``: a name or a list): ``unseen`` (the 8
            unseen categories, split test, of the dataset in ``data_dir``), ``test`` (the test
            split of the 8 training categories of ``data_dir``), ``meshes`` (every mesh file of
            ``mesh_dir``, prepared through the dataset pipeline and cached), ``ycb`` (the 78 YCB
            objects) or ``scans`` (15 classic scanned models), the real objects ``make
            real-data`` installs, prepared like ``meshes``. null = unseen, plus meshes when
            ``mesh_dir`` is set.
        data_dir: a dataset folder made by ``make dataset``.
        mesh_dir: a folder of mesh files (obj, ply, off, stl, glb, gltf; searched recursively),
            a complex-object test set; null = none.
        limit: at most this many models of each dataset (spread over its categories); null =
            all.
        prepare: how ``mesh_dir`` is turned into a dataset (:class:`PrepareSettings`).
        viewspaces: the viewspaces to run on (key ``viewspace``: a name or a list): ``original``
            (the networks' training viewspace) and/or ``permuted`` (other camera positions in
            another order: the networks' indices point elsewhere), or a generated one:
            ``hemisphere_<n>`` / ``sphere_<n>`` (a Fibonacci lattice of n views; the protocols
            ``protocol=hemisphere_30`` and ``protocol=sphere_32`` set them with their start
            views) or a file of ``x y z`` rows. Views the dataset lacks are rendered once, with
            the dataset's own settings, into ``prepare.dir``. A network with one output per view
            of another viewspace is skipped there, and the report says so.
        start_views: the episodes' start views (indices into every selected viewspace);
            non-empty.
        n_views: views per episode, the start view included; at least 2.
        checkpoints: network method name -> its training checkpoint (``best.pt`` of
            ``python -m train``, or of ``python -m train.conditioned`` for the
            viewspace-conditioned ones); every selected network method needs one, and so does
            the network a selected method is led by (``vig_hull_sco``: ``pcnbv_sph_vig``'s).
        setcover: the convex-hull set cover (:class:`~nbv.setcover.settings.SetCoverSettings`).
        infogain: the volumetric information gain's occupancy map and scores
            (:class:`~nbv.infogain.settings.InfoGainSettings`).
        ig_scorer: the learned score of ig_learned, a ``scorer.json`` of
            ``python -m train.scorer``; null = the one the package ships
            (nbv/assets/weights/ig_learned.json). It uses the ``infogain:`` settings for its map.
        disturb: the disturbance checks (:class:`DisturbSettings`).
        random_repeats: episodes of a stochastic method (random) run with this many seeds each;
            its numbers are their means, so a comparison with random is not one seed's luck.
        seed: every random draw (random views, probes, hull samples, disturbances) derives from
            this seed, the method, the model, the viewspace and the start view.
        threads: torch threads for the networks (0 = torch's default). ``python -m nbv.eval``
            makes idle OpenMP threads sleep (OMP_WAIT_POLICY=PASSIVE, unless the environment
            sets it: :mod:`nbv.models.threads`), so cores busy with other work cost about 1.1-2x,
            not 4-11x.
        workers: worker processes, each running whole models (0 = one per available core, at
            most 8; 1 = everything in this process). With more than one, each worker's torch
            runs ``threads`` threads (0 = 1): the timing table is then of one thread per
            episode.
        progress: show a progress bar.
        plots: draw the PNG plots (matplotlib, Agg).
        batched: run each method's episodes of a model in lockstep, a network deciding for all
            of them in one batched forward pass (:mod:`nbv.policies.lockstep`); false: one
            episode after another. Both give the same episodes; batched is faster.
        precision: the PCNBV networks' arithmetic: null = each checkpoint's (one trained in
            bfloat16, as the shipped weights, runs in bfloat16 where the CPU has it natively,
            AMX or AVX512-BF16, else in float32); ``fp32`` runs float32 everywhere (what an
            AVX2-only CPU runs: to time or reproduce such a machine), ``bf16`` and ``auto`` as
            :mod:`nbv.models.precision` defines them.
    """

    run: str = field(kw_only=True)
    out_root: Path = Path("outputs/eval")
    methods: tuple[str, ...] = names_setting("methods", DEFAULT_METHODS)
    datasets: tuple[str, ...] = names_setting("dataset", (), key="dataset", config_default=None)
    data_dir: Path = Path("data/generated/synthetic")
    mesh_dir: Path | None = setting(None, convert=optional_path)
    limit: int | None = setting(None, allows=or_null(at_least(1)))
    prepare: PrepareSettings = setting(factory=PrepareSettings)
    viewspaces: tuple[str, ...] = names_setting("viewspace", VIEWSPACES, key="viewspace")
    start_views: tuple[int, ...] = setting(
        DEFAULT_START_VIEWS, check=lambda v: len(v) >= 1, allowed="non-empty"
    )
    n_views: int = setting(EPISODE_VIEWS, allows=at_least(2))
    checkpoints: dict[str, str] = setting(factory=dict)
    setcover: SetCoverSettings = setting(factory=SetCoverSettings)
    infogain: InfoGainSettings = setting(factory=InfoGainSettings)
    ig_scorer: Path | None = setting(None, convert=optional_path)
    disturb: DisturbSettings = setting(factory=DisturbSettings)
    random_repeats: int = setting(10, allows=at_least(1))
    seed: int = 0
    threads: int = setting(0, allows=at_least(0, note="0 = torch's default"))
    workers: int = setting(1, allows=at_least(0, note="0 = one per available core, at most 8"))
    progress: bool = True
    plots: bool = True
    batched: bool = True
    precision: str | None = setting(
        None, check=lambda v: v is None or v in ("auto", "fp32", "bf16"),
        allowed="null, auto, fp32 or bf16",
    )  # fmt: skip

    @property
    def out_dir(self) -> Path:
        """The run folder, ``<out_root>/<run>``."""
        return Path(self.out_root) / self.run

    def scorer_file(self) -> Path:
        """The learned score ``ig_learned`` runs with: ``ig_scorer``, or the shipped one."""
        return self.ig_scorer if self.ig_scorer is not None else SHIPPED_SCORER

    def __post_init__(self) -> None:
        unknown_ckpt = sorted(set(self.checkpoints) - set(NETWORK_INPUTS))
        if unknown_ckpt:
            raise EvalConfigError(
                f"checkpoints: unknown {unknown_ckpt}; allowed: {', '.join(NETWORK_INPUTS)}"
            )
        if not self.datasets:  # null: derived from mesh_dir
            derived = ("unseen", "meshes") if self.mesh_dir else ("unseen",)
            object.__setattr__(self, "datasets", derived)
        check_allowed("methods", self.methods, tuple(METHODS))
        check_allowed("dataset", self.datasets, datasets())
        check_viewspaces("viewspace", self.viewspaces)
        missing = sorted(set(networks_of(self.methods)) - set(self.checkpoints))
        if missing:
            raise EvalConfigError(
                f"checkpoints: no entry for {missing}; give checkpoints.<method>=<path of best.pt>"
            )
        prepared = prepared_datasets()
        for name in self.datasets:
            source = prepared.get(name)
            if source and MESH_SOURCES[source].installed is None and self.mesh_dir is None:
                raise EvalConfigError(f"dataset={name} needs mesh_dir=<folder of mesh files>")
        check_ranges(self)
        if not isinstance(self.setcover.dilate, bool):
            raise EvalConfigError(
                f"setcover.dilate={self.setcover.dilate!r}: must be true or false"
            )
        for vs in self.viewspaces:
            try:
                n = len(get_viewspace(vs))
            except ViewspaceError as err:
                raise EvalConfigError(f"viewspace={vs}: {err}") from None
            if max(self.start_views) >= n and vs not in VIEWSPACES:
                raise EvalConfigError(
                    f"start_views={[v for v in self.start_views if v >= n]}: the viewspace "
                    f"{vs!r} has {n} views (indices 0..{n - 1}); give start_views=[...] or a "
                    "protocol that sets them for it (protocol=hemisphere_30, protocol=sphere_32)"
                )
            check_views("start_views", self.start_views, vs, n)
        if self.disturb.checks and self.check_viewspaces and not self.check_start_views:
            raise EvalConfigError(
                f"disturb.start_views={list(self.disturb.start_views)}: none of them is in "
                f"start_views={list(self.start_views)}; the checks compare with the undisturbed "
                "episodes from the same start views (give disturb.start_views=null for all)"
            )
        if self.mesh_dir is not None and not Path(self.mesh_dir).is_dir():
            raise EvalConfigError(f"mesh_dir={str(self.mesh_dir)!r}: no such folder")

    @property
    def check_viewspaces(self) -> tuple[str, ...]:
        """The viewspaces of the disturbance checks: ``disturb.viewspaces`` also evaluated."""
        return tuple(v for v in self.disturb.viewspaces if v in self.viewspaces)

    @property
    def check_start_views(self) -> tuple[int, ...]:
        """The start views of the disturbance checks: ``start_views`` also in
        ``disturb.start_views`` (all of them when that is null)."""
        chosen = self.disturb.start_views
        return tuple(v for v in self.start_views if chosen is None or v in chosen)

    def stored(self) -> dict[str, Any]:
        """The settings as ``results.json`` and the episode log's identity store them.

        The layout predates the nested YAML and stays, so that runs stay comparable and
        resumable: ``out_dir`` for ``run`` and ``out_root``; the camera's ``width``, ``height``
        and ``focal`` inside ``prepare``; the ``disturb`` group flat, as ``checks``,
        ``disturb_viewspaces``, ``disturb_start_views`` (resolved: null is ``start_views``),
        ``disturb_radius`` and ``noise_sigmas``. Every other field keeps its name, in field
        order (values as :func:`dataclasses.asdict` gives them: paths, tuples).
        """
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "run":
                out["out_dir"] = self.out_dir
            elif f.name == "out_root":
                continue
            elif f.name == "prepare":
                out["prepare"] = _stored_prepare(value)
            elif f.name == "disturb":
                out.update(
                    checks=value.checks,
                    disturb_viewspaces=value.viewspaces,
                    disturb_start_views=(
                        self.start_views if value.start_views is None else value.start_views
                    ),
                    disturb_radius=value.radius,
                    noise_sigmas=value.noise,
                )
            elif dataclasses.is_dataclass(value):
                out[f.name] = dataclasses.asdict(value)
            else:
                out[f.name] = dict(value) if isinstance(value, dict) else value
        return out


def _stored_prepare(prepare: PrepareSettings) -> dict[str, Any]:
    """``prepare`` as :meth:`EvalSettings.stored` gives it: the camera as width, height, focal."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(prepare):
        value = getattr(prepare, f.name)
        if f.name == "camera":
            out.update(width=value.width, height=value.height, focal=value.fx)
        else:
            out[f.name] = value
    return out


#: ``python -m nbv.eval``: the schema ``eval_schema`` and the builder of :class:`EvalSettings`.
ENTRY = Entry(
    "eval_schema",
    EvalSettings,
    extra=(("protocol", ProtocolConfig), ("paths", PathsConfig)),
)
