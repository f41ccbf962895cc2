import numpy as np
import pytest
from scipy.special import sph_harm_y

from nbv.geometry.sph import (
    angles,
    equiangular_directions,
    evaluate,
    fit,
    n_coeffs,
    real_sph_harm,
    real_sph_harm_dirs,
    signature,
    signature_with_centroid,
    sph_index,
    unit_vectors,
)


def _random_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _scipy_real_sph_harm(lmax: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Reference: scipy's complex harmonics (with Condon-Shortley phase) turned real."""
    out = np.zeros((len(theta), (lmax + 1) ** 2))
    for l in range(lmax + 1):  # noqa: E741
        for m in range(-l, l + 1):
            y = sph_harm_y(l, abs(m), theta, phi)
            if m == 0:
                out[:, l * l + l] = y.real
            elif m > 0:
                out[:, l * l + l + m] = np.sqrt(2.0) * (-1.0) ** m * y.real
            else:
                out[:, l * l + l + m] = np.sqrt(2.0) * (-1.0) ** m * y.imag
    return out


def test_index_and_count():
    assert n_coeffs(0) == 1 and n_coeffs(3) == 16
    assert [sph_index(d, m) for d in range(3) for m in range(-d, d + 1)] == list(range(9))
    with pytest.raises(ValueError):
        sph_index(2, 3)
    with pytest.raises(ValueError):
        n_coeffs(-1)


def test_matches_scipy_complex_harmonics_turned_real():
    rng = np.random.default_rng(0)
    theta = np.concatenate([np.arccos(rng.uniform(-1, 1, 200)), [0.0, np.pi, np.pi / 2]])
    phi = np.concatenate([rng.uniform(0, 2 * np.pi, 200), [0.3, 1.0, 0.0]])
    ours = real_sph_harm(6, theta, phi)
    assert ours.shape == (203, 49)
    np.testing.assert_allclose(ours, _scipy_real_sph_harm(6, theta, phi), rtol=0, atol=1e-10)


def test_known_low_degree_values():
    # Y_1^-1, Y_1^0, Y_1^1 are sqrt(3 / 4pi) times y, z, x.
    rng = np.random.default_rng(1)
    d = _random_directions(rng, 50)
    y = real_sph_harm_dirs(1, d)
    np.testing.assert_allclose(y[:, 0], 0.5 / np.sqrt(np.pi))
    np.testing.assert_allclose(y[:, 1:], np.sqrt(3 / (4 * np.pi)) * d[:, [1, 2, 0]], atol=1e-15)


def test_orthonormal_by_gauss_legendre_quadrature():
    lmax = 8
    # Exact for polynomials of degree <= 2 * lmax in cos(theta) and trig degree <= 2 * lmax.
    nodes, weights = np.polynomial.legendre.leggauss(lmax + 2)
    n_phi = 2 * lmax + 3
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    tt, pp = np.meshgrid(np.arccos(nodes), phi, indexing="ij")
    w = np.repeat(weights, n_phi) * (2 * np.pi / n_phi)
    y = real_sph_harm(lmax, tt.ravel(), pp.ravel())
    gram = y.T @ (w[:, None] * y)
    np.testing.assert_allclose(gram, np.eye((lmax + 1) ** 2), atol=1e-10)


def test_theta_phi_and_direction_paths_agree_and_broadcast():
    rng = np.random.default_rng(2)
    d = _random_directions(rng, 30)
    theta, phi = angles(d)
    assert np.all((theta >= 0) & (theta <= np.pi)) and np.all((phi >= 0) & (phi < 2 * np.pi))
    np.testing.assert_allclose(unit_vectors(theta, phi), d, atol=1e-15)
    np.testing.assert_allclose(real_sph_harm(4, theta, phi), real_sph_harm_dirs(4, d), atol=1e-14)
    assert real_sph_harm(2, theta.reshape(5, 6), 0.0).shape == (5, 6, 9)


def test_sphere_gives_only_c00():
    rng = np.random.default_rng(3)
    center = np.array([0.1, -0.2, 0.3])
    radius = 0.37
    pts = center + radius * _random_directions(rng, 5000)
    coeffs = fit(pts, 5, center=center)
    expected = np.zeros(36)
    expected[0] = radius * np.sqrt(4 * np.pi)
    np.testing.assert_allclose(coeffs, expected, atol=1e-10)


def test_sphere_about_its_centroid_by_default():
    rng = np.random.default_rng(4)
    d = _random_directions(rng, 2000)
    # Antipodal pairs: the centroid is exactly the centre.
    pts = np.array([1.0, 2.0, 3.0]) + 0.5 * np.concatenate([d, -d])
    coeffs = fit(pts, 3)
    np.testing.assert_allclose(coeffs[0], 0.5 * np.sqrt(4 * np.pi), atol=1e-10)
    np.testing.assert_allclose(coeffs[1:], 0.0, atol=1e-10)


def test_band_limited_radius_recovered_exactly():
    rng = np.random.default_rng(5)
    lmax = 4
    truth = np.zeros(25)
    truth[0] = 2.0
    truth[[sph_index(1, 0), sph_index(2, -2), sph_index(3, 1), sph_index(4, 4)]] = [
        0.3,
        -0.2,
        0.15,
        0.1,
    ]
    d = _random_directions(rng, 3000)
    r = real_sph_harm_dirs(lmax, d) @ truth
    assert r.min() > 0
    center = np.array([-0.4, 0.25, 0.05])
    pts = center + r[:, None] * d
    np.testing.assert_allclose(fit(pts, lmax, center=center), truth, atol=1e-8)
    # A higher degree than the truth finds zeros above it.
    high = fit(pts, 6, center=center)
    np.testing.assert_allclose(high[:25], truth, atol=1e-8)
    np.testing.assert_allclose(high[25:], 0.0, atol=1e-8)
    theta, phi = angles(d[:10])
    np.testing.assert_allclose(evaluate(truth, theta, phi), r[:10], atol=1e-12)


def test_fit_is_the_least_squares_solution_even_on_a_small_patch():
    # Directions within 20 degrees of +z pin down the low degrees badly: the solver must still
    # give the least-squares optimum (reference: numpy's SVD-based lstsq on scipy's harmonics).
    rng = np.random.default_rng(6)
    d = _random_directions(rng, 4000)
    d = d[d[:, 2] > np.cos(np.deg2rad(20))]
    r = 1.0 + 0.1 * rng.standard_normal(len(d))
    pts = r[:, None] * d
    coeffs = fit(pts, 3, center=np.zeros(3))
    theta, phi = angles(d)
    design = _scipy_real_sph_harm(3, theta, phi)
    ref = np.linalg.lstsq(design, r, rcond=None)[0]
    resid = np.linalg.norm(design @ coeffs - r)
    np.testing.assert_allclose(resid, np.linalg.norm(design @ ref - r), rtol=1e-6)


@pytest.mark.parametrize("lmax", [3, 6])
def test_fit_on_noisy_cloud_matches_brute_force_least_squares(lmax):
    # 20000 points span several blocks of the accumulated normal equations.
    rng = np.random.default_rng(7)
    pts = rng.normal(size=(20000, 3)) * [0.3, 0.2, 0.1] + [0.5, 0.0, -0.5]
    c = pts.mean(axis=0)
    theta, phi = angles(pts - c)
    ref = np.linalg.lstsq(
        _scipy_real_sph_harm(lmax, theta, phi), np.linalg.norm(pts - c, axis=1), rcond=None
    )[0]
    np.testing.assert_allclose(fit(pts, lmax), ref, atol=1e-9)
    np.testing.assert_allclose(fit(pts.astype(np.float32), lmax), ref, atol=1e-5)


def test_points_at_the_centre_are_left_out_and_bad_input_refused():
    rng = np.random.default_rng(8)
    d = _random_directions(rng, 12000)
    pts = (1.0 + 0.2 * d[:, :1] * d[:, 1:2]) * d
    # Points at the centre in the middle of the cloud (inside a later chunk and block).
    with_centre = np.concatenate([pts[:5000], np.zeros((3, 3)), pts[5000:], np.zeros((2, 3))])
    ref = np.linalg.lstsq(real_sph_harm_dirs(6, d), np.linalg.norm(pts, axis=1), rcond=None)[0]
    np.testing.assert_allclose(fit(with_centre, 6, center=np.zeros(3)), ref, atol=1e-12)
    with pytest.raises(ValueError, match="centre"):
        fit(np.zeros((4, 3)), 2)
    with pytest.raises(ValueError, match="empty"):
        fit(np.zeros((0, 3)), 2)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        fit(np.zeros((4, 2)), 2)
    with pytest.raises(ValueError, match="non-finite"):
        fit(np.concatenate([pts, [[np.nan, 0, 0]]]), 2)
    with pytest.raises(ValueError, match="lmax"):
        fit(pts, -1)
    with pytest.raises(ValueError, match="coefficient"):
        evaluate(np.zeros(5), 0.0, 0.0)


@pytest.mark.parametrize("lmax", [0, 1, 3, 5])
def test_equiangular_grid(lmax):
    theta, phi = equiangular_directions(lmax)
    b = lmax + 1
    assert theta.shape == phi.shape == (4 * b * b,)
    j, k = np.divmod(np.arange(4 * b * b), 2 * b)
    np.testing.assert_allclose(theta, np.pi * (2 * j + 1) / (4 * b))
    np.testing.assert_allclose(phi, 2 * np.pi * k / (2 * b))
    # No pole samples, no duplicate directions, symmetric about the equator.
    assert theta.min() > 0 and theta.max() < np.pi
    dirs = unit_vectors(theta, phi)
    assert len(np.unique(np.round(dirs, 12), axis=0)) == len(dirs)
    np.testing.assert_allclose(np.sort(theta), np.sort(np.pi - theta), atol=1e-15)


def test_signature_of_a_sphere_lies_on_it():
    rng = np.random.default_rng(9)
    d = _random_directions(rng, 3000)
    center = np.array([0.2, 0.1, -0.3])
    pts = (center + 0.4 * np.concatenate([d, -d])).astype(np.float32)
    sig, centroid = signature_with_centroid(pts, 3)
    assert sig.shape == (64, 3) and sig.dtype == np.float32
    np.testing.assert_allclose(centroid, center, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(sig, axis=1), 0.4, rtol=1e-5)
    np.testing.assert_allclose(
        sig / np.linalg.norm(sig, axis=1, keepdims=True),
        unit_vectors(*equiangular_directions(3)),
        atol=1e-6,
    )
    np.testing.assert_array_equal(signature(pts, 3), sig)


def test_signature_reconstructs_a_band_limited_shape():
    rng = np.random.default_rng(10)
    truth = np.zeros(16)
    truth[0], truth[sph_index(2, 1)], truth[sph_index(2, -2)] = 1.5, 0.2, -0.1
    d = _random_directions(rng, 4000)
    d = np.concatenate([d, -d])
    # Even degrees only and antipodal pairs: r(-d) = r(d), so the centroid is the origin and the
    # signature must be the true radius on the grid.
    pts = (real_sph_harm_dirs(3, d) @ truth)[:, None] * d
    sig, centroid = signature_with_centroid(pts, 3)
    np.testing.assert_allclose(centroid, 0.0, atol=1e-12)
    theta, phi = equiangular_directions(3)
    expected = evaluate(truth, theta, phi)[:, None] * unit_vectors(theta, phi)
    np.testing.assert_allclose(sig, expected, atol=1e-6)
    assert signature(pts, 1).shape == (16, 3)
    assert signature(pts, 0).shape == (4, 3)
    # Degree 0: a sphere of the mean radius.
    np.testing.assert_allclose(
        np.linalg.norm(signature(pts, 0), axis=1), np.linalg.norm(pts, axis=1).mean(), rtol=1e-6
    )


@pytest.mark.parametrize("lmax", [0, 1, 2, 3, 6])
def test_compiled_design_columns_equal_the_array_recurrences_bit_for_bit(lmax):
    # The fit's design is built point by point in numba; its values must be those of the numpy
    # recurrences exactly (the signatures the shipped networks were trained and evaluated on).
    from nbv.geometry.sph import (
        _design_columns,
        _harmonics_rows,
        _recurrence_constants,
        _unit_offsets,
    )

    rng = np.random.default_rng(lmax)
    coords = rng.normal(size=(3, 5000)) * rng.uniform(0.01, 10.0) + rng.normal(size=(3, 1))
    centre = coords.mean(axis=1)
    coords[:, [5, 4000]] = centre[:, None]  # two points at the centre: skipped
    k = (lmax + 1) ** 2
    design = np.full((k + 1, 6000), np.nan)
    used = _design_columns(coords, 3, 4999, centre, *_recurrence_constants(lmax), design)
    x, y, z, r = _unit_offsets(coords[:, 3:4999], centre)
    assert used == len(r) == 4994
    assert np.array_equal(design[:k, :used], _harmonics_rows(lmax, x, y, z))
    assert np.array_equal(design[k, :used], r)
    assert np.isnan(design[:, used:]).all()  # nothing written past the points used
