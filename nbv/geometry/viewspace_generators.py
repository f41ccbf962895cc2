"""Viewspaces for real rigs: generated directions, an up axis, and one spec that names them all.

A generated viewspace is a ``(V, 3)`` float64 array of unit directions from the object's centre
to the cameras (multiply by a radius for positions). They are made in the project's Y-up frame
and turned so that +y goes to the rig's ``up`` axis (:func:`up_rotation`):

* :func:`fibonacci_sphere`: ``n`` directions of a Fibonacci lattice over the whole sphere, or
  over the upper hemisphere (elevation >= 0, the half a turntable camera can reach); point ``i``
  sits at height ``1 - (2 i + 1) / n`` (sphere) or ``1 - (i + 0.5) / n`` (hemisphere), azimuth
  ``i`` times the golden angle from +z towards +x.
* :func:`rings`: rings of ``per_ring`` views at given elevations (degrees), azimuth from +z
  towards +x; a ring at +-90 degrees is one view (a pole). ``rings([90, 60, 30, 0, -30], 8)`` is
  PC-NBV's original viewspace, row for row.

:class:`ViewspaceSpec` is what a config gives (``kind`` and the values the kind reads); it
refuses a bad spec with one :class:`nbv.geometry.viewspace.ViewspaceError` naming the key, and
:meth:`ViewspaceSpec.directions` makes the directions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv.geometry.viewspace import (
    ViewspaceError,
    angular_distances,
    fibonacci_directions,
    get_viewspace,
)

#: What ``kind`` a spec may name (``file``: a text file of ``x y z`` rows).
KINDS = ("original", "permuted", "file", "sphere", "hemisphere", "rings")
#: Up axes by name.
UP_AXES = {
    "x": (1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "-x": (-1.0, 0.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "-z": (0.0, 0.0, -1.0),
}


def up_rotation(up: str | tuple[float, float, float] | np.ndarray) -> np.ndarray:
    """The rotation that takes the project's +y to ``up``: (3, 3) float64, det +1.

    The smallest such rotation (about ``y x up``); for ``up = -y`` a half turn about +x. So
    ``y`` gives the identity and ``z`` maps (x, y, z) to (x, -z, y): +z (azimuth 0) goes to -y.

    Args:
        up: an axis name of :data:`UP_AXES` or a non-zero 3-vector.

    Raises:
        ViewspaceError: an unknown name or a zero, non-finite or malformed vector.
    """
    if isinstance(up, str):
        if up not in UP_AXES:
            raise ViewspaceError(f"viewspace.up={up!r}: must be one of {', '.join(UP_AXES)}")
        up = UP_AXES[up]
    u = np.asarray(up, dtype=np.float64)
    if u.shape != (3,) or not np.all(np.isfinite(u)) or not np.linalg.norm(u) > 0:
        raise ViewspaceError(f"viewspace.up={np.asarray(up).tolist()}: must be a non-zero 3-vector")
    u = u / np.linalg.norm(u)
    y = np.array([0.0, 1.0, 0.0])
    axis = np.cross(y, u)
    s, c = np.linalg.norm(axis), float(y @ u)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * cross + (1.0 - c) * cross @ cross


def fibonacci_sphere(n: int, hemisphere: bool = False, up: str | np.ndarray = "y") -> np.ndarray:
    """``n`` directions of a Fibonacci lattice (:func:`fibonacci_directions`), turned to ``up``.

    Args:
        n: number of directions, >= 1.
        hemisphere: only the half above the equator (elevation in (0, 90) degrees).
        up: the rig's up axis (:func:`up_rotation`).

    Returns:
        (n, 3) float64 unit vectors.
    """
    return fibonacci_directions(n, hemisphere) @ up_rotation(up).T


def rings(
    elevations: list[float] | tuple[float, ...],
    per_ring: int | list[int] | tuple[int, ...],
    up: str | np.ndarray = "y",
    azimuth_offset: float = 0.0,
) -> np.ndarray:
    """Rings of views at the given elevations, ring after ring, azimuth from +z towards +x.

    Args:
        elevations: degrees in [-90, 90], distinct; +-90 is a single view (a pole).
        per_ring: views per ring, one count for all or one per elevation (a pole's is ignored).
        up: the rig's up axis (:func:`up_rotation`).
        azimuth_offset: degrees added to every azimuth.

    Returns:
        (V, 3) float64 unit vectors.
    """
    elevations = [float(e) for e in elevations]
    if not elevations:
        raise ViewspaceError("viewspace.elevations is empty; give at least one elevation")
    bad = [e for e in elevations if not -90.0 <= e <= 90.0]
    if bad:
        raise ViewspaceError(f"viewspace.elevations={bad}: must be degrees in [-90, 90]")
    if len(set(elevations)) != len(elevations):
        raise ViewspaceError(f"viewspace.elevations={elevations}: an elevation is given twice")
    counts = [per_ring] * len(elevations) if isinstance(per_ring, int) else list(per_ring)
    if len(counts) != len(elevations):
        raise ViewspaceError(
            f"viewspace.per_ring={counts}: give one count, or one per elevation ({len(elevations)})"
        )
    if any(int(c) != c or c < 1 for c in counts):
        raise ViewspaceError(f"viewspace.per_ring={counts}: counts must be integers >= 1")
    rows = []
    for e, count in zip(elevations, counts, strict=True):
        a = np.deg2rad(e)
        if abs(e) == 90.0:
            rows.append([0.0, np.sign(e), 0.0])
            continue
        for b in np.deg2rad(azimuth_offset + 360.0 * np.arange(int(count)) / count):
            rows.append([np.cos(a) * np.sin(b), np.sin(a), np.cos(a) * np.cos(b)])
    return np.array(rows, dtype=np.float64) @ up_rotation(up).T


@dataclass(frozen=True)
class ViewspaceSpec:
    """A viewspace as a config names it (``viewspace:`` of ``conf/plan.yaml``).

    Attributes:
        kind: one of :data:`KINDS`.
        file: the text file of ``kind=file`` (rows ``x y z``, directions in the Y-up frame).
        n: views of ``sphere`` and ``hemisphere``.
        elevations: degrees of the rings of ``rings``.
        per_ring: views per ring of ``rings`` (one count, or one per elevation).
        up: the rig's up axis: the Y-up frame's +y goes there (every kind is turned).
    """

    kind: str = "original"
    file: str | None = None
    n: int = 33
    elevations: tuple[float, ...] = (60.0, 30.0, 0.0, -30.0)
    per_ring: int | tuple[int, ...] = 8
    up: str = "y"

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ViewspaceError(f"viewspace.kind={self.kind!r}: must be one of {', '.join(KINDS)}")
        if self.kind == "file" and not self.file:
            raise ViewspaceError(
                "viewspace.kind=file needs viewspace.file=<text file of x y z rows>"
            )
        up_rotation(self.up)
        if self.kind in ("sphere", "hemisphere") and (int(self.n) != self.n or self.n < 2):
            raise ViewspaceError(f"viewspace.n={self.n!r}: must be an integer >= 2")
        if self.kind == "rings":
            self._make()  # the generator refuses bad elevations or counts, naming the key

    def _make(self) -> np.ndarray:
        if self.kind in ("original", "permuted"):
            # Unit vectors already; kept bit for bit (the dataset's poses are made from them).
            return get_viewspace(self.kind) @ up_rotation(self.up).T
        if self.kind == "file":
            base = get_viewspace(self.file)
            base = base / np.linalg.norm(base, axis=1, keepdims=True)
            return base @ up_rotation(self.up).T
        if self.kind == "rings":
            per_ring = self.per_ring if isinstance(self.per_ring, int) else list(self.per_ring)
            return rings(list(self.elevations), per_ring, self.up)
        return fibonacci_sphere(self.n, self.kind == "hemisphere", self.up)

    def directions(self) -> np.ndarray:
        """The viewspace's (V, 3) float64 unit directions, in the rig's frame (``up`` applied).

        Raises:
            ViewspaceError: a file that cannot be read, or two views in one direction.
        """
        dirs = self._make()
        if len(dirs) > 1:
            gaps = angular_distances(dirs, dirs) + np.diag(np.full(len(dirs), np.inf))
            if gaps.min() < 1e-6:
                i, j = np.unravel_index(np.argmin(gaps), gaps.shape)
                raise ViewspaceError(
                    f"viewspace ({self.kind}): views {min(i, j)} and {max(i, j)} point the same "
                    "way; every view needs its own direction"
                )
        return dirs
