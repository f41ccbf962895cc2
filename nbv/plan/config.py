"""The settings of ``python -m nbv.plan``: the schema of ``conf/plan.yaml`` and the settings built
from it.

:class:`PlanConfig` is registered as ``plan_schema``, the first entry of the config's defaults
list: hydra refuses an unknown key or a value of the wrong type while composing.
:class:`PlanSettings` checks the rest before any work: exactly one input, a method that does not
read the ground truth (the registry's ``ground_truth``), a valid viewspace spec, the object's
centre and radius, ranges.
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
    register,
    schema_of,
    validated,
)
from nbv.geometry.camera import Intrinsics
from nbv.geometry.viewspace_generators import ViewspaceSpec
from nbv.planning.settings import PlannerSettings, VolumetricSettings
from nbv.policies.registry import METHODS, NETWORK_INPUTS

#: The methods a user may plan with: those that do not read the ground truth.
PLANNABLE = tuple(name for name, m in METHODS.items() if not m.ground_truth)


@dataclass(frozen=True)
class PlanSettings:
    """Everything one plan needs (see ``conf/plan.yaml`` for the meaning of each).

    Attributes:
        out_dir: the run folder (plan.json, plan.png, plan.html, cloud.ply, ...).
        mesh: a mesh file to simulate captures of (exclusive with ``captures``).
        captures: a capture folder (:mod:`nbv.plan.captures`).
        method: a registered method of :data:`PLANNABLE`.
        viewspace: the candidate directions.
        distance: the cameras' distance from the object's centre, world units; None = twice
            its radius.
        center, radius: the object's sphere, world units; None = from the captures.
        start_view: the mesh episode's first view.
        n_views: views of an episode or a plan, the captured ones included.
        camera: the planner's (and the mesh simulation's) camera.
        match_degrees: a capture within this angle of a viewspace direction is that view.
        save_captures: write the mesh episode's first this many views as a capture folder.
        captures_out: where (None = ``<out_dir>/captures``).
        checkpoint: a network method's weights (None = ``paths.checkpoints`` or the shipped).
    """

    out_dir: Path
    method: str
    mesh: Path | None = None
    captures: Path | None = None
    viewspace: ViewspaceSpec = field(default_factory=ViewspaceSpec)
    distance: float | None = None
    center: tuple[float, float, float] | None = None
    radius: float | None = None
    start_view: int = 0
    n_views: int = 10
    camera: Intrinsics = field(default_factory=Intrinsics)
    match_degrees: float = 2.0
    points_per_view: int = 2048
    eps: float = 0.00707
    n_gt: int = 16384
    save_captures: int = 0
    captures_out: Path | None = None
    hull: PlannerSettings = field(default_factory=PlannerSettings)
    ig: VolumetricSettings = field(default_factory=VolumetricSettings)
    checkpoint: Path | None = None
    seed: int = 0
    picture: bool = True
    page: bool = True

    def __post_init__(self) -> None:
        if (self.mesh is None) == (self.captures is None):
            raise ConfigError(
                "give exactly one input: mesh=<mesh file> (simulated captures) or "
                "captures=<folder with views.json>"
            )
        if self.method not in PLANNABLE:
            why = "reads the ground truth" if self.method in METHODS else "is not registered"
            raise ConfigError(f"method={self.method!r} {why}; allowed: {', '.join(PLANNABLE)}")
        checks = [
            ("n_views", self.n_views, self.n_views >= 2, "an integer >= 2"),
            ("start_view", self.start_view, self.start_view >= 0, "an integer >= 0"),
            ("viewspace.radius", self.distance, self.distance is None or self.distance > 0,
             "null or a positive distance"),
            ("object.radius", self.radius, self.radius is None or self.radius > 0,
             "null or a positive distance"),
            ("match_degrees", self.match_degrees, 0 <= self.match_degrees < 90,
             "degrees in [0, 90)"),
            ("points_per_view", self.points_per_view, self.points_per_view >= 0,
             "an integer >= 0 (0 = all)"),
            ("eps", self.eps, self.eps > 0, "a positive distance"),
            ("n_gt", self.n_gt, self.n_gt >= 1, "an integer >= 1"),
            ("save_captures", self.save_captures, self.save_captures >= 0, "an integer >= 0"),
        ]  # fmt: skip
        for key, value, ok, allowed in checks:
            if not ok:
                raise ConfigError(f"{key}={value!r}: must be {allowed}")
        n_candidates = len(self.viewspace.directions())  # reads a viewspace file: refused now
        check_views("start_view", [self.start_view], self.viewspace.kind, n_candidates)
        if self.save_captures and self.mesh is None:
            raise ConfigError("save_captures needs mesh=<mesh file>: it saves simulated views")
        if self.save_captures > self.n_views:
            raise ConfigError(
                f"save_captures={self.save_captures}: the episode has n_views={self.n_views}"
            )
        if self.distance is not None and self.radius is not None and self.distance <= self.radius:
            raise ConfigError(
                f"viewspace.radius={self.distance}: the cameras would sit inside the object's "
                f"sphere (object.radius={self.radius})"
            )
        for key, path in (("mesh", self.mesh), ("captures", self.captures)):
            if path is not None and not Path(path).exists():
                raise ConfigError(f"{key}={str(path)!r}: no such file or folder")
        saved = self.captures_out or Path(self.out_dir) / "captures"
        if self.save_captures and saved.exists() and any(saved.iterdir()):
            raise ConfigError(
                f"captures_out={str(saved)!r}: exists and is not empty; saved captures go to a "
                "new folder (another out_dir or captures_out)"
            )


#: ``hull:`` and ``ig:``: the fields of the planners' settings, each null (= the settings'
#: default) unless given, so the planners' defaults are written once, in their settings.
HullConfig = schema_of(PlannerSettings, "PlanHullConfig", optional=True)
IGConfig = schema_of(VolumetricSettings, "PlanIGConfig", optional=True)


@dataclass
class ViewspaceConfig:
    """``viewspace:`` (the fields of :class:`ViewspaceSpec`, and the cameras' distance)."""

    kind: str = MISSING
    file: str | None = MISSING
    n: int = MISSING
    elevations: list[float] = MISSING
    per_ring: Any = MISSING
    up: str = MISSING
    radius: float | None = MISSING


@dataclass
class ObjectConfig:
    """``object:``."""

    center: list[float] | None = MISSING
    radius: float | None = MISSING


@dataclass
class PlanConfig:
    """``conf/plan.yaml``."""

    mesh: str | None = MISSING
    captures: str | None = MISSING
    method: str = MISSING
    out_dir: str = MISSING
    viewspace: ViewspaceConfig = field(default_factory=ViewspaceConfig)
    object: ObjectConfig = field(default_factory=ObjectConfig)
    start_view: int = MISSING
    n_views: int = MISSING
    camera: CameraConfig = field(default_factory=CameraConfig)
    match_degrees: float = MISSING
    points_per_view: int = MISSING
    eps: float = MISSING
    n_gt: int = MISSING
    save_captures: int = MISSING
    captures_out: str | None = MISSING
    hull: HullConfig = field(default_factory=HullConfig)
    ig: IGConfig = field(default_factory=IGConfig)
    checkpoint: str | None = MISSING
    seed: int = MISSING
    picture: bool = MISSING
    page: bool = MISSING
    protocol: ProtocolConfig = field(default_factory=ProtocolConfig)
    paths: PathsConfig = field(default_factory=PathsConfig)


register("plan_schema", PlanConfig)


def settings_from_config(cfg) -> PlanSettings:
    """Build :class:`PlanSettings` from the composed hydra config of ``conf/plan.yaml``.

    Raises:
        ConfigError: an unknown key, a value of the wrong type or out of range, a bad viewspace
            spec, a ground-truth method, a missing input (the message names the key).
    """
    c = validated(PlanConfig, cfg)
    vs, obj, cam = c["viewspace"], c["object"], c["camera"]
    per_ring = vs["per_ring"]
    if isinstance(per_ring, list):
        per_ring = tuple(per_ring)
    if not (isinstance(per_ring, int) or all(isinstance(x, int) for x in per_ring)):
        raise ConfigError(f"viewspace.per_ring={per_ring!r}: must be an integer or a list of them")
    center = obj["center"]
    if center is not None and len(center) != 3:
        raise ConfigError(f"object.center={center}: must be [x, y, z] or null")
    try:
        spec = ViewspaceSpec(
            kind=vs["kind"],
            file=vs["file"],
            n=vs["n"],
            elevations=tuple(vs["elevations"]),
            per_ring=per_ring,
            up=vs["up"],
        )
        hull = PlannerSettings(**{k: v for k, v in c["hull"].items() if v is not None})
        ig = VolumetricSettings(**{k: v for k, v in c["ig"].items() if v is not None})
        camera = Intrinsics.centred(cam["width"], cam["height"], cam["focal"])
    except ValueError as err:  # each names its key
        raise ConfigError(str(err)) from None
    checkpoint = c["checkpoint"]
    method = c["method"]
    if checkpoint is None and method in NETWORK_INPUTS:
        checkpoint = c["paths"]["checkpoints"].get(method)
    return PlanSettings(
        out_dir=Path(c["out_dir"]),
        method=method,
        mesh=Path(c["mesh"]) if c["mesh"] else None,
        captures=Path(c["captures"]) if c["captures"] else None,
        viewspace=spec,
        distance=vs["radius"],
        center=tuple(center) if center is not None else None,
        radius=obj["radius"],
        start_view=c["start_view"],
        n_views=c["n_views"],
        camera=camera,
        match_degrees=c["match_degrees"],
        points_per_view=c["points_per_view"],
        eps=c["eps"],
        n_gt=c["n_gt"],
        save_captures=c["save_captures"],
        captures_out=Path(c["captures_out"]) if c["captures_out"] else None,
        hull=hull,
        ig=ig,
        checkpoint=Path(checkpoint) if checkpoint else None,
        seed=c["seed"],
        picture=c["picture"],
        page=c["page"],
    )
