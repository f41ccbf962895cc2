"""The settings of ``python -m nbv.plan``: :class:`PlanSettings`, the one declaration of
``conf/plan.yaml``'s keys (the hydra schema ``plan_schema`` is derived from it by
:mod:`nbv.config.settings`).

Every key is checked before any work: its range (field metadata), then what spans keys (exactly
one input, a method that does not read the ground truth, a start view of the viewspace, the
saved captures). The object's sphere against the cameras' distance is checked where the sphere is
known (:func:`nbv.plan.frame.object_frame`): it may come from the input.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nbv.config.schema import CameraConfig, ConfigError, PathsConfig, ProtocolConfig, check_views
from nbv.config.settings import Entry, check_ranges, setting
from nbv.geometry.camera import Intrinsics
from nbv.geometry.fusion import FusionSettings
from nbv.geometry.scores import DEFAULT_EPS, DEFAULT_N_GT, DEFAULT_POINTS_PER_VIEW
from nbv.geometry.viewspace_generators import ViewspaceSpec
from nbv.infogain.settings import VolumetricSettings
from nbv.plan.candidates import CandidateSettings
from nbv.plan.object_estimate import EstimateSettings
from nbv.policies.episode import EPISODE_VIEWS
from nbv.policies.registry import IG, METHODS, networks_of
from nbv.setcover.settings import HullSettings
from nbv.utils.fields import at_least, positive

#: The methods a user may plan with: those that do not read the ground truth.
PLANNABLE = tuple(name for name, m in METHODS.items() if not m.ground_truth)
_DISTANCE = "null or a positive distance"
INPUTS = ("give exactly one input: mesh=<mesh file> (simulated captures) or "
          "captures=<folder with views.json>")  # fmt: skip


def _null_or_positive(value: float | None) -> bool:
    return value is None or value > 0


@dataclass(frozen=True)
class ViewspaceSettings(ViewspaceSpec):
    """``viewspace:``, the candidate views: a :class:`ViewspaceSpec` and the cameras' distance.

    Directions are in a Y-up frame turned so that +y is ``up`` (a turntable's axis).

    Attributes:
        kind: ``original`` (PC-NBV's 33 views), ``permuted`` (33 others), ``file`` (a text file of
            ``x y z`` rows, directions), ``sphere`` / ``hemisphere`` (``n`` views of a Fibonacci
            lattice; the hemisphere above the equator), ``rings`` (``per_ring`` views at each of
            ``elevations``).
        file: the text file of ``kind=file``.
        n: views of ``sphere`` and ``hemisphere`` (an integer >= 2).
        elevations: degrees of the rings of ``rings`` (90 is the top pole).
        per_ring: views per ring of ``rings``: one count, or one per elevation.
        up: the rig's up axis: ``x``, ``y``, ``z``, ``-x``, ``-y`` or ``-z``.
        radius: the cameras' distance from the object's centre, world units; null = twice the
            object's radius (the dataset's ratio).
    """

    radius: float | None = setting(None, check=_null_or_positive, allowed=_DISTANCE)

    def __post_init__(self) -> None:
        check_ranges(self)
        per_ring = self.per_ring
        if not (isinstance(per_ring, int) or all(isinstance(x, int) for x in per_ring)):
            raise ConfigError(
                f"viewspace.per_ring={per_ring!r}: must be an integer or a list of them"
            )
        super().__post_init__()


@dataclass(frozen=True)
class ObjectSettings:
    """``object:``, the object's sphere in world units, or a region of interest that holds it.

    Null keeps the input's: the mesh's (bounding-box centre, farthest vertex), else the region
    ``box_min`` .. ``box_max`` (its centre, half its diagonal), else the captures' ``views.json``
    ``object``, else estimated from the captured points (one object on a support, found among
    the table, walls and stray points: :mod:`nbv.plan.object_estimate`, with ``estimate``).
    A sphere region of interest is ``center`` and ``radius``.

    Attributes:
        center: ``[x, y, z]``, or null.
        radius: a positive distance, or null.
        box_min: ``[x, y, z]``, with ``box_max``: a box region of interest (clutter such as a
            shelf bin's contents), or null.
        box_max: the box's other corner.
        estimate: how the object is found without them
            (:class:`~nbv.plan.object_estimate.EstimateSettings`).
    """

    center: tuple[float, float, float] | None = setting(
        None, check=lambda c: c is None or len(c) == 3, allowed="[x, y, z] or null"
    )
    radius: float | None = setting(None, check=_null_or_positive, allowed=_DISTANCE)
    box_min: tuple[float, float, float] | None = setting(
        None, check=lambda c: c is None or len(c) == 3, allowed="[x, y, z] or null"
    )
    box_max: tuple[float, float, float] | None = setting(
        None, check=lambda c: c is None or len(c) == 3, allowed="[x, y, z] or null"
    )
    estimate: EstimateSettings = setting(factory=EstimateSettings)

    def __post_init__(self) -> None:
        check_ranges(self)
        if (self.box_min is None) != (self.box_max is None):
            raise ConfigError("object.box_min and object.box_max: give both or neither")
        box = (self.box_min, self.box_max)
        if self.box_min is not None and not all(a < b for a, b in zip(*box, strict=True)):
            raise ConfigError(
                f"object.box_min={list(self.box_min)} must be below object.box_max="
                f"{list(self.box_max)} on every axis"
            )

    @property
    def box_sphere(self) -> tuple[tuple[float, float, float], float] | None:
        """The box region's ``(centre, radius)`` (half its diagonal), or None without one."""
        if self.box_min is None or self.box_max is None:
            return None
        lo, hi = self.box_min, self.box_max
        center = tuple(0.5 * (a + b) for a, b in zip(lo, hi, strict=True))
        return center, 0.5 * sum((b - a) ** 2 for a, b in zip(lo, hi, strict=True)) ** 0.5


@dataclass(frozen=True)
class PlanSettings:
    """Everything one plan needs (``conf/plan.yaml``).

    Attributes:
        mesh: the input, a mesh file (obj, ply, off, stl, glb, gltf; its units are the world's)
            to simulate captures of: a whole episode. Exclusive with ``captures``.
        captures: the input, a capture folder (``views.json`` and one file a view; the format is
            in :mod:`nbv.plan.captures`): the next view, or a one-shot planner's whole plan.
            (:class:`nbv.plan.planner.Planner` takes neither: its views are given one by one.)
        views: captures input: the views of the folder to plan from, by their index in
            ``views.json`` (e.g. ``[0, 7, 14]``), in that order; null takes them all.
        method: a registered method that does not read the ground truth (:data:`PLANNABLE`).
        checkpoint: the weights of the network the method runs (its own, or for a planner led by
            a network such as ``vig_hull_sco`` the leading one's); null =
            ``paths.checkpoints.<network>``, and when that file does not exist the weights the
            package ships.
        viewspace: the candidate views (:class:`ViewspaceSettings`).
        object: the object's sphere or region of interest (:class:`ObjectSettings`).
        candidates: where the robot's camera may go; the candidates it cannot reach are dropped
            and counted (:class:`~nbv.plan.candidates.CandidateSettings`; captures input).
        start_view: mesh input: the episode's first view (an index of the viewspace).
        n_views: views of an episode or a plan, the captured ones included (>= 2;
            ``protocol.n_views``).
        camera: the planner's (and the mesh simulation's) camera, ``conf/camera/``.
        match_degrees: a capture within this many degrees (seen from the object's centre) of a
            viewspace direction is that view; one farther off joins the plan as an extra
            visited view. In [0, 90).
        points_per_view: points kept of each view (a seeded random subset, as the dataset keeps
            them); 0 keeps all (``protocol.points_per_view``).
        eps: mesh input: coverage distance, normalised units (the object fits in radius 0.5;
            ``protocol.eps``).
        n_gt: mesh input: ground-truth points the coverage by view is measured on
            (``protocol.n_gt``).
        save_captures: mesh input: write the episode's first this many views as a capture
            folder (depth NPY and ``views.json``); 0 writes none.
        captures_out: where; null = ``<out_dir>/captures``. It must be new or empty.
        hull: the convex-hull planners' settings (:class:`HullSettings`).
        ig: the information-gain planners' settings (:class:`VolumetricSettings`).
        reconstruction: the depth views fused into ``reconstruction.ply``
            (:class:`~nbv.geometry.fusion.FusionSettings`).
        seed: every random draw (random views, hull samples, point subsets, the mesh's ground
            truth).
        picture: draw ``plan.png`` (matplotlib).
        page: write ``plan.html`` (plotly, self-contained).
        out_dir: the run folder: ``plan.json``, ``plan.png``, ``plan.html``, ``cloud.ply`` (and
            ``captures/`` with ``save_captures``), hydra's ``.hydra/`` and ``plan.log``.
    """

    mesh: Path | None = None
    captures: Path | None = None
    views: tuple[int, ...] | None = setting(
        None, check=lambda v: v is None or (len(v) > 0 and all(i >= 0 for i in v)
                                            and len(set(v)) == len(v)),
        allowed="null or a non-empty list of distinct view indices >= 0",
    )  # fmt: skip
    method: str = IG.name
    checkpoint: Path | None = None
    viewspace: ViewspaceSettings = setting(factory=ViewspaceSettings)
    object: ObjectSettings = setting(factory=ObjectSettings)
    candidates: CandidateSettings = setting(factory=CandidateSettings)
    start_view: int = setting(0, allows=at_least(0))
    n_views: int = setting(EPISODE_VIEWS, allows=at_least(2))
    camera: Intrinsics = setting(
        factory=Intrinsics, config=CameraConfig, convert=Intrinsics.from_config
    )
    match_degrees: float = setting(2.0, check=lambda v: 0 <= v < 90, allowed="degrees in [0, 90)")
    points_per_view: int = setting(DEFAULT_POINTS_PER_VIEW, allows=at_least(0, note="0 = all"))
    eps: float = setting(DEFAULT_EPS, allows=positive("distance"))
    n_gt: int = setting(DEFAULT_N_GT, allows=at_least(1))
    save_captures: int = setting(0, allows=at_least(0))
    captures_out: Path | None = None
    hull: HullSettings = setting(factory=HullSettings)
    ig: VolumetricSettings = setting(factory=VolumetricSettings)
    reconstruction: FusionSettings = setting(factory=FusionSettings)
    seed: int = 0
    picture: bool = True
    page: bool = True
    out_dir: Path = field(kw_only=True)

    def __post_init__(self) -> None:
        # Exactly one input is the command's rule (PlanEntry.build): a Planner takes neither.
        if self.mesh is not None and self.captures is not None:
            raise ConfigError(INPUTS)
        if self.method not in PLANNABLE:
            why = "reads the ground truth" if self.method in METHODS else "is not registered"
            raise ConfigError(f"method={self.method!r} {why}; allowed: {', '.join(PLANNABLE)}")
        check_ranges(self)
        n_candidates = len(self.viewspace.directions())  # reads a viewspace file: refused now
        check_views("start_view", [self.start_view], self.viewspace.kind, n_candidates)
        if self.mesh is not None and self.candidates.active:
            raise ConfigError(
                "candidates.*: the candidate limits apply to captures=<folder>; a mesh's episode "
                "plays the whole viewspace (give a viewspace file of the reachable views)"
            )
        if self.views is not None and self.mesh is not None:
            raise ConfigError("views: selects captures of captures=<folder>, not a mesh's views")
        if self.save_captures and self.mesh is None:
            raise ConfigError("save_captures needs mesh=<mesh file>: it saves simulated views")
        if self.save_captures > self.n_views:
            raise ConfigError(
                f"save_captures={self.save_captures}: the episode has n_views={self.n_views}"
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


class PlanEntry(Entry):
    """``plan_schema``; :meth:`build` also names a network method's default checkpoint."""

    def build(self, cfg: Any) -> PlanSettings:
        """The settings of a composed ``conf/plan.yaml``; ``checkpoint=null`` of a network
        method becomes ``paths.checkpoints.<method>`` (whether it exists is the registry's
        business when the network is loaded: else the shipped weights)."""
        settings = super().build(cfg)
        if settings.mesh is None and settings.captures is None:
            raise ConfigError(INPUTS)
        network = networks_of([settings.method])
        if settings.checkpoint is None and network:
            default = cfg["paths"]["checkpoints"].get(network[0])
            if default:
                settings = dataclasses.replace(settings, checkpoint=Path(default))
        return settings


ENTRY = PlanEntry(
    "plan_schema",
    PlanSettings,
    extra=(("protocol", ProtocolConfig), ("paths", PathsConfig)),
)
