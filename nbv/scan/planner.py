"""A planner that stays warm in a robot's loop: ``from nbv.scan import Planner``.

``python -m nbv.plan captures=...`` reads a folder, decides once and exits. A robot decides again
after every view, so :class:`Planner` keeps what does not change between decisions:

* the settings, checked once (:class:`~nbv.scan.settings.ScanSettings`, or keyword overrides of
  it: the command's keys, without hydra);
* the object's frame, placed at the first decision (the ``object`` settings, a region of
  interest, else estimated from the views added so far) and kept after it: the candidates do
  not move under the robot mid-scan, and the map is never rebuilt;
* the candidate poses and their limits, the policy of the method with its network or scorer,
  and the compiled code;
* ``ig``'s and ``ig_learned``'s occupancy map, which takes only the new view's rays at each
  decision (:meth:`nbv.policies.infogain.InfoGainPolicy.update`), and the candidates'
  rays, traced once.

Each view is read as a capture file would be (:func:`nbv.scan.capture.depth_capture`,
:func:`~nbv.scan.capture.cloud_capture`) and matched to a candidate; ``python -m nbv.plan
captures=...`` loads a folder with :meth:`Planner.load` and decides once, so the planner's choices
are the command's on the same views. :meth:`Planner.save` writes a capture folder (``views.json``,
one file a view) with ``planner.json`` beside it (the settings, the frame and the support found),
and :meth:`Planner.load` resumes from it: the same next view as before the crash for the methods
that draw nothing at random (every method but ``random``).
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from nbv.geometry.camera import Intrinsics, opencv_to_blender
from nbv.scan.capture import (
    AXES,
    NO_RETURN,
    Capture,
    CaptureError,
    check_rigid,
    check_views_see,
    cloud_capture,
    depth_capture,
)
from nbv.scan.captures import read_captures, select_views, write_views
from nbv.scan.decision import Decider
from nbv.scan.frame import ObjectFrame
from nbv.scan.result import PlanResult
from nbv.scan.settings import ScanSettings
from nbv.utils.settings_values import plain, replaced

log = logging.getLogger(__name__)

#: The planner's own file in a saved folder, beside ``views.json``.
STATE = "planner.json"
#: Keys of ``python -m nbv.plan``'s own settings that ``planner.json`` files saved before
#: 2026-12-07 hold beside the scan's: its inputs and outputs, nothing a decision reads.
_COMMAND_KEYS = ("mesh", "captures", "views", "start_view", "n_gt", "save_captures",
                 "captures_out", "picture", "page", "out_dir")  # fmt: skip


@dataclass(frozen=True)
class NextView:
    """A planned view, in the world frame and units of the views.

    Attributes:
        index: the plan's candidate index (``plan.json``'s ``chosen``).
        view: its viewspace index (differs from ``index`` when ``candidates.*`` dropped views).
        opencv: (4, 4) camera-to-world, OpenCV axes (x right, y down, z forward).
        blender: (4, 4) the same camera in Blender / OpenGL axes (x right, y up, -z forward).
        position: (3,) the camera centre.
        gain: the planner's predicted gain of the view (``gain_unit``), None when it predicts
            none.
        gain_unit: what ``gain`` counts.
    """

    index: int
    view: int
    opencv: np.ndarray
    blender: np.ndarray
    position: np.ndarray
    gain: float | None
    gain_unit: str


def scan_settings(settings: ScanSettings | None, overrides: Mapping[str, Any]) -> ScanSettings:
    """``settings`` (a :class:`ScanSettings`, or a command's settings that extend it: only the
    scan's keys are kept) with keyword overrides of its keys, nested groups as dicts
    (``viewspace={"kind": "sphere", "n": 60}``; ``camera`` an :class:`Intrinsics`), checked as
    the command checks its keys.

    Raises:
        ConfigError: an unknown key or a bad value, named.
    """
    if settings is None:
        settings = ScanSettings()
    elif type(settings) is not ScanSettings:
        settings = ScanSettings(**{f.name: getattr(settings, f.name) for f in fields(ScanSettings)})
    return replaced(settings, overrides) if overrides else settings


class Planner:
    """Next views from views added one by one (module docstring).

    Args:
        settings: the scan's settings (:class:`~nbv.scan.settings.ScanSettings`, or the
            command's :class:`~nbv.plan.config.PlanSettings`, whose scan keys are taken); None:
            the defaults.
        **overrides: settings by key, over ``settings``: ``method="ig_learned"``,
            ``viewspace={"kind": "hemisphere", "n": 40, "up": "z", "radius": 0.45}``,
            ``object={"center": [0, 0, 0.1], "radius": 0.1}``, ``candidates={...}``.

    Raises:
        ConfigError: a bad setting, named.
    """

    def __init__(self, settings: ScanSettings | None = None, /, **overrides) -> None:
        self.settings = scan_settings(settings, overrides)
        #: What the views are called in messages: their folder once loaded.
        self.where = "the views"
        self.captures: list[Capture] = []
        self._decider: Decider | None = None
        self._restored: dict | None = None  # planner.json's frame and support
        self._given: dict | None = None  # views.json's object
        self.result: PlanResult | None = None

    # --- views ---------------------------------------------------------------------------

    def add_view(
        self,
        depth_or_points: np.ndarray,
        pose: np.ndarray,
        intrinsics: Intrinsics | None = None,
        axes: str = "opencv",
        no_return: str = "unknown",
        max_range: float | None = None,
    ) -> int:
        """Add a captured view; returns its index (the order of :meth:`save`'s files).

        Args:
            depth_or_points: a depth image (H, W) of planar depth, world units (0, NaN or inf
                where nothing was measured), with ``intrinsics``; or (N, 3) world points
                without them.
            pose: (4, 4) camera-to-world of the view, world units.
            intrinsics: the depth image's camera.
            axes: the pose's camera axes: ``opencv`` (z forward, y down) or ``blender``.
            no_return: what a pixel without a measurement means: ``unknown`` (a sensor's) or
                ``free`` (a rendered view's background; :mod:`nbv.scan.captures`).
            max_range: the sensor's range (planar depth, world units), or None.

        Raises:
            CaptureError: bad input, one line naming the view and what is wrong.
        """
        where = Path(f"add_view #{len(self.captures)}")
        if axes not in AXES:
            raise CaptureError(f"{where}: axes={axes!r}; allowed: {', '.join(AXES)}")
        if no_return not in NO_RETURN:
            raise CaptureError(f"{where}: no_return={no_return!r}; allowed: {', '.join(NO_RETURN)}")
        if max_range is not None and not max_range > 0:
            raise CaptureError(f"{where}: max_range={max_range!r}; must be a positive distance")
        pose = check_rigid(pose, str(where))
        if axes == "blender":
            pose = opencv_to_blender(pose)
        data = np.asarray(depth_or_points)
        if not (np.issubdtype(data.dtype, np.floating) or np.issubdtype(data.dtype, np.integer)):
            raise CaptureError(f"{where}: an array of numbers, got dtype {data.dtype}")
        if intrinsics is not None:
            if not isinstance(intrinsics, Intrinsics):
                raise CaptureError(f"{where}: intrinsics must be an nbv.geometry.camera.Intrinsics")
            if data.ndim != 2 or not np.issubdtype(data.dtype, np.floating):
                raise CaptureError(
                    f"{where}: with intrinsics, a float depth image (H, W) in world units; got "
                    f"shape {data.shape}, dtype {data.dtype}"
                )
            capture = depth_capture(data.astype(np.float64), intrinsics, pose, where, no_return,
                                    max_range)  # fmt: skip
        else:
            if data.ndim != 2 or data.shape[1] != 3 or len(data) == 0:
                raise CaptureError(
                    f"{where}: without intrinsics, points (N, 3) with N >= 1; got shape "
                    f"{data.shape} (a depth image needs its intrinsics)"
                )
            points = data.astype(np.float64)
            if not np.isfinite(points).all():
                raise CaptureError(f"{where}: NaN or infinite points")
            capture = cloud_capture(points, pose, where, no_return, max_range)
        if self._decider is not None:
            check_views_see([capture], self._decider.frame.center, self._decider.frame.radius,
                            self.settings.camera)  # fmt: skip
            self._decider.add(capture)
        self.captures.append(capture)
        return len(self.captures) - 1

    # --- decisions -----------------------------------------------------------------------

    def _ready(self) -> Decider:
        """The decider, built at the first decision (the frame placed, the policy built)."""
        if not self.captures:
            raise CaptureError("Planner: no views yet; add_view first")
        if self._decider is None:
            self._decider = Decider(self.settings, self.captures, self._given, self._restored,
                                   self.where)  # fmt: skip
        return self._decider

    def decide(self) -> PlanResult:
        """The policy's decision on the views so far: the command's :class:`PlanResult`."""
        self.result = self._ready().decide()
        return self.result

    def next_view(self) -> NextView:
        """The next view to take (a one-shot planner's first of its plan)."""
        return self._views(self.decide())[0]

    def plan(self) -> list[NextView]:
        """The method's whole plan from the views so far: a one-shot planner's (``hull_sco``)
        remaining views in order; one view for the methods that decide one at a time."""
        return self._views(self.decide())

    def _views(self, result: PlanResult) -> list[NextView]:
        world = result.frame.poses_to_world(result.views.poses)
        kept = (result.candidate_limits or {}).get("kept_views")
        out = []
        for k, v in enumerate(result.chosen):
            gain = None if result.gains is None else result.gains[k]
            out.append(NextView(v, int(kept[v]) if kept else v, world[v],
                                opencv_to_blender(world[v]), world[v][:3, 3].copy(), gain,
                                result.gain_unit))  # fmt: skip
        return out

    @property
    def frame(self) -> ObjectFrame | None:
        """The object's frame (None before the first decision)."""
        return None if self._decider is None else self._decider.frame

    # --- the reconstruction ----------------------------------------------------------------

    def reconstruct(self):
        """The depth views fused into a mesh (:func:`nbv.scan.reconstruction.reconstruct_captures`;
        None when every view is a point cloud)."""
        from nbv.scan.reconstruction import reconstruct_captures

        return reconstruct_captures(self.settings, self.captures, self._ready().frame)

    # --- saved and resumed ---------------------------------------------------------------

    def save(self, folder: str | os.PathLike) -> Path:
        """Write the views as a capture folder with ``planner.json`` (replacing a folder saved
        before, whole or not at all); :meth:`load` resumes from it. Returns the folder."""
        # The camera is saved whole (all its parameters), beside the other keys.
        values = plain(self.settings)
        values.pop("camera")
        state: dict = {"settings": values, "camera": self.settings.camera.as_dict()}
        if self._decider is not None:
            state |= self._decider.placement()
        elif self._restored is not None:
            state |= self._restored
        folder = Path(folder)
        write_views(folder, self.captures, extra={STATE: json.dumps(state, indent=1)},
                    replace=True)  # fmt: skip
        return folder

    @classmethod
    def load(
        cls,
        folder: str | os.PathLike,
        settings: ScanSettings | None = None,
        views: Sequence[int] | None = None,
        **overrides,
    ) -> Planner:
        """A planner on the views of a capture folder: one :meth:`save` wrote (its settings,
        frame and support restored; ``overrides`` apply over them), or any other (``settings``
        and ``overrides``, as ``python -m nbv.plan captures=folder``).

        Args:
            folder: the capture folder (``views.json`` and one file a view).
            settings: the scan's settings; None: ``planner.json``'s when the folder has one,
                else the defaults.
            views: the folder's views to plan from, by their index in ``views.json``, in that
                order; None takes them all.
            **overrides: settings by key, as for :class:`Planner`.

        Raises:
            CaptureError: the folder or ``planner.json`` cannot be used, named.
        """
        folder = Path(folder)
        state_file = folder / STATE
        restored = None
        if state_file.is_file() and settings is None:
            try:
                state = json.loads(state_file.read_text())
                values = {k: v for k, v in state["settings"].items() if k not in _COMMAND_KEYS}
                camera = Intrinsics(**state["camera"])
            except (OSError, ValueError, KeyError, TypeError) as err:
                raise CaptureError(
                    f"{state_file}: cannot read the planner's state ({err})"
                ) from err
            values.pop("camera", None)
            try:
                saved = replaced(ScanSettings(), values)
            except ValueError as err:
                raise CaptureError(f"{state_file}: settings: {err}") from None
            planner = cls(saved, camera=camera, **overrides)
            restored = {k: state[k] for k in ("frame", "support", "source") if k in state}
        else:
            planner = cls(settings, **overrides)
        planner.where = str(folder)
        captures, given = read_captures(folder)
        if views is not None:
            captures = select_views(captures, views, folder)
        planner.captures = captures
        planner._given = given
        planner._restored = restored or None
        return planner
