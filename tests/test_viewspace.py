from pathlib import Path

import numpy as np
import pytest

from nbv.geometry.viewspace import (
    DATA_DIR,
    PERMUTED_SEED,
    ViewspaceError,
    angular_distances,
    elevation,
    get_viewspace,
    load_viewspace,
    original_viewspace,
    permuted_viewspace,
    save_viewspace,
)

REFERENCE = (
    Path(__file__).resolve().parents[2] / "shared" / "reference" / "viewspace_original_33.txt"
)


def test_original_viewspace_layout():
    vs = original_viewspace()
    assert vs.shape == (33, 3) and vs.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(vs, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(vs[0], [0, 1, 0], atol=1e-15)
    rings = elevation(vs[1:]).reshape(4, 8)
    np.testing.assert_allclose(rings, [[60] * 8, [30] * 8, [0] * 8, [-30] * 8], atol=1e-9)
    # Azimuth 0 is +z, then 45 degrees towards +x.
    np.testing.assert_allclose(vs[17], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(vs[19], [1, 0, 0], atol=1e-15)


@pytest.mark.skipif(
    not REFERENCE.exists(), reason="../shared/reference is not beside this checkout"
)
def test_original_viewspace_matches_reference_file():
    np.testing.assert_allclose(original_viewspace(), np.loadtxt(REFERENCE), rtol=0, atol=1e-12)


def test_shipped_original_file_matches():
    np.testing.assert_allclose(
        load_viewspace(DATA_DIR / "original_33.txt"), original_viewspace(), rtol=0, atol=1e-15
    )


def test_permuted_viewspace_properties():
    orig = original_viewspace()
    perm = get_viewspace("permuted")
    assert perm.shape == (33, 3)
    np.testing.assert_allclose(np.linalg.norm(perm, axis=1), 1.0, atol=1e-12)
    # No permuted view within 5 degrees of an original view (so positions differ, and so order).
    assert angular_distances(perm, orig).min() >= 5.0
    # Same elevation band, and spread over it: both hemispheres of the band and all azimuths.
    el = elevation(perm)
    assert el.min() >= -30.0 and el.max() <= 90.0
    assert (el < 0).sum() >= 3 and (el > 45).sum() >= 3
    az = np.rad2deg(np.arctan2(perm[:, 0], perm[:, 2])) % 360
    assert np.histogram(az, bins=4, range=(0, 360))[0].min() >= 4
    # Evenly spread: no two permuted views closer than 10 degrees.
    d = angular_distances(perm, perm) + np.eye(33) * 999
    assert d.min() > 10.0


def test_permuted_file_is_the_seeded_procedure():
    np.testing.assert_allclose(
        get_viewspace("permuted"), permuted_viewspace(PERMUTED_SEED), rtol=0, atol=1e-15
    )
    assert not np.allclose(permuted_viewspace(1), permuted_viewspace(2))


def test_save_load_round_trip(tmp_path):
    vs = permuted_viewspace(5)
    save_viewspace(tmp_path / "v.txt", vs)
    np.testing.assert_array_equal(load_viewspace(tmp_path / "v.txt"), vs)
    assert np.array_equal(get_viewspace(tmp_path / "v.txt"), vs)


def test_user_file_with_comments_and_commas(tmp_path):
    path = tmp_path / "mine.txt"
    path.write_text("# my views\n1 0 0\n\n0, 2, 0\n")
    np.testing.assert_array_equal(load_viewspace(path), [[1, 0, 0], [0, 2, 0]])


@pytest.mark.parametrize(
    "text, line, message",
    [
        ("1 0 0\n0 1\n", 2, "expected 3 columns"),
        ("1 0 0\n0 1 0 4\n", 2, "expected 3 columns"),
        ("1 0 nan\n", 1, "NaN or infinite"),
        ("1 0 0\n0 inf 0\n", 2, "NaN or infinite"),
        ("1 0 0\n0 0 0\n", 2, "zero vector"),
        ("1 0 0\n0 1 0\n2 0 0\n", 3, "duplicate of the direction on line 1"),
        ("1 a 0\n", 1, "not a number"),
    ],
)
def test_bad_viewspace_files_refused_with_file_and_line(tmp_path, text, line, message):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(ViewspaceError, match=message) as err:
        load_viewspace(path)
    assert f"{path}:{line}:" in str(err.value)


def test_missing_and_empty_files_refused(tmp_path):
    with pytest.raises(ViewspaceError, match="cannot read"):
        load_viewspace(tmp_path / "none.txt")
    (tmp_path / "empty.txt").write_text("# nothing\n")
    with pytest.raises(ViewspaceError, match="no camera positions"):
        load_viewspace(tmp_path / "empty.txt")
    with pytest.raises(ViewspaceError, match="no such viewspace"):
        get_viewspace("sideways")
