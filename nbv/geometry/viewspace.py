"""Viewspaces: the candidate camera positions of next-best-view planning.

A viewspace is a ``(V, 3)`` float64 array of camera positions; every camera looks at the origin.

* :func:`original_viewspace` is PC-NBV's 33-view viewspace (radius 1, Y up): for elevation
  ``a`` in (-90, -60, -30, 0, 30) degrees and azimuth ``b`` in (0, 45, ..., 315) degrees, the third
  column of ``Ry(b) @ Rx(a)``; of these 40 rows the first seven repeat the pole and are dropped.
  Row 0 is the top pole, rows 1-8 the ring at elevation 60, 9-16 at 30, 17-24 the equator,
  25-32 at -30 degrees.
* :func:`permuted_viewspace` is a seeded set of other directions over the same elevation band
  (see its docstring); ``data/viewspaces/permuted_33.txt`` holds the one made with the default seed.
* :func:`fibonacci_directions` is a Fibonacci lattice of ``n`` directions over the sphere or the
  upper hemisphere; :func:`get_viewspace` names them ``sphere_<n>`` and ``hemisphere_<n>``
  (``hemisphere_30`` is GenNBV's uniform hemisphere of 30 views, ``sphere_32`` has SCVP's count).
* :func:`load_viewspace` reads any text file of ``V`` rows ``x y z``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from nbv.utils.atomic import atomic_path

#: The viewspace files that ship with the project.
DATA_DIR = Path(__file__).resolve().parents[2] / "data" / "viewspaces"
#: The seed of the shipped permuted viewspace.
PERMUTED_SEED = 2024
#: Elevation band of the original viewspace, degrees.
ELEVATION_BAND = (-30.0, 90.0)
#: The viewspaces that ship as files.
SHIPPED = ("original", "permuted")
#: A generated viewspace's name: ``sphere_<n>`` or ``hemisphere_<n>`` (n >= 2).
GENERATED_NAME = re.compile(r"(sphere|hemisphere)_([1-9][0-9]*)")
#: The golden angle, radians: successive lattice points turn by it.
GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def _rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def original_viewspace() -> np.ndarray:
    """PC-NBV's 33 camera positions on the unit sphere, in PC-NBV's order.

    Returns:
        (33, 3) float64.
    """
    rows = [
        (_rot_y(np.deg2rad(b)) @ _rot_x(np.deg2rad(a)))[:, 2]
        for a in (-90.0, -60.0, -30.0, 0.0, 30.0)
        for b in range(0, 360, 45)
    ]
    return np.array(rows[7:])


def elevation(viewspace: np.ndarray) -> np.ndarray:
    """Elevation above the XZ plane of each camera direction, in degrees: (V, 3) -> (V,)."""
    v = np.asarray(viewspace, dtype=np.float64)
    return np.rad2deg(np.arcsin(np.clip(v[:, 1] / np.linalg.norm(v, axis=1), -1.0, 1.0)))


#: Two open views tie for a spread pick when the cosines of their smallest angles to the closed
#: views differ by at most this much. Rounding puts about 1e-16 of noise in the cosines of a
#: symmetric viewspace (PC-NBV's rings): those must tie. Distinct cosines differ by far more: at
#: least 4e-6 over every start's first nine picks on the original and permuted viewspaces and on
#: Fibonacci spheres and hemispheres of 30 and 32 views. The lowest-index rule before this one
#: rounded the cosines to 12 decimals; it picks the same views as ``rng=None`` does on those.
TIE_TOLERANCE = 1e-12
#: Decimals of a degree :func:`angular_distances` keeps (1e-9 degrees: far above float64's
#: rounding error of an angle, far below any two views' difference that means something).
ANGLE_DECIMALS = 9


class SpreadPicks(NamedTuple):
    """What :func:`spread_picks` chose.

    Attributes:
        views: the picked view indices, in order.
        tied: for each pick, how many open views tied for it (1: no tie).
    """

    views: list[int]
    tied: list[int]

    @property
    def ties(self) -> int:
        """The picks made among two or more tied views."""
        return sum(1 for t in self.tied if t > 1)


def spread_picks(
    directions: np.ndarray,
    closed: np.ndarray,
    count: int,
    rng: np.random.Generator | None = None,
) -> SpreadPicks:
    """``count`` views, not ``closed``, each as far in angle as possible from those before.

    Each pick maximises its smallest angle (at the origin) to the closed views and the earlier
    picks (maximin). The open views whose cosine to their nearest closed view is within
    :data:`TIE_TOLERANCE` of the smallest such cosine are tied for the pick:

    * with ``rng``, the pick is uniform among them: one ``rng.integers(k)`` for ``k > 1`` tied
      views, nothing drawn when only one is best (the fair ``spread`` baseline);
    * with ``rng=None``, the lowest index among them (the named deterministic variant,
      *lowest-index spread*: on a viewspace of rings such as PC-NBV's it picks the first view
      of each ring, a systematic bias that a random tie-break averages out).

    With nothing closed, every open view ties for the first pick.

    Args:
        directions: ``(V, 3)`` unit vectors from the origin to the views.
        closed: ``(V,)`` bool, the views already visited or chosen; not modified.
        count: number of picks, at most the open views.
        rng: the generator of the tie-break; None for the lowest index.

    Returns:
        :class:`SpreadPicks`: the views and how many views tied for each.
    """
    closed = np.array(closed, dtype=bool)
    open_views = ~closed
    nearest = np.full(len(directions), -np.inf)  # cosine of the smallest angle to a closed view
    if closed.any():
        nearest = (directions @ directions[closed].T).max(axis=1)
    views: list[int] = []
    tied: list[int] = []
    for _ in range(count):
        candidates = np.flatnonzero(open_views)
        cosines = nearest[candidates]
        # With nothing closed every cosine is -inf, and -inf + tolerance is -inf: all tie.
        best = candidates[cosines <= cosines.min() + TIE_TOLERANCE]
        pick = int(best[0] if rng is None or len(best) == 1 else best[rng.integers(len(best))])
        views.append(pick)
        tied.append(len(best))
        open_views[pick] = False
        np.maximum(nearest, directions @ directions[pick], out=nearest)
    return SpreadPicks(views, tied)


def spread_views(
    directions: np.ndarray,
    closed: np.ndarray,
    count: int,
    rng: np.random.Generator | None = None,
) -> list[int]:
    """The views of :func:`spread_picks` (see there for ``rng`` and ties).

    This is the ``spread`` baseline (each next view farthest in angle from the visited ones, no
    geometry of the object) and the convex-hull planner's fill once its hull is covered.
    """
    return spread_picks(directions, closed, count, rng).views


def unit_directions(positions: np.ndarray, dtype: type = np.float64) -> np.ndarray:
    """(N, 3) unit directions, of ``dtype``, of the nonzero vectors ``positions`` (N, 3)
    (normalised in float64 whatever ``dtype``)."""
    positions = np.asarray(positions, dtype=np.float64)
    return (positions / np.linalg.norm(positions, axis=1, keepdims=True)).astype(dtype)


def angular_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles in degrees between every direction of ``a`` (N, 3) and of ``b`` (M, 3): (N, M).

    atan2 of the cross and dot products (exact near 0, where arccos of the dot product is off
    by up to 1e-6 degrees), rounded to :data:`ANGLE_DECIMALS`: pairs of views equally far apart
    in exact arithmetic (the rings of a symmetric viewspace) are equally far here, so a rule or
    a rank read off the angles ties them rather than ordering them by rounding error.
    """
    ua, ub = unit_directions(a), unit_directions(b)
    cross = np.linalg.norm(np.cross(ua[:, None, :], ub[None, :, :]), axis=-1)
    return np.round(np.rad2deg(np.arctan2(cross, ua @ ub.T)), ANGLE_DECIMALS)


def _band_directions(rng: np.random.Generator, n: int, band: tuple[float, float]) -> np.ndarray:
    """``n`` directions uniform in area over the elevation band (degrees): (n, 3)."""
    lo, hi = np.sin(np.deg2rad(band[0])), np.sin(np.deg2rad(band[1]))
    y = rng.uniform(lo, hi, n)
    azimuth = rng.uniform(0.0, 2.0 * np.pi, n)
    r = np.sqrt(1.0 - y**2)
    return np.stack([r * np.sin(azimuth), y, r * np.cos(azimuth)], axis=1)


def permuted_viewspace(
    seed: int = PERMUTED_SEED,
    n_views: int = 33,
    min_separation_deg: float = 5.0,
    candidates: int = 64,
    reference: np.ndarray | None = None,
) -> np.ndarray:
    """A viewspace whose positions and order differ from ``reference`` (default: the original).

    Procedure (Mitchell's best-candidate sampling, seeded): for each new view draw ``candidates``
    directions uniformly by area over the reference's elevation band (-30 to 90 degrees), discard
    those within ``min_separation_deg`` of any reference view, and keep the one farthest from the
    views chosen so far. This spreads the views evenly over the band while no view coincides
    with a reference view; the order is the order of drawing, unrelated to the reference's.

    Args:
        seed: seed of the ``numpy.random.Generator``.
        n_views: number of views.
        min_separation_deg: minimum angle between any new view and any reference view.
        candidates: candidates drawn per view (more gives a more even spread).
        reference: (V, 3) viewspace to avoid; default :func:`original_viewspace`.

    Returns:
        (n_views, 3) float64 unit vectors.
    """
    rng = np.random.default_rng(seed)
    reference = original_viewspace() if reference is None else np.asarray(reference, np.float64)
    chosen: list[np.ndarray] = []
    while len(chosen) < n_views:
        pool = _band_directions(rng, candidates, ELEVATION_BAND)
        pool = pool[angular_distances(pool, reference).min(axis=1) >= min_separation_deg]
        if len(pool) == 0:
            continue
        if chosen:
            best = int(np.argmax(angular_distances(pool, np.array(chosen)).min(axis=1)))
        else:
            best = 0
        chosen.append(pool[best])
    return np.array(chosen)


class ViewspaceError(ValueError):
    """A viewspace file that cannot be used; the message names the file and line."""


def load_viewspace(path: str | Path) -> np.ndarray:
    """Read a viewspace text file: one camera position ``x y z`` per line.

    Blank lines and lines starting with ``#`` are skipped.

    Args:
        path: the text file.

    Returns:
        (V, 3) float64 camera positions.

    Raises:
        ViewspaceError: for a missing or empty file, a line without exactly three numbers, a NaN
            or infinite value, a zero vector, or two identical directions; the message names the
            file and line.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise ViewspaceError(f"{path}: cannot read viewspace file ({err.strerror})") from err
    except UnicodeDecodeError as err:
        raise ViewspaceError(f"{path}: not a text file of 'x y z' lines ({err.reason})") from err
    rows: list[np.ndarray] = []
    lines: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        fields = stripped.replace(",", " ").split()
        if len(fields) != 3:
            raise ViewspaceError(
                f"{path}:{number}: expected 3 columns 'x y z', found {len(fields)}: {stripped!r}"
            )
        try:
            row = np.array([float(f) for f in fields])
        except ValueError as err:
            raise ViewspaceError(f"{path}:{number}: not a number: {stripped!r}") from err
        if not np.all(np.isfinite(row)):
            raise ViewspaceError(f"{path}:{number}: NaN or infinite value: {stripped!r}")
        if not np.linalg.norm(row) > 0:
            raise ViewspaceError(f"{path}:{number}: zero vector, a camera needs a direction")
        for other, other_line in zip(rows, lines, strict=True):
            if angular_distances(row[None], other[None])[0, 0] < 1e-6:
                raise ViewspaceError(
                    f"{path}:{number}: duplicate of the direction on line {other_line}"
                )
        rows.append(row)
        lines.append(number)
    if not rows:
        raise ViewspaceError(f"{path}: no camera positions found (expected rows 'x y z')")
    return np.array(rows)


def save_viewspace(path: str | Path, viewspace: np.ndarray) -> None:
    """Write a viewspace as text with full float64 precision (``%.18e``)."""
    with atomic_path(path) as tmp:
        np.savetxt(tmp, np.asarray(viewspace, dtype=np.float64), fmt="%.18e")


def fibonacci_directions(n: int, hemisphere: bool = False) -> np.ndarray:
    """``n`` directions of a Fibonacci lattice (nearly even spacing, no two alike), Y up.

    Point ``i`` sits at height ``1 - (2 i + 1) / n`` (sphere) or ``1 - (i + 0.5) / n``
    (hemisphere: elevations in (0, 90) degrees), azimuth ``i`` times the golden angle from +z
    towards +x.

    Args:
        n: number of directions, >= 1.
        hemisphere: only the half above the equator.

    Returns:
        (n, 3) float64 unit vectors.
    """
    if int(n) != n or n < 1:
        raise ViewspaceError(f"viewspace.n={n!r}: must be an integer >= 1")
    i = np.arange(int(n), dtype=np.float64)
    height = 1.0 - (i + 0.5) / n if hemisphere else 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(np.clip(1.0 - height**2, 0.0, 1.0))
    azimuth = i * GOLDEN_ANGLE
    return np.stack([r * np.sin(azimuth), height, r * np.cos(azimuth)], axis=1)


def is_named(name: str) -> bool:
    """Whether ``name`` names a viewspace (shipped or generated) rather than a file."""
    return name in SHIPPED or GENERATED_NAME.fullmatch(name) is not None


def get_viewspace(name_or_path: str | Path) -> np.ndarray:
    """A viewspace by name or by the path of a text file: (V, 3) float64.

    Names: ``original``, ``permuted`` (the shipped files), ``sphere_<n>`` and
    ``hemisphere_<n>`` (:func:`fibonacci_directions`, Y up).

    Raises:
        ViewspaceError: neither a name nor a readable file.
    """
    name = str(name_or_path)
    if name == "original":
        return original_viewspace()
    if name == "permuted":
        return load_viewspace(DATA_DIR / "permuted_33.txt")
    generated = GENERATED_NAME.fullmatch(name)
    if generated:
        return fibonacci_directions(int(generated[2]), generated[1] == "hemisphere")
    path = Path(name_or_path)
    if not path.exists():
        raise ViewspaceError(
            f"{path}: no such viewspace; use 'original', 'permuted', 'sphere_<n>', "
            "'hemisphere_<n>' or a text file of 'x y z' rows"
        )
    return load_viewspace(path)
