"""The evaluation settings, validated from the hydra config (``conf/eval.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from nbv.policies.episode import DEFAULT_START_VIEWS, EPISODE_VIEWS

#: Every method name, in report order.
METHODS = (
    "random",
    "oracle",
    "pcnbv",
    "pcnbv_sph",
    "hull_sco",
    "hull_sco_sph",
    "hull_sco_probes",
    "hull_sco_replan",
)
#: The methods that run a network, and the checkpoint input each one needs.
NETWORK_INPUTS = {"pcnbv": "points", "pcnbv_sph": "signature"}
DATASETS = ("unseen", "test", "meshes")
VIEWSPACES = ("original", "permuted")
CHECKS = ("random_cloud", "permuted_state", "random_hull")
SIMULATIONS = ("analytic", "raycast")
BACKENDS = ("raycast", "blender")


class EvalConfigError(ValueError):
    """A setting that cannot be used; the message names the key and what is allowed."""


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
    eps: float = 0.00707
    points_per_view: int = 2048
    seed: int = 0


@dataclass(frozen=True)
class HullSettings:
    """Convex-hull set cover settings (``hull:`` in ``conf/eval.yaml``)."""

    n_samp: int = 16384
    simulation: str = "analytic"
    dilate: bool = False
    lmax: int = 3
    probes: int = 3
    probe_points: int = 100


@dataclass(frozen=True)
class EvalSettings:
    """Everything one evaluation needs (see ``conf/eval.yaml`` for the meaning of each)."""

    out_dir: Path
    methods: tuple[str, ...] = METHODS
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
        }
    )
    hull: HullSettings = field(default_factory=HullSettings)
    checks: tuple[str, ...] = CHECKS
    disturb_viewspaces: tuple[str, ...] = ("original",)
    disturb_start_views: tuple[int, ...] = (1, 10, 24)
    disturb_radius: float = 0.5
    seed: int = 0
    threads: int = 0
    progress: bool = True
    plots: bool = True

    def __post_init__(self) -> None:
        _allowed("methods", self.methods, METHODS)
        _allowed("dataset", self.datasets, DATASETS)
        _allowed("viewspace", self.viewspaces, VIEWSPACES)
        _allowed("disturb.checks", self.checks, CHECKS, empty_ok=True)
        _allowed("disturb.viewspace", self.disturb_viewspaces, VIEWSPACES, empty_ok=True)
        _allowed("hull.simulation", (self.hull.simulation,), SIMULATIONS)
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
            ("start_views", list(self.start_views), min(self.start_views, default=0) >= 0,
             "view indices >= 0"),
            ("limit", self.limit, self.limit is None or self.limit >= 1,
             "null or an integer >= 1"),
            ("threads", self.threads, self.threads >= 0, "an integer >= 0 (0 = torch's default)"),
            ("disturb.radius", self.disturb_radius, self.disturb_radius > 0, "a positive distance"),
            ("hull.n_samp", h.n_samp, h.n_samp >= 1, "an integer >= 1"),
            ("hull.dilate", h.dilate, isinstance(h.dilate, bool), "true or false"),
            ("hull.lmax", h.lmax, h.lmax >= 0, "an integer >= 0"),
            ("hull.probes", h.probes, h.probes >= 0, "an integer >= 0"),
            ("hull.probe_points", h.probe_points, h.probe_points >= 1, "an integer >= 1"),
            ("prepare.n_gt", p.n_gt, p.n_gt >= 1, "an integer >= 1"),
            ("prepare.eps", p.eps, p.eps > 0, "a positive distance"),
            ("prepare.points_per_view", p.points_per_view, p.points_per_view >= 0,
             "an integer >= 0 (0 = all)"),
        ]  # fmt: skip
        for key, value, ok, allowed in checks:
            if not ok:
                raise EvalConfigError(f"{key}={value!r}: must be {allowed}")
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


def _names(value, key: str) -> tuple[str, ...]:
    """A config value that may be one name or a list of names."""
    if value is None:
        return ()
    if isinstance(value, str):
        return (value,)
    if isinstance(value, list | tuple) and all(isinstance(v, str) for v in value):
        return tuple(value)
    raise EvalConfigError(f"{key}={value!r}: must be a name or a list of names")


def _int(value, key: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise EvalConfigError(f"{key}={value!r}: must be an integer")
    return value


def _ints(value, key: str) -> tuple[int, ...]:
    if not isinstance(value, list | tuple):
        raise EvalConfigError(f"{key}={value!r}: must be a list of view indices")
    return tuple(_int(v, key) for v in value)


def _number(value, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise EvalConfigError(f"{key}={value!r}: must be a number")
    return float(value)


def _section(c: dict, key: str, known: set[str]) -> dict:
    section = c.get(key)
    if not isinstance(section, dict):
        raise EvalConfigError(f"{key} must be a mapping with keys {sorted(known)}")
    unknown = sorted(set(section) - known)
    if unknown:
        raise EvalConfigError(f"unknown keys {key}.{unknown}; allowed: {sorted(known)}")
    return section


KNOWN_KEYS = {
    "run", "out_root", "methods", "dataset", "data_dir", "mesh_dir", "limit", "prepare",
    "viewspace", "start_views", "n_views", "checkpoints", "hull", "disturb", "seed", "threads",
    "progress", "plots",
}  # fmt: skip


def settings_from_config(cfg) -> EvalSettings:
    """Build :class:`EvalSettings` from the composed hydra config of ``conf/eval.yaml``.

    Raises:
        EvalConfigError: an unknown key or a bad value (the message names the key).
    """
    from omegaconf import OmegaConf

    c = OmegaConf.to_container(cfg, resolve=True) if not isinstance(cfg, dict) else dict(cfg)
    c.pop("hydra", None)
    unknown = sorted(set(c) - KNOWN_KEYS)
    if unknown:
        raise EvalConfigError(f"unknown keys {unknown}; allowed: {sorted(KNOWN_KEYS)}")
    prep = _section(c, "prepare", {"dir", "backend", "blender", "camera", "n_gt", "eps",
                                   "points_per_view", "seed"})  # fmt: skip
    camera = prep.get("camera", {})
    hull = _section(c, "hull", {"n_samp", "simulation", "dilate", "lmax", "probes",
                                "probe_points"})  # fmt: skip
    disturb = _section(c, "disturb", {"checks", "viewspace", "start_views", "radius"})
    checkpoints = c.get("checkpoints") or {}
    if not isinstance(checkpoints, dict):
        raise EvalConfigError(f"checkpoints={checkpoints!r}: must map method names to paths")
    unknown_ckpt = sorted(set(checkpoints) - set(NETWORK_INPUTS))
    if unknown_ckpt:
        raise EvalConfigError(
            f"checkpoints: unknown {unknown_ckpt}; allowed: {', '.join(NETWORK_INPUTS)}"
        )
    mesh_dir = c.get("mesh_dir")
    datasets = _names(c.get("dataset"), "dataset")
    if not datasets:
        datasets = ("unseen", "meshes") if mesh_dir else ("unseen",)
    start_views = _ints(c.get("start_views"), "start_views")
    disturb_starts = disturb.get("start_views")
    disturb_starts = (
        start_views if disturb_starts is None else _ints(disturb_starts, "disturb.start_views")
    )
    limit = c.get("limit")
    return EvalSettings(
        out_dir=Path(str(c["out_root"])) / str(c["run"]),
        methods=_names(c.get("methods"), "methods"),
        datasets=datasets,
        data_dir=Path(str(c["data_dir"])),
        mesh_dir=Path(str(mesh_dir)) if mesh_dir else None,
        limit=None if limit is None else _int(limit, "limit"),
        prepare=PrepareSettings(
            dir=Path(str(prep.get("dir", "outputs/eval/prepared"))),
            backend=str(prep.get("backend", "raycast")),
            blender=prep.get("blender"),
            width=_int(camera.get("width", 640), "prepare.camera.width"),
            height=_int(camera.get("height", 480), "prepare.camera.height"),
            focal=_number(camera.get("focal", 476.0), "prepare.camera.focal"),
            n_gt=_int(prep.get("n_gt", 16384), "prepare.n_gt"),
            eps=_number(prep.get("eps", 0.00707), "prepare.eps"),
            points_per_view=_int(prep.get("points_per_view", 2048), "prepare.points_per_view"),
            seed=_int(prep.get("seed", 0), "prepare.seed"),
        ),
        viewspaces=_names(c.get("viewspace"), "viewspace"),
        start_views=start_views,
        n_views=_int(c.get("n_views"), "n_views"),
        checkpoints={k: str(v) for k, v in checkpoints.items()},
        hull=HullSettings(
            n_samp=_int(hull.get("n_samp", 16384), "hull.n_samp"),
            simulation=str(hull.get("simulation", "analytic")),
            dilate=hull.get("dilate", False),
            lmax=_int(hull.get("lmax", 3), "hull.lmax"),
            probes=_int(hull.get("probes", 3), "hull.probes"),
            probe_points=_int(hull.get("probe_points", 100), "hull.probe_points"),
        ),
        checks=_names(disturb.get("checks"), "disturb.checks"),
        disturb_viewspaces=_names(disturb.get("viewspace"), "disturb.viewspace"),
        disturb_start_views=disturb_starts,
        disturb_radius=_number(disturb.get("radius", 0.5), "disturb.radius"),
        seed=_int(c.get("seed"), "seed"),
        threads=_int(c.get("threads", 0), "threads"),
        progress=bool(c.get("progress", True)),
        plots=bool(c.get("plots", True)),
    )
