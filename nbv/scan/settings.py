"""The settings of a scan: :class:`ScanSettings`, what the robot's
:class:`~nbv.scan.planner.Planner` and the decision need (the method, the candidate views, the
object, the camera, the planners' own settings), as plain frozen dataclasses.

Made in code (``ScanSettings(method="ig_learned")``) or by keyword overrides
(:func:`nbv.utils.settings_values.replaced`); every range is checked when the object is made, and a
bad value raises :class:`~nbv.utils.fields.ConfigError` naming its key. ``python -m nbv.plan``
adds its inputs and outputs (:class:`nbv.plan.config.PlanSettings`) and hydra's YAML on top.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from nbv.geometry.camera import Intrinsics
from nbv.geometry.fusion import FusionSettings
from nbv.geometry.scores import DEFAULT_EPS, DEFAULT_POINTS_PER_VIEW
from nbv.geometry.viewspace_generators import ViewspaceSpec
from nbv.infogain.settings import InfoGainSettings
from nbv.policies.episode import EPISODE_VIEWS
from nbv.policies.registry import IG, METHODS
from nbv.scan.candidates import CandidateSettings
from nbv.scan.object_estimate import EstimateSettings
from nbv.setcover.settings import SetCoverSettings
from nbv.utils.fields import ConfigError, at_least, check_ranges, positive, setting

#: The methods a user may plan with: those that do not read the ground truth.
PLANNABLE = tuple(name for name, m in METHODS.items() if not m.ground_truth)
_DISTANCE = "null or a positive distance"


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
    the table, walls and stray points: :mod:`nbv.scan.object_estimate`, with ``estimate``).
    A sphere region of interest is ``center`` and ``radius``.

    Attributes:
        center: ``[x, y, z]``, or null.
        radius: a positive distance, or null.
        box_min: ``[x, y, z]``, with ``box_max``: a box region of interest (clutter such as a
            shelf bin's contents), or null.
        box_max: the box's other corner.
        estimate: how the object is found without them
            (:class:`~nbv.scan.object_estimate.EstimateSettings`).
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
class ScanSettings:
    """What a scan's decisions need (the keys of ``conf/plan.yaml`` that are not the command's
    inputs and outputs).

    Attributes:
        method: a registered method that does not read the ground truth (:data:`PLANNABLE`).
        checkpoint: the weights of the network the method runs (its own, or for a planner led by
            a network such as ``vig_hull_sco`` the leading one's); null: the weights the package
            ships (the command's default is ``paths.checkpoints.<network>`` when that file
            exists).
        viewspace: the candidate views (:class:`ViewspaceSettings`).
        object: the object's sphere or region of interest (:class:`ObjectSettings`).
        candidates: where the robot's camera may go; the candidates it cannot reach are dropped
            and counted (:class:`~nbv.scan.candidates.CandidateSettings`; captured views).
        n_views: views of an episode or a plan, the captured ones included (>= 2;
            ``protocol.n_views``).
        camera: the planner's (and the mesh simulation's) camera.
        match_degrees: a capture within this many degrees (seen from the object's centre) of a
            viewspace direction is that view; one farther off joins the plan as an extra
            visited view. In [0, 90).
        points_per_view: points kept of each view (a seeded random subset, as the dataset keeps
            them); 0 keeps all (``protocol.points_per_view``).
        eps: the convex-hull planners' capture distance, normalised units (the object fits in
            radius 0.5), and a mesh episode's coverage distance (``protocol.eps``).
        setcover: the convex-hull planners' settings (:class:`SetCoverSettings`).
        infogain: the information-gain planners' settings (:class:`InfoGainSettings`).
        reconstruction: the depth views fused into a mesh
            (:class:`~nbv.geometry.fusion.FusionSettings`).
        seed: every random draw (random views, hull samples, point subsets, a mesh's ground
            truth).
    """

    method: str = IG.name
    checkpoint: Path | None = None
    viewspace: ViewspaceSettings = setting(factory=ViewspaceSettings)
    object: ObjectSettings = setting(factory=ObjectSettings)
    candidates: CandidateSettings = setting(factory=CandidateSettings)
    n_views: int = setting(EPISODE_VIEWS, allows=at_least(2))
    camera: Intrinsics = setting(factory=Intrinsics)
    match_degrees: float = setting(2.0, check=lambda v: 0 <= v < 90, allowed="degrees in [0, 90)")
    points_per_view: int = setting(DEFAULT_POINTS_PER_VIEW, allows=at_least(0, note="0 = all"))
    eps: float = setting(DEFAULT_EPS, allows=positive("distance"))
    setcover: SetCoverSettings = setting(factory=SetCoverSettings)
    infogain: InfoGainSettings = setting(factory=InfoGainSettings)
    reconstruction: FusionSettings = setting(factory=FusionSettings)
    seed: int = 0

    def __post_init__(self) -> None:
        if self.method not in PLANNABLE:
            why = "reads the ground truth" if self.method in METHODS else "is not registered"
            raise ConfigError(f"method={self.method!r} {why}; allowed: {', '.join(PLANNABLE)}")
        check_ranges(self)
        self.viewspace.directions()  # reads a viewspace file: refused now, not mid-scan
