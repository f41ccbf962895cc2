"""The evaluation settings: the schema of ``conf/eval.yaml`` and the settings built from it.

:class:`EvalConfig` is registered as ``eval_schema``, the first entry of the config's defaults
list: hydra refuses an unknown key or a value of the wrong type while composing. The method
names, the network methods' checkpoint inputs and the disturbance checks come from the registry
(:mod:`nbv.policies.registry`); the ``hull:`` keys are the fields of
:class:`nbv.planning.settings.PlannerSettings`, which :attr:`EvalSettings.hull` holds.
:class:`EvalSettings` keeps the checks of names, ranges and fields that go together, among them
that every start view lies in every selected viewspace.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omegaconf import MISSING

from nbv.config.schema import (
    CameraConfig,
    ConfigError,
    PathsConfig,
    ProtocolConfig,
    check_views,
    names,
    register,
    schema_of,
    validated,
)
from nbv.geometry.scores import DEFAULT_EPS
from nbv.geometry.viewspace import get_viewspace
from nbv.planning.settings import PlannerSettings, VolumetricSettings
from nbv.policies.episode import DEFAULT_START_VIEWS, EPISODE_VIEWS
from nbv.policies.registry import CHECKS, METHODS, NETWORK_INPUTS, SHIPPED_SCORER

DATASETS = ("unseen", "test", "meshes")
VIEWSPACES = ("original", "permuted")
BACKENDS = ("raycast", "blender")

#: The error of a setting that cannot be used (one class for every entry point).
EvalConfigError = ConfigError


@dataclass(frozen=True)
class PrepareSettings:
    """How ``mesh_dir`` becomes a dataset (see ``prepare:`` in ``conf/eval.yaml``)."""

    dir: Path = Path("outputs/eval/prepared")
    backend: str = "raycast"
    blender: str | None = None
    width: int = 640
    height: int = 480
    focal: float = 476.0
    n_gt: int = 16384
    eps: float = DEFAULT_EPS
    points_per_view: int = 2048
    seed: int = 0


@dataclass(frozen=True)
class EvalSettings:
    """Everything one evaluation needs (see ``conf/eval.yaml`` for the meaning of each)."""

    out_dir: Path
    methods: tuple[str, ...] = tuple(METHODS)
    datasets: tuple[str, ...] = ("unseen",)
    data_dir: Path = Path("data/generated/synthetic")
    mesh_dir: Path | None = None
    limit: int | None = None
    prepare: PrepareSettings = field(default_factory=PrepareSettings)
    viewspaces: tuple[str, ...] = VIEWSPACES
    start_views: tuple[int, ...] = DEFAULT_START_VIEWS
    n_views: int = EPISODE_VIEWS
    checkpoints: dict[str, str] = field(
        default_factory=lambda: {
            "pcnbv": "outputs/train/pcnbv_coverage_fold0/best.pt",
            "pcnbv_sph": "outputs/train/pcnbv_sph_coverage_fold0/best.pt",
            "vcnbv": "outputs/train/vcnbv/best.pt",
            "vcnbv_map": "outputs/train/vcnbv_map/best.pt",
        }
    )
    hull: PlannerSettings = field(default_factory=PlannerSettings)
    ig: VolumetricSettings = field(default_factory=VolumetricSettings)
    ig_scorer: Path | None = None
    checks: tuple[str, ...] = CHECKS
    disturb_viewspaces: tuple[str, ...] = ("original",)
    disturb_start_views: tuple[int, ...] = (1, 10, 24)
    disturb_radius: float = 0.5
    noise_sigmas: tuple[float, ...] = (0.002, 0.005, 0.01)
    random_repeats: int = 10
    seed: int = 0
    threads: int = 0
    workers: int = 1
    progress: bool = True
    plots: bool = True

    def scorer_file(self) -> Path:
        """The learned score ``ig_learned`` runs with: ``ig_scorer``, or the shipped one."""
        return self.ig_scorer if self.ig_scorer is not None else SHIPPED_SCORER

    def __post_init__(self) -> None:
        _allowed("methods", self.methods, tuple(METHODS))
        _allowed("dataset", self.datasets, DATASETS)
        _allowed("viewspace", self.viewspaces, VIEWSPACES)
        _allowed("disturb.checks", self.checks, CHECKS, empty_ok=True)
        _allowed("disturb.viewspace", self.disturb_viewspaces, VIEWSPACES, empty_ok=True)
        _allowed("prepare.backend", (self.prepare.backend,), BACKENDS)
        missing = sorted(set(NETWORK_INPUTS) & set(self.methods) - set(self.checkpoints))
        if missing:
            raise EvalConfigError(
                f"checkpoints: no entry for {missing}; give checkpoints.<method>=<path of best.pt>"
            )
        if "meshes" in self.datasets and self.mesh_dir is None:
            raise EvalConfigError("dataset=meshes needs mesh_dir=<folder of mesh files>")
        h, p = self.hull, self.prepare
        checks = [
            ("n_views", self.n_views, self.n_views >= 2, "an integer >= 2"),
            ("start_views", list(self.start_views), len(self.start_views) >= 1, "non-empty"),
            ("limit", self.limit, self.limit is None or self.limit >= 1,
             "null or an integer >= 1"),
            ("threads", self.threads, self.threads >= 0, "an integer >= 0 (0 = torch's default)"),
            ("workers", self.workers, self.workers >= 0,
             "an integer >= 0 (0 = one per available core, at most 8)"),
            ("disturb.radius", self.disturb_radius, self.disturb_radius > 0, "a positive distance"),
            ("disturb.noise", list(self.noise_sigmas),
             all(x > 0 for x in self.noise_sigmas) and len(set(self.noise_sigmas))
             == len(self.noise_sigmas), "distinct positive standard deviations"),
            ("random_repeats", self.random_repeats, self.random_repeats >= 1, "an integer >= 1"),
            ("hull.dilate", h.dilate, isinstance(h.dilate, bool), "true or false"),
            ("prepare.n_gt", p.n_gt, p.n_gt >= 1, "an integer >= 1"),
            ("prepare.eps", p.eps, p.eps > 0, "a positive distance"),
            ("prepare.points_per_view", p.points_per_view, p.points_per_view >= 0,
             "an integer >= 0 (0 = all)"),
        ]  # fmt: skip
        for key, value, ok, allowed in checks:
            if not ok:
                raise EvalConfigError(f"{key}={value!r}: must be {allowed}")
        for vs in self.viewspaces:
            check_views("start_views", self.start_views, vs, len(get_viewspace(vs)))
        if self.checks and self.check_viewspaces and not self.check_start_views:
            raise EvalConfigError(
                f"disturb.start_views={list(self.disturb_start_views)}: none of them is in "
                f"start_views={list(self.start_views)}; the checks compare with the undisturbed "
                "episodes from the same start views (give disturb.start_views=null for all)"
            )
        if self.mesh_dir is not None and not Path(self.mesh_dir).is_dir():
            raise EvalConfigError(f"mesh_dir={str(self.mesh_dir)!r}: no such folder")

    @property
    def check_viewspaces(self) -> tuple[str, ...]:
        """The viewspaces of the disturbance checks: ``disturb_viewspaces`` also evaluated."""
        return tuple(v for v in self.disturb_viewspaces if v in self.viewspaces)

    @property
    def check_start_views(self) -> tuple[int, ...]:
        """The start views of the disturbance checks: ``start_views`` also in
        ``disturb_start_views``."""
        return tuple(v for v in self.start_views if v in self.disturb_start_views)


def _allowed(key: str, values: tuple, allowed: tuple, empty_ok: bool = False) -> None:
    if not values and not empty_ok:
        raise EvalConfigError(f"{key} is empty; allowed: {', '.join(allowed)}")
    bad = [v for v in values if v not in allowed]
    if bad:
        raise EvalConfigError(
            f"{key}: unknown {', '.join(map(repr, bad))}; allowed: {', '.join(allowed)}"
        )
    if len(set(values)) != len(values):
        raise EvalConfigError(f"{key} lists a name twice: {list(values)}")


# The schema of conf/eval.yaml: which keys exist and their types (the values are there). A key
# that takes one name or a list of names is typed Any and checked by names.

#: ``hull:``: the fields of PlannerSettings.
HullConfig = schema_of(PlannerSettings, "HullConfig")
#: ``ig:``: the fields of VolumetricSettings.
IGConfig = schema_of(VolumetricSettings, "IGConfig")


@dataclass
class PrepareConfig:
    """``prepare:``; its camera comes from ``conf/camera/`` (``camera@prepare.camera``)."""

    dir: str = MISSING
    backend: str = MISSING
    blender: str | None = MISSING
    camera: CameraConfig = field(default_factory=CameraConfig)
    n_gt: int = MISSING
    eps: float = MISSING
    points_per_view: int = MISSING
    seed: int = MISSING


@dataclass
class DisturbConfig:
    """``disturb:``."""

    checks: Any = MISSING
    viewspace: Any = MISSING
    start_views: list[int] | None = MISSING
    radius: float = MISSING
    noise: list[float] = MISSING


@dataclass
class EvalConfig:
    """``conf/eval.yaml``."""

    run: str = MISSING
    out_root: str = MISSING
    methods: Any = MISSING
    dataset: Any = MISSING
    data_dir: str = MISSING
    mesh_dir: str | None = MISSING
    limit: int | None = MISSING
    prepare: PrepareConfig = field(default_factory=PrepareConfig)
    viewspace: Any = MISSING
    start_views: list[int] = MISSING
    n_views: int = MISSING
    checkpoints: dict[str, str] = MISSING
    hull: HullConfig = field(default_factory=HullConfig)
    ig: IGConfig = field(default_factory=IGConfig)
    ig_scorer: str | None = MISSING
    disturb: DisturbConfig = field(default_factory=DisturbConfig)
    random_repeats: int = MISSING
    seed: int = MISSING
    threads: int = MISSING
    workers: int = MISSING
    progress: bool = MISSING
    plots: bool = MISSING
    protocol: ProtocolConfig = field(default_factory=ProtocolConfig)
    paths: PathsConfig = field(default_factory=PathsConfig)


register("eval_schema", EvalConfig)


def settings_from_config(cfg) -> EvalSettings:
    """Build :class:`EvalSettings` from the composed hydra config of ``conf/eval.yaml``.

    Raises:
        EvalConfigError: an unknown key, a value of the wrong type or out of range, a start
            view outside a viewspace (the message names the key).
    """
    c = validated(EvalConfig, cfg)
    prep, disturb, checkpoints = c["prepare"], c["disturb"], c["checkpoints"]
    unknown_ckpt = sorted(set(checkpoints) - set(NETWORK_INPUTS))
    if unknown_ckpt:
        raise EvalConfigError(
            f"checkpoints: unknown {unknown_ckpt}; allowed: {', '.join(NETWORK_INPUTS)}"
        )
    mesh_dir = c["mesh_dir"]
    datasets = names(c["dataset"], "dataset")
    if not datasets:
        datasets = ("unseen", "meshes") if mesh_dir else ("unseen",)
    start_views = tuple(c["start_views"])
    disturb_starts = disturb["start_views"]
    disturb_starts = start_views if disturb_starts is None else tuple(disturb_starts)
    try:
        hull = PlannerSettings(**c["hull"])
        ig = VolumetricSettings(**c["ig"])
    except ValueError as err:  # the settings name the hull.<key> or ig.<key> they refuse
        raise EvalConfigError(str(err)) from None
    camera = prep["camera"]
    return EvalSettings(
        out_dir=Path(c["out_root"]) / c["run"],
        methods=names(c["methods"], "methods"),
        datasets=datasets,
        data_dir=Path(c["data_dir"]),
        mesh_dir=Path(mesh_dir) if mesh_dir else None,
        limit=c["limit"],
        prepare=PrepareSettings(
            dir=Path(prep["dir"]),
            backend=prep["backend"],
            blender=prep["blender"],
            width=camera["width"],
            height=camera["height"],
            focal=camera["focal"],
            n_gt=prep["n_gt"],
            eps=prep["eps"],
            points_per_view=prep["points_per_view"],
            seed=prep["seed"],
        ),
        viewspaces=names(c["viewspace"], "viewspace"),
        start_views=start_views,
        n_views=c["n_views"],
        checkpoints=dict(checkpoints),
        hull=hull,
        ig=ig,
        ig_scorer=Path(c["ig_scorer"]) if c["ig_scorer"] else None,
        checks=names(disturb["checks"], "disturb.checks"),
        disturb_viewspaces=names(disturb["viewspace"], "disturb.viewspace"),
        disturb_start_views=disturb_starts,
        disturb_radius=disturb["radius"],
        noise_sigmas=tuple(float(x) for x in disturb["noise"]),
        random_repeats=c["random_repeats"],
        seed=c["seed"],
        threads=c["threads"],
        workers=c["workers"],
        progress=c["progress"],
        plots=c["plots"],
    )
