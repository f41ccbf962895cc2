"""The spherical signatures (:mod:`nbv.geometry.sph`) against pyshtools' ``SHExpandLSQ``.

The toolkit's real orthonormal harmonics without the Condon-Shortley phase are pyshtools'
``norm=4, csphase=1`` harmonics, at latitude ``90 - degrees(theta)`` and longitude
``degrees(phi)``; coefficient ``l * l + l + m`` is ``cilm[0, l, m]`` for ``m >= 0`` and
``cilm[1, l, -m]`` for ``m < 0``. Both fits are plain least squares on the same radii, so after
that mapping they agree to rounding: the tests allow 1e-10 of the largest coefficient (measured:
about 2e-14). pyshtools' default ``norm=1`` (4-pi geodesy) coefficients are the toolkit's divided
by ``sqrt(4 pi)``. A planar cloud, whose directions span only part of the harmonics, is refused
by ``SHExpandLSQ`` (LAPACK's DGELS assumes full rank) while the toolkit returns the minimum-norm
solution: the same as the minimum-norm least squares on pyshtools' own design ``LSQ_G``
(the test does not call ``SHExpandLSQ`` there: its Fortran error message would leak into the
test run's output).

The meshes are ``../shared/meshes`` beside the checkout; their tests skip when it is absent.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from nbv.assets.meshes import load_mesh, normalise, sample_surface
from nbv.geometry.sph import (
    angles,
    equiangular_directions,
    fit,
    n_coeffs,
    signature_with_centroid,
    sph_index,
    unit_vectors,
)

pyshtools = pytest.importorskip("pyshtools")

SHARED_MESHES = Path(__file__).resolve().parents[1].parent / "shared" / "meshes"
LMAX = 3
#: Points sampled on a mesh: the size of a ground-truth cloud.
N_POINTS = 16384
#: Allowed difference between the two fits, relative to the largest coefficient.
RTOL = 1e-10

#: Column ``j`` of pyshtools' ``LSQ_G`` (per degree: cosines m = 0..l, then sines m = 1..l) is
#: the toolkit's harmonic ``_LSQ_G_ORDER[j]``.
_LSQ_G_ORDER = [
    sph_index(l, s * m)
    for l in range(LMAX + 1)  # noqa: E741
    for s, ms in ((1, range(l + 1)), (-1, range(1, l + 1)))
    for m in ms
]


def _from_cilm(cilm: np.ndarray) -> np.ndarray:
    """pyshtools' ``(2, lmax + 1, lmax + 1)`` coefficients in the toolkit's order."""
    out = np.zeros(n_coeffs(LMAX))
    for l in range(LMAX + 1):  # noqa: E741
        for m in range(-l, l + 1):
            out[sph_index(l, m)] = cilm[0, l, m] if m >= 0 else cilm[1, l, -m]
    return out


def _lat_lon(theta: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """pyshtools' latitude and longitude (degrees) of polar angles and azimuths (radians)."""
    return 90.0 - np.degrees(theta), np.degrees(phi)


def _radii(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radii about the centroid and their latitudes and longitudes, as :func:`fit` sees them."""
    offsets = points - points.mean(axis=0)
    return np.linalg.norm(offsets, axis=1), *_lat_lon(*angles(offsets))


def _cloud(name: str) -> np.ndarray:
    """A seeded ground-truth-sized cloud on the normalised mesh ``name`` of ../shared/meshes."""
    path = SHARED_MESHES / f"{name}.obj"
    if not path.is_file():
        pytest.skip(f"{path} is not there (the development meshes beside the checkout)")
    mesh = normalise(load_mesh(path))[0]
    return sample_surface(mesh, N_POINTS, np.random.default_rng(0)).astype(np.float64)


@pytest.mark.parametrize("name", ["cow", "spot", "teapot"])
def test_fit_and_signature_match_pyshtools(name: str):
    points = _cloud(name)
    r, lat, lon = _radii(points)
    cilm, _ = pyshtools.expand.SHExpandLSQ(r, lat, lon, LMAX, norm=4, csphase=1)
    expected = _from_cilm(cilm)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(fit(points, LMAX), expected, rtol=0, atol=RTOL * scale)
    # The default 4-pi normalisation: the same fit, coefficients divided by sqrt(4 pi).
    geodesy, _ = pyshtools.expand.SHExpandLSQ(r, lat, lon, LMAX)
    np.testing.assert_allclose(
        _from_cilm(geodesy) * np.sqrt(4.0 * np.pi), expected, rtol=0, atol=RTOL * scale
    )
    # The signature is pyshtools' expansion on the equiangular grid, to float32 rounding.
    sig, _ = signature_with_centroid(points, LMAX)
    theta, phi = equiangular_directions(LMAX)
    radius = pyshtools.expand.MakeGridPoint(cilm, *_lat_lon(theta, phi), norm=4, csphase=1)
    np.testing.assert_allclose(sig, radius[:, None] * unit_vectors(theta, phi), rtol=0, atol=1e-6)


def test_sphere_is_its_degree_zero_term():
    # Antipodal pairs on a sphere of radius 0.3 about the origin: the centroid is the centre.
    rng = np.random.default_rng(1)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    points = 0.3 * np.concatenate([d, -d])
    expected = np.zeros(n_coeffs(LMAX))
    expected[0] = 0.3 * np.sqrt(4.0 * np.pi)
    np.testing.assert_allclose(fit(points, LMAX), expected, rtol=0, atol=1e-12)
    cilm, _ = pyshtools.expand.SHExpandLSQ(*_radii(points), LMAX, norm=4, csphase=1)
    np.testing.assert_allclose(_from_cilm(cilm), expected, rtol=0, atol=1e-12)


def test_planar_cloud_is_the_minimum_norm_fit():
    # woody is flat (z = 0): its directions fill the equator only, 7 of the 16 harmonics' span.
    points = _cloud("woody")
    # (SHExpandLSQ itself stops with "DGELS INFO = 2", printed by Fortran at the process's exit.)
    r, lat, lon = _radii(points)
    design = pyshtools.expand.LSQ_G(lat, lon, LMAX, norm=4, csphase=1)
    assert np.linalg.matrix_rank(design) == 7
    expected = np.zeros(n_coeffs(LMAX))
    expected[_LSQ_G_ORDER] = np.linalg.lstsq(design, r, rcond=None)[0]
    scale = np.abs(expected).max()
    np.testing.assert_allclose(fit(points, LMAX), expected, rtol=0, atol=RTOL * scale)
