"""Candidate views a robot can use: the viewspace's cameras less those it cannot reach.

A camera position (world units) is dropped, and counted by the first reason that holds:

* ``support``: below the support's plane, or closer to it than ``clearance`` (inside the table);
* ``elevation``: seen from the object's centre, less than ``min_elevation`` degrees above the
  support's plane;
* ``wall``: behind a declared wall (a plane; its normal points to the allowed side), or closer
  to it than ``clearance``;
* ``cone``: more than ``cone_degrees`` off ``cone_axis`` seen from the object's centre;
* ``box``: outside the box ``box_min`` .. ``box_max`` of allowed camera positions.

The support is the declared ``support`` plane, else the one the object estimate found
(:mod:`nbv.scan.object_estimate`); the elevation and support limits need one of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv.scan.object_estimate import Plane
from nbv.utils.fields import ConfigError, at_least, between, check_ranges, setting

#: The reasons a candidate is dropped, in the order they are tried.
REASONS = ("support", "elevation", "wall", "cone", "box")


def _plane_ok(p) -> bool:
    return p is None or (len(p) == 4 and float(np.linalg.norm(p[:3])) > 0)


def _point_ok(p) -> bool:
    return p is None or len(p) == 3


@dataclass(frozen=True)
class CandidateSettings:
    """``candidates:``, where the robot's camera may go (world frame and units).

    Attributes:
        min_elevation: degrees; a candidate seen from the object's centre lower than this above
            the support's plane is dropped (null: no limit; 0 drops those below the plane's
            level).
        support: the support's plane ``[a, b, c, d]`` (``a x + b y + c z + d = 0``; ``(a, b, c)``
            toward the object), null: the plane the object estimate finds (a camera inside or
            under it is always dropped).
        walls: planes ``[a, b, c, d]`` the camera must stay in front of (``(a, b, c)`` toward the
            allowed side).
        clearance: the least distance a camera keeps from the support and the walls.
        cone_axis: ``[x, y, z]``, with ``cone_degrees``: the cone of allowed directions from
            the object's centre (null: no cone).
        cone_degrees: the cone's half angle, degrees.
        box_min: ``[x, y, z]``, with ``box_max``: the box of allowed camera positions (null: no
            box).
        box_max: the box's other corner.
    """

    min_elevation: float | None = setting(
        None, check=lambda v: v is None or -90 <= v < 90, allowed="null or degrees in [-90, 90)"
    )
    support: tuple[float, float, float, float] | None = setting(
        None, check=_plane_ok, allowed="null or [a, b, c, d] with (a, b, c) not zero"
    )
    walls: tuple[tuple[float, float, float, float], ...] = setting(
        (), check=lambda w: all(_plane_ok(p) and p is not None for p in w),
        allowed="a list of planes [a, b, c, d] with (a, b, c) not zero",
    )  # fmt: skip
    clearance: float = setting(0.0, allows=at_least(0, "a distance"))
    cone_axis: tuple[float, float, float] | None = setting(
        None, check=lambda p: p is None or (len(p) == 3 and float(np.linalg.norm(p)) > 0),
        allowed="null or a non-zero [x, y, z]",
    )  # fmt: skip
    cone_degrees: float = setting(90.0, allows=between(0, 180, "(]"))
    box_min: tuple[float, float, float] | None = setting(
        None, check=_point_ok, allowed="null or [x, y, z]"
    )
    box_max: tuple[float, float, float] | None = setting(
        None, check=_point_ok, allowed="null or [x, y, z]"
    )

    def __post_init__(self) -> None:
        check_ranges(self)
        if (self.box_min is None) != (self.box_max is None):
            raise ConfigError("candidates.box_min and candidates.box_max: give both or neither")
        if self.box_min is not None and not np.all(np.less(self.box_min, self.box_max)):
            raise ConfigError(
                f"candidates.box_min={list(self.box_min)} must be below box_max="
                f"{list(self.box_max)} on every axis"
            )

    @property
    def needs_support(self) -> bool:
        """Whether a limit reads the support's plane."""
        return self.min_elevation is not None

    @property
    def active(self) -> bool:
        """Whether any limit is set (a support found by the estimate drops cameras inside it
        even when none is)."""
        return (self.min_elevation is not None or self.support is not None or bool(self.walls)
                or self.cone_axis is not None or self.box_min is not None)  # fmt: skip


def declared_plane(values: tuple[float, float, float, float]) -> Plane:
    """A plane of the settings as a :class:`Plane` with a unit normal."""
    v = np.asarray(values, dtype=np.float64)
    scale = float(np.linalg.norm(v[:3]))
    return Plane(v[:3] / scale, float(v[3] / scale), 0)


def limit_candidates(
    positions: np.ndarray,
    center: np.ndarray,
    settings: CandidateSettings,
    support: Plane | None,
) -> tuple[np.ndarray, dict[str, int]]:
    """Which candidates a robot can use (module docstring).

    Args:
        positions: (V, 3) candidate camera centres, world units.
        center: (3,) the object's centre, world units.
        settings: the limits.
        support: the support's plane (declared or estimated), or None.

    Returns:
        ``(keep, dropped)``: (V,) bool, and the count dropped by each reason of :data:`REASONS`.

    Raises:
        ValueError: a limit needs the support and there is none (naming the setting to give).
    """
    positions = np.asarray(positions, dtype=np.float64)
    center = np.asarray(center, dtype=np.float64)
    if settings.needs_support and support is None:
        raise ValueError(
            "candidates.min_elevation needs the support's plane: give candidates.support = "
            "[a, b, c, d], or captures in which the object estimate finds it"
        )
    rays = positions - center
    unit = rays / np.maximum(np.linalg.norm(rays, axis=1, keepdims=True), 1e-300)
    tests: dict[str, np.ndarray] = {}
    if support is not None:
        tests["support"] = support.distance(positions) >= max(settings.clearance, 0.0) + 1e-12
        if settings.min_elevation is not None:
            elevation = np.degrees(np.arcsin(np.clip(unit @ support.normal, -1.0, 1.0)))
            tests["elevation"] = elevation >= settings.min_elevation
    if settings.walls:
        ok = np.ones(len(positions), dtype=bool)
        for wall in settings.walls:
            ok &= declared_plane(wall).distance(positions) >= max(settings.clearance, 1e-12)
        tests["wall"] = ok
    if settings.cone_axis is not None:
        axis = np.asarray(settings.cone_axis, dtype=np.float64)
        axis = axis / np.linalg.norm(axis)
        angle = np.degrees(np.arccos(np.clip(unit @ axis, -1.0, 1.0)))
        tests["cone"] = angle <= settings.cone_degrees
    if settings.box_min is not None:
        lo, hi = np.asarray(settings.box_min), np.asarray(settings.box_max)
        tests["box"] = np.all((positions >= lo) & (positions <= hi), axis=1)
    keep = np.ones(len(positions), dtype=bool)
    dropped = dict.fromkeys(REASONS, 0)
    for reason in REASONS:
        if reason in tests:
            dropped[reason] = int(np.sum(keep & ~tests[reason]))
            keep &= tests[reason]
    return keep, dropped
