"""The settings of ``python -m nbv.plan``: :class:`PlanSettings`, the one declaration of
``conf/plan.yaml``'s keys (the hydra schema ``plan_schema`` is derived from it by
:mod:`nbv.config.settings`).

Every key is checked before any work: its range (field metadata), then what spans keys (exactly
one input, a method that does not read the ground truth, a start view of the viewspace, the
saved captures). The object's sphere against the cameras' distance is checked where the sphere is
known (:func:`nbv.scan.frame.object_frame`): it may come from the input.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nbv.config.schema import CameraConfig, ConfigError, PathsConfig, ProtocolConfig, check_views
from nbv.config.settings import Entry, setting
from nbv.geometry.camera import Intrinsics
from nbv.geometry.scores import DEFAULT_N_GT
from nbv.policies.registry import networks_of
from nbv.scan.settings import ScanSettings
from nbv.utils.fields import at_least

INPUTS = ("give exactly one input: mesh=<mesh file> (simulated captures) or "
          "captures=<folder with views.json>")  # fmt: skip


@dataclass(frozen=True)
class PlanSettings(ScanSettings):
    """Everything one plan needs (``conf/plan.yaml``): the scan's settings
    (:class:`~nbv.scan.settings.ScanSettings`) and the command's inputs and outputs.

    Attributes:
        mesh: the input, a mesh file (obj, ply, off, stl, glb, gltf; its units are the world's)
            to simulate captures of: a whole episode. Exclusive with ``captures``.
        captures: the input, a capture folder (``views.json`` and one file a view; the format is
            in :mod:`nbv.scan.captures`): the next view, or a one-shot planner's whole plan.
        views: captures input: the views of the folder to plan from, by their index in
            ``views.json`` (e.g. ``[0, 7, 14]``), in that order; null takes them all.
        checkpoint: the weights of the network the method runs (its own, or for a planner led by
            a network such as ``vig_hull_sco`` the leading one's); null =
            ``paths.checkpoints.<network>``, and when that file does not exist the weights the
            package ships.
        camera: the planner's (and the mesh simulation's) camera, ``conf/camera/``.
        start_view: mesh input: the episode's first view (an index of the viewspace).
        n_gt: mesh input: ground-truth points the coverage by view is measured on
            (``protocol.n_gt``).
        save_captures: mesh input: write the episode's first this many views as a capture
            folder (depth NPY and ``views.json``); 0 writes none.
        captures_out: where; null = ``<out_dir>/captures``. It must be new or empty.
        reconstruction: the depth views fused into ``reconstruction.ply``
            (:class:`~nbv.geometry.fusion.FusionSettings`).
        picture: draw ``plan.png`` (matplotlib).
        page: write ``plan.html`` (plotly, self-contained).
        out_dir: the run folder: ``plan.json``, ``plan.png``, ``plan.html``, ``cloud.ply`` (and
            ``captures/`` with ``save_captures``), hydra's ``.hydra/`` and ``plan.log``.
    """

    camera: Intrinsics = setting(
        factory=Intrinsics, config=CameraConfig, convert=Intrinsics.from_config
    )
    mesh: Path | None = None
    captures: Path | None = None
    views: tuple[int, ...] | None = setting(
        None, check=lambda v: v is None or (len(v) > 0 and all(i >= 0 for i in v)
                                            and len(set(v)) == len(v)),
        allowed="null or a non-empty list of distinct view indices >= 0",
    )  # fmt: skip
    start_view: int = setting(0, allows=at_least(0))
    n_gt: int = setting(DEFAULT_N_GT, allows=at_least(1))
    save_captures: int = setting(0, allows=at_least(0))
    captures_out: Path | None = None
    picture: bool = True
    page: bool = True
    out_dir: Path = field(kw_only=True)

    def __post_init__(self) -> None:
        # Exactly one input is the command's rule (PlanEntry.build): a Planner takes neither.
        if self.mesh is not None and self.captures is not None:
            raise ConfigError(INPUTS)
        super().__post_init__()
        n_candidates = len(self.viewspace.directions())
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
