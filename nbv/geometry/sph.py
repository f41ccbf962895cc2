"""Real spherical harmonics, least-squares radius fits, and the spherical signature of a cloud.

A cloud seen from a centre ``c`` (its centroid unless told otherwise) defines a radius function
``r(theta, phi) = |p - c|`` over the directions of its points. :func:`fit` expands it in real
spherical harmonics up to degree ``lmax`` (the paper's eq. 8 and 12); :func:`signature` (the
paper's Algorithm 1) evaluates the expansion on a fixed equiangular grid of ``4 (lmax + 1)^2``
directions and returns the points ``r(dir) * dir``: a fixed-size cloud for the network.

Conventions (the paper swaps the names latitude/longitude; these are the ones used here):

* ``theta`` is the polar angle (colatitude) in ``[0, pi]``, measured from the **+z axis** of the
  frame the points are given in; ``phi`` is the azimuth in ``[0, 2 pi)``, from +x towards +y.
  The unit direction is ``(sin theta cos phi, sin theta sin phi, cos theta)``. The world is Y-up,
  but the harmonics' pole is z: the pole only decides where the sampling grid is densest (the
  signature is a set of 3-D points in the cloud's own frame either way).
* Real, orthonormal harmonics (``integral over the sphere of Y_i Y_j = delta_ij``)::

      Y_l^m = sqrt(2) K_l^m  P_l^m(cos theta)  cos(m phi)       m > 0
      Y_l^0 =         K_l^0  P_l^0(cos theta)
      Y_l^m = sqrt(2) K_l^|m| P_l^|m|(cos theta) sin(|m| phi)    m < 0
      K_l^m = sqrt((2l + 1) / (4 pi) * (l - m)! / (l + m)!)

  with ``P_l^m`` the associated Legendre functions *without* the Condon-Shortley phase
  ``(-1)^m``. Against the complex harmonics that include it (``scipy.special.sph_harm_y``):
  ``Y_l^m = sqrt(2) (-1)^m Re Y_l^m,complex`` for ``m > 0`` and
  ``Y_l^m = sqrt(2) (-1)^m Im Y_l^|m|,complex`` for ``m < 0``.
* Coefficients are ordered by ``index = l * l + l + m`` (``l = 0..lmax``, ``m = -l..l``), so there
  are ``(lmax + 1)^2`` of them. Every array of harmonics is ``(..., (lmax + 1)^2)``.
* Fit (eq. 12): ``c = argmin_c sum_i (r_i - sum_lm c_lm Y_lm(theta_i, phi_i))^2``. The paper's
  eq. 12-13 square the ``Y``; that is a typo, the model is linear in ``Y``. A sphere of radius
  ``R`` about the centre gives ``c_00 = R sqrt(4 pi)`` and nothing else.
* Sampling grid: Driscoll-Healy style equiangular grid with bandwidth ``B = lmax + 1``, shifted by
  half a step in ``theta`` so that no sample sits on a pole (the variant used by Kostelec and
  Rockmore's SOFT): ``theta_j = pi (2 j + 1) / (4 B)``, ``phi_k = 2 pi k / (2 B)``,
  ``j, k = 0 .. 2B - 1``, flattened theta-major (``index = j * 2B + k``): ``4 B^2`` directions,
  no duplicates.

The harmonics are computed from unit vectors by recurrences on ``cos theta = z`` and
``sin^m theta e^{i m phi} = (x + i y)^m``: no trigonometric functions in the fast path.
"""

from __future__ import annotations

from functools import lru_cache

import numba
import numpy as np

_INV_SQRT_4PI = 1.0 / np.sqrt(4.0 * np.pi)
_SQRT2 = np.sqrt(2.0)

#: The normal equations are solved directly when the Gram matrix's condition number is below
#: this (so the fit loses at most ~1e-8 relative); otherwise a full least-squares solve is used.
_MAX_GRAM_CONDITION = 1e8


def n_coeffs(lmax: int) -> int:
    """Number of harmonics of degree ``0..lmax``: ``(lmax + 1)^2``."""
    return (_check_lmax(lmax) + 1) ** 2


def sph_index(l: int, m: int) -> int:  # noqa: E741 - l is the standard name of the degree
    """Position of ``Y_l^m`` in a coefficient vector: ``l * l + l + m``."""
    if l < 0 or abs(m) > l:
        raise ValueError(f"need l >= 0 and |m| <= l, got l={l}, m={m}")
    return l * l + l + m


def _check_lmax(lmax: int) -> int:
    if isinstance(lmax, bool) or not isinstance(lmax, int | np.integer) or lmax < 0:
        raise ValueError(f"lmax must be an integer >= 0, got {lmax!r}")
    return int(lmax)


def _lmax_of(n: int) -> int:
    lmax = int(round(np.sqrt(n))) - 1
    if n == 0 or n_coeffs(lmax) != n:
        raise ValueError(f"a coefficient vector has (lmax + 1)^2 entries, got {n}")
    return lmax


def unit_vectors(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit directions ``(..., 3)`` float64 of polar angles ``theta`` and azimuths ``phi`` (rad)."""
    theta, phi = np.broadcast_arrays(np.asarray(theta, np.float64), np.asarray(phi, np.float64))
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def angles(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Polar angle in ``[0, pi]`` and azimuth in ``[0, 2 pi)`` of ``(..., 3)`` non-zero vectors."""
    d = np.asarray(directions, dtype=np.float64)
    theta = np.arctan2(np.hypot(d[..., 0], d[..., 1]), d[..., 2])
    phi = np.mod(np.arctan2(d[..., 1], d[..., 0]), 2.0 * np.pi)
    return theta, phi


def _harmonics_rows(
    lmax: int, x: np.ndarray, y: np.ndarray, z: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """Real harmonics of unit vectors, ``((lmax + 1)^2, P)`` float64 (one contiguous row each).

    ``x, y, z`` are contiguous ``(P,)`` float64 components of unit vectors; ``out`` an optional
    ``((lmax + 1)^2, P)`` buffer to write into.
    """
    n = x.shape[0]
    if out is None:
        out = np.empty((n_coeffs(lmax), n))
    out[0] = _INV_SQRT_4PI
    c_m, s_m = None, None  # sin^m(theta) cos(m phi), sin^m(theta) sin(m phi)
    # Normalised P_m^m(cos theta) / sin^m(theta) is a constant; sqrt(2) of the m > 0 harmonics
    # is folded into it.
    q_mm = _INV_SQRT_4PI
    for m in range(lmax + 1):
        if m == 1:
            c_m, s_m = x, y
            q_mm *= np.sqrt(1.5) * _SQRT2
        elif m > 1:
            c_m, s_m = x * c_m - y * s_m, x * s_m + y * c_m
            q_mm *= np.sqrt((2.0 * m + 1.0) / (2.0 * m))
        # Legendre values (over sin^m) by the stable three-term recurrence in l; q_l2, q_l1 are
        # those of degrees l - 2 and l - 1 (scalars at l = m).
        q_l2, q_l1 = 0.0, q_mm
        for l in range(m, lmax + 1):  # noqa: E741
            base = l * l + l
            # For m = 0 the Legendre values are the harmonics: written in place, no copy.
            dest = out[base] if m == 0 else None
            if l == m + 1:
                q_l = np.multiply(np.sqrt(2.0 * m + 3.0) * q_mm, z, out=dest)
            elif l > m + 1:
                a = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
                b = np.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
                q_l = np.subtract(a * z * q_l1, (a * b) * q_l2, out=dest)
            else:
                q_l = q_mm
            if l > m:
                q_l2, q_l1 = q_l1, q_l
            if m > 0:
                np.multiply(q_l, c_m, out=out[base + m])
                np.multiply(q_l, s_m, out=out[base - m])
    return out


def real_sph_harm_dirs(lmax: int, directions: np.ndarray) -> np.ndarray:
    """Real harmonics of degree ``0..lmax`` at unit directions.

    Args:
        lmax: maximum degree, >= 0.
        directions: ``(P, 3)`` unit vectors (not normalised here).

    Returns:
        ``(P, (lmax + 1)^2)`` float64, column ``l * l + l + m`` holds ``Y_l^m``.
    """
    lmax = _check_lmax(lmax)
    d = np.asarray(directions, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] != 3:
        raise ValueError(f"directions must have shape (P, 3), got {d.shape}")
    x, y, z = (np.ascontiguousarray(d[:, i]) for i in range(3))
    return np.ascontiguousarray(_harmonics_rows(lmax, x, y, z).T)


def real_sph_harm(lmax: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Real orthonormal harmonics of degree ``0..lmax`` (module conventions).

    Args:
        lmax: maximum degree, >= 0.
        theta: polar angles in radians, any shape broadcastable with ``phi``.
        phi: azimuths in radians.

    Returns:
        ``(*shape, (lmax + 1)^2)`` float64, last axis ordered by ``l * l + l + m``.
    """
    dirs = unit_vectors(theta, phi)
    shape = dirs.shape[:-1]
    return real_sph_harm_dirs(lmax, dirs.reshape(-1, 3)).reshape(*shape, -1)


def _as_coords(points: np.ndarray) -> np.ndarray:
    """An ``(N, 3)`` cloud as contiguous float64 coordinate rows ``(3, N)``, or a ValueError."""
    arr = np.asarray(points)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {arr.shape}")
    if len(arr) == 0:
        raise ValueError("points is empty: a radius function needs at least one point")
    # Finiteness is checked on the accumulated sums (NaN and inf propagate there): one pass less.
    return np.array(arr.T, dtype=np.float64, order="C")


def _center_of(coords: np.ndarray, center: np.ndarray | None) -> np.ndarray:
    if center is None:
        return coords.mean(axis=1)
    c = np.asarray(center, dtype=np.float64)
    if c.shape != (3,) or not np.isfinite(c).all():
        raise ValueError(f"center must be a finite (3,) vector, got {c!r}")
    return c


def _block_size(n_harmonics: int) -> int:
    """Columns per BLAS block of the design matrix: the normal equations are accumulated over
    blocks of about 4 MB of design, so that BLAS is called a few times only. (A multiple of
    4,096 columns: the blocks, and so the sums' rounding, are those of the fits before.)"""
    return max(1, 2**19 // (n_harmonics * 4096)) * 4096


def _unit_offsets(
    coords: np.ndarray, center: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit directions ``x, y, z`` and radii ``r`` of ``(3, P)`` coordinates about ``center``.

    Points at the centre (no direction) are left out.
    """
    x, y, z = coords[0] - center[0], coords[1] - center[1], coords[2] - center[2]
    r = np.sqrt(x * x + y * y + z * z)
    if not r.all():
        keep = r > 0.0
        x, y, z, r = x[keep], y[keep], z[keep], r[keep]
    inv_r = 1.0 / r
    return x * inv_r, y * inv_r, z * inv_r, r


def fit(points: np.ndarray, lmax: int, center: np.ndarray | None = None) -> np.ndarray:
    """Least-squares harmonic coefficients of a cloud's radius function (the paper's eq. 12).

    Args:
        points: ``(N, 3)`` cloud, any float dtype.
        lmax: maximum degree, >= 0.
        center: ``(3,)`` point the radii and directions are measured from; defaults to the
            cloud's centroid. Points at the centre have no direction and are left out.

    Returns:
        ``((lmax + 1)^2,)`` float64 coefficients ``c`` with ``r(theta, phi) ~ sum c_lm Y_lm``,
        in the cloud's units, ordered by ``l * l + l + m``. When the directions do not determine
        every coefficient (a small patch, too few points), the minimum-norm least-squares
        solution.
    """
    return _fit_coords(_as_coords(points), _check_lmax(lmax), center)


@lru_cache(maxsize=16)
def _recurrence_constants(lmax: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The (read-only) scalars of :func:`_harmonics_rows`'s recurrences, computed as it does:
    ``q_mm`` and ``sqrt(2 m + 3) q_mm`` (each ``(lmax + 1,)``), and ``a`` and ``a b`` of degree
    ``l`` and order ``m`` (each ``(lmax + 1, lmax + 1)``, indexed ``[m, l]``, used for
    ``l > m + 1``)."""
    q_mm = np.empty(lmax + 1)
    first = np.empty(lmax + 1)
    a_ml = np.zeros((lmax + 1, lmax + 1))
    ab_ml = np.zeros((lmax + 1, lmax + 1))
    q = _INV_SQRT_4PI
    for m in range(lmax + 1):
        if m == 1:
            q *= np.sqrt(1.5) * _SQRT2
        elif m > 1:
            q *= np.sqrt((2.0 * m + 1.0) / (2.0 * m))
        q_mm[m], first[m] = q, np.sqrt(2.0 * m + 3.0) * q
        for l in range(m + 2, lmax + 1):  # noqa: E741
            a = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b = np.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
            a_ml[m, l], ab_ml[m, l] = a, a * b
    return _read_only(q_mm, first, a_ml, ab_ml)


def _read_only(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """``arrays``, made read-only: a cached value must not be changed by a caller."""
    for a in arrays:
        a.flags.writeable = False
    return arrays


#: Points a pass of :func:`_design_columns` works on: its eight temporaries (128 KB) stay in
#: the cache.
_DESIGN_CHUNK = 2048


@numba.njit(cache=True, nogil=True)
def _design_columns(coords, start, stop, center, q_mm, first, a_ml, ab_ml, out):  # pragma: no cover
    """The design ``out`` ((lmax + 1)^2 + 1, block) of the points ``start:stop`` of ``coords``
    (3, N) about ``center``: a column per point, the harmonics of its direction, then its
    radius; points at the centre are skipped. Returns the number of columns written.

    Every value is the one :func:`_unit_offsets` and :func:`_harmonics_rows` compute, bit for
    bit: the same IEEE operations in the same order, fused into a few loops over cached chunks
    of points (numba reassociates nothing and contracts no multiply-add into an FMA unless
    asked to).
    """
    lmax = len(q_mm) - 1
    k = (lmax + 1) * (lmax + 1)
    size = min(_DESIGN_CHUNK, stop - start)
    x, y, z, r = np.empty(size), np.empty(size), np.empty(size), np.empty(size)
    c_m, s_m, q_l1, q_l2 = np.empty(size), np.empty(size), np.empty(size), np.empty(size)
    o = 0
    for begin in range(start, stop, size):
        n = min(size, stop - begin)
        for i in range(n):
            x[i] = coords[0, begin + i] - center[0]
            y[i] = coords[1, begin + i] - center[1]
            z[i] = coords[2, begin + i] - center[2]
            r[i] = np.sqrt(x[i] * x[i] + y[i] * y[i] + z[i] * z[i])
        used = 0
        for i in range(n):
            if r[i] != 0.0:
                x[used], y[used], z[used], r[used] = x[i], y[i], z[i], r[i]
                used += 1
        for i in range(used):
            inv_r = 1.0 / r[i]
            x[i] = x[i] * inv_r
            y[i] = y[i] * inv_r
            z[i] = z[i] * inv_r
            out[k, o + i] = r[i]
        for m in range(lmax + 1):
            if m == 1:
                c_m[:used] = x[:used]
                s_m[:used] = y[:used]
            elif m > 1:
                for i in range(used):
                    c, s = c_m[i], s_m[i]
                    c_m[i] = x[i] * c - y[i] * s
                    s_m[i] = x[i] * s + y[i] * c
            q = q_mm[m]
            for l in range(m, lmax + 1):  # noqa: E741
                row_c, row_s = out[l * l + l + m], out[l * l + l - m]
                if l == m:
                    if m == 0:
                        row_c[o : o + used] = q
                    else:
                        for i in range(used):
                            row_c[o + i] = q * c_m[i]
                            row_s[o + i] = q * s_m[i]
                    continue
                f, a, ab = first[m], a_ml[m, l], ab_ml[m, l]
                for i in range(used):
                    if l == m + 1:
                        q_l = f * z[i]
                    elif l == m + 2:
                        q_l = a * z[i] * q_l1[i] - ab * q
                    else:
                        q_l = a * z[i] * q_l1[i] - ab * q_l2[i]
                    q_l2[i] = q_l1[i]
                    q_l1[i] = q_l
                    if m == 0:
                        row_c[o + i] = q_l
                    else:
                        row_c[o + i] = q_l * c_m[i]
                        row_s[o + i] = q_l * s_m[i]
        o += used
    return o


def _fit_coords(coords: np.ndarray, lmax: int, center: np.ndarray | None) -> np.ndarray:
    """:func:`fit` on ``(3, N)`` contiguous float64 coordinates."""
    c = _center_of(coords, center)
    k = (lmax + 1) ** 2
    # Normal equations accumulated block by block: the design matrix is never held whole.
    # The radii ride along as an extra design row: one product gives both A A^T and A r.
    normal = np.zeros((k + 1, k + 1))
    block = _block_size(k + 1)
    design = np.empty((k + 1, block))
    constants = _recurrence_constants(lmax)
    n_used = 0
    for start in range(0, coords.shape[1], block):
        stop = min(start + block, coords.shape[1])
        filled = _design_columns(coords, start, stop, c, *constants, design)
        rows = design[:, :filled]
        normal += rows @ rows.T
        n_used += filled
    gram, rhs = normal[:k, :k], normal[:k, k]
    if not (np.isfinite(gram).all() and np.isfinite(rhs).all()):
        raise ValueError("points holds non-finite values (nan or inf); only finite points allowed")
    if n_used == 0:
        raise ValueError("every point lies at the centre: the radius function is undefined")
    w = np.linalg.eigvalsh(gram)
    if w[0] > w[-1] / _MAX_GRAM_CONDITION:
        return np.linalg.solve(gram, rhs)
    # Ill-conditioned: solve on the whole design, which does not square the condition number.
    x, y, z, r = _unit_offsets(coords, c)
    return np.linalg.lstsq(_harmonics_rows(lmax, x, y, z).T, r, rcond=None)[0]


def evaluate(coeffs: np.ndarray, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Radius ``r(theta, phi) = sum c_lm Y_lm(theta, phi)`` (the paper's eq. 8).

    Args:
        coeffs: ``((lmax + 1)^2,)`` coefficients from :func:`fit`.
        theta, phi: angles in radians (module conventions), broadcastable.

    Returns:
        float64 array of the broadcast shape of ``theta`` and ``phi``.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim != 1:
        raise ValueError(f"coeffs must be a 1-D vector, got shape {c.shape}")
    return real_sph_harm(_lmax_of(len(c)), theta, phi) @ c


def equiangular_directions(lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """The signature's sampling grid: ``4 (lmax + 1)^2`` equiangular directions.

    Bandwidth ``B = lmax + 1``; ``theta_j = pi (2 j + 1) / (4 B)`` and ``phi_k = 2 pi k / (2 B)``
    for ``j, k = 0 .. 2B - 1`` (Driscoll-Healy grid shifted half a step in theta: no pole
    samples), flattened theta-major, ``index = j * 2B + k``.

    Returns:
        ``(theta, phi)``, each ``(4 (lmax + 1)^2,)`` float64, radians.
    """
    two_b = 2 * (_check_lmax(lmax) + 1)
    theta = np.pi * (2.0 * np.arange(two_b) + 1.0) / (2.0 * two_b)
    phi = 2.0 * np.pi * np.arange(two_b) / two_b
    tt, pp = np.meshgrid(theta, phi, indexing="ij")
    return tt.ravel(), pp.ravel()


def signature_with_centroid(points: np.ndarray, lmax: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Spherical signature (Algorithm 1) and the centroid it is relative to.

    Fits the radius function about the cloud's centroid (:func:`fit`), evaluates it on
    :func:`equiangular_directions` and returns ``r(dir) * dir``. Where the fit is poor the
    reconstructed radius may be negative; it is kept as is (the point then lies on the opposite
    side of the centroid), so the signature is exactly the expansion's values.

    Args:
        points: ``(N, 3)`` cloud, any float dtype, N >= 1.
        lmax: maximum degree, >= 0 (the paper uses 3).

    Returns:
        ``(signature, centroid)``: ``(4 (lmax + 1)^2, 3)`` float32 points in the cloud's own
        frame (centred at the centroid; add ``centroid`` for world coordinates), rows in the order
        of :func:`equiangular_directions`; and the ``(3,)`` float64 centroid.
    """
    lmax = _check_lmax(lmax)
    coords = _as_coords(points)
    centroid = coords.mean(axis=1)
    coeffs = _fit_coords(coords, lmax, centroid)
    dirs, harmonics = _signature_grid(lmax)
    radius = harmonics @ coeffs
    return (radius[:, None] * dirs).astype(np.float32), centroid


@lru_cache(maxsize=16)
def _signature_grid(lmax: int) -> tuple[np.ndarray, np.ndarray]:
    """The (read-only) unit directions ``(4 (lmax + 1)^2, 3)`` of
    :func:`equiangular_directions` and their harmonics ``(4 (lmax + 1)^2, (lmax + 1)^2)``:
    the same for every cloud, so computed once a degree."""
    dirs = unit_vectors(*equiangular_directions(lmax))
    return _read_only(dirs, real_sph_harm_dirs(lmax, dirs))


def signature(points: np.ndarray, lmax: int = 3) -> np.ndarray:
    """Spherical signature (Algorithm 1): ``(4 (lmax + 1)^2, 3)`` float32 points about the centroid.

    See :func:`signature_with_centroid`.
    """
    return signature_with_centroid(points, lmax)[0]
