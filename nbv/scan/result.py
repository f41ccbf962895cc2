"""What a plan found (:class:`PlanResult`), whatever its input.

Both inputs become what the evaluator's policies read, :class:`~nbv.geometry.views.CapturedViews`
(the candidates' poses and the captured views' points), in the planners' normalised frame
(:mod:`nbv.scan.frame`):
the object's centre at the origin, its radius 0.5, the rig's up axis +y.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from nbv.geometry.camera import Intrinsics
from nbv.geometry.views import CapturedViews
from nbv.scan.frame import ObjectFrame

#: The viewspace's name in a mesh episode's record.
VIEWSPACE = "plan"


@dataclass
class Reconstruction:
    """The fused mesh and what it was made from.

    Attributes:
        vertices: (N, 3) float64 world points; triangles: (M, 3) int64.
        views: the fused views (view indices of the plan).
        voxel: the voxel edge used, world units.
        scores: mesh input: :func:`mesh_scores` against the mesh (world units); else None.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    views: list[int]
    voxel: float
    scores: dict[str, float] | None = None

    def record(self, file: str = "reconstruction.ply") -> dict:
        """``plan.json``'s ``reconstruction``."""
        return {
            "file": file if len(self.triangles) else None,
            "views": self.views,
            "voxel": self.voxel,
            "vertices": len(self.vertices),
            "triangles": len(self.triangles),
            "scores": self.scores,
        }


@dataclass
class PlanResult:
    """What one plan found, in the planners' normalised frame unless said otherwise.

    Attributes:
        frame: the object's frame (world <-> normalised).
        views: the views the policy read (candidates first, then extra captured views).
        n_candidates: V, the viewspace's views (indices ``0..V-1``).
        visited: the captured views in order (candidate indices; extras ``>= V``).
        chosen: the planned views in order (candidate indices).
        gains: the planner's predicted gain of each chosen view (None when it predicts none),
            and ``gain_unit`` what it counts.
        coverage: mesh input: coverage of the ground truth after each view of the episode.
        decisions: seconds of each policy call; ``stages`` the policy's own timings.
        captured_files: captures input: each capture's file and its view index.
        notes: what the policy or the input had to work around.
        frame_estimated: the object's centre and radius were estimated from the captures.
        camera: the planner's camera (its view simulation, ``ig``'s rays).
        object_source: captures input: where the object's sphere came from: ``object
            settings``, ``region of interest`` (``object.box_*``), ``views.json``, or
            ``estimated``.
        estimate: captures input: the object estimate
            (:meth:`nbv.scan.object_estimate.ObjectEstimate.record`), when one ran.
        candidate_limits: captures input: the candidates dropped
            (:func:`nbv.scan.candidates.limit_candidates`): ``dropped`` (how many),
            ``by_reason``, ``dropped_views`` and ``kept_views`` (viewspace indices; the plan's
            candidate ``i`` is viewspace view ``kept_views[i]``), ``support`` (the plane used, or
            None); None when nothing limits them.
        reconstruction: the views fused into a mesh (:mod:`nbv.scan.reconstruction`), when the
            command made one.
    """

    frame: ObjectFrame
    views: CapturedViews
    n_candidates: int
    visited: list[int]
    chosen: list[int]
    gains: list[float] | None = None
    gain_unit: str = ""
    coverage: list[float] | None = None
    decisions: list[float] = field(default_factory=list)
    stages: dict[str, float] = field(default_factory=dict)
    captured_files: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    frame_estimated: bool = False
    camera: Intrinsics | None = None
    object_source: str = ""
    estimate: dict | None = None
    candidate_limits: dict | None = None
    reconstruction: Reconstruction | None = None

    @property
    def cloud(self) -> np.ndarray:
        """(N, 3) float32 accumulated cloud of the visited views, normalised frame."""
        return np.concatenate([self.views.view_points(v) for v in self.visited])
