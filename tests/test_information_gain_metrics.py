"""Area Factor and Proximity Count on hand-built occupancy grids with known answers, and against
brute force: the two volumetric information-gain baselines of the field (Vasquez-Gomez et al.
2014; Isler et al. 2016; compared by Delmerico et al. 2018)."""

import math

import numpy as np
import pytest

from nbv.infogain.gain import (
    AREA_OCCPLANE,
    AREA_OCCUPIED,
    OCCPLANE_RAY,
    OCCUPIED_RAY,
    PROXIMITY_RANGE,
    UNOBSERVED_RAY,
    area_factor,
    frontier,
    proximity,
    ray_gains,
    view_gains,
)
from nbv.infogain.occupancy import OccupancyMap, OccupancySettings

OCCUPIED, FREE = 1.0, -1.0  # log-odds of a hit voxel and of a crossed one (NaN: unknown)


def _map(resolution: float = 0.04) -> OccupancyMap:
    """An all-unknown map (no free prior outside the object's sphere): 28^3 voxels of 4 cm."""
    return OccupancyMap(OccupancySettings(resolution=resolution, bound=0.56, object_radius=None))


def _flat(occupancy: OccupancyMap, *ijk) -> int:
    n = occupancy.settings.n
    return int(np.ravel_multi_index(ijk, (n, n, n)))


def _rays(occupancy: OccupancyMap, rows: list[list[tuple[int, int, int]]]) -> np.ndarray:
    """(R, S) flat voxel indices of hand-listed rays, padded with -1."""
    width = max(len(r) for r in rows)
    out = np.full((len(rows), width), -1, dtype=np.int64)
    for i, row in enumerate(rows):
        out[i, : len(row)] = [_flat(occupancy, *ijk) for ijk in row]
    return out


# --------------------------------------------------------------------------------------------
# Proximity Count
# --------------------------------------------------------------------------------------------


def test_proximity_count_weighs_unknown_voxels_by_their_distance_to_the_surface():
    occupancy = _map()
    assert PROXIMITY_RANGE == 0.1  # the numbers below are for 4 cm voxels and a 10 cm range
    occupancy.log_odds[_flat(occupancy, 14, 14, 14)] = OCCUPIED
    occupancy.log_odds[_flat(occupancy, 17, 15, 14)] = FREE
    rays = _rays(occupancy, [
        # Straight at the occupied voxel: unknown at 16, 12, 8 and 4 cm from it, then the hit
        # (the ray stops there; what lies beyond does not count).
        [(10, 14, 14), (11, 14, 14), (12, 14, 14), (13, 14, 14), (14, 14, 14), (15, 14, 14)],
        # Beside it, one voxel off: dx = -4..4, d = 4 cm sqrt(dx^2 + 1); the voxel at dx = 3
        # is free (it counts nothing, and would count nothing anyway: d > 10 cm) ...
        [(i, 15, 14) for i in range(10, 19)],
        # ... and one at dx = 1 is made free below, in the third ray's copy of the map.
        [(i, 13, 14) for i in range(10, 19)],
        # Far away: nothing.
        [(i, 2, 2) for i in range(0, 28)],
    ])  # fmt: skip
    beside = 0.6 + 2 * (1 - 0.4 * math.sqrt(2)) + 2 * (1 - 0.4 * math.sqrt(5))
    expected = [0.2 + 0.6, beside, beside, 0.0]
    np.testing.assert_allclose(ray_gains(occupancy, rays, "proximity_count"), expected, atol=1e-12)
    occupancy.log_odds[_flat(occupancy, 15, 13, 14)] = FREE  # dx = 1 on the third ray
    expected[2] -= 1 - 0.4 * math.sqrt(2)
    np.testing.assert_allclose(ray_gains(occupancy, rays, "proximity_count"), expected, atol=1e-12)
    # A view's gain is the sum over its rays; depth caps only unobserved and frontier.
    gains = view_gains(occupancy, rays.reshape(2, 2, -1), "proximity_count", depth=1)
    np.testing.assert_allclose(gains, [expected[0] + expected[1], expected[2]], atol=1e-12)


def test_proximity_weights_equal_brute_force_distances():
    rng = np.random.default_rng(3)
    occupancy = _map(0.08)  # 14^3 voxels
    n = occupancy.settings.n
    labels = rng.choice([np.nan, OCCUPIED, FREE], n**3, p=[0.9, 0.004, 0.096])
    labels[: n**2] = np.nan  # one face of the box all unknown: the crop must not cut it off
    occupancy.log_odds[:] = labels
    centres = occupancy.centres()
    occupied = centres[labels == OCCUPIED]
    assert 3 <= len(occupied) <= 30
    distance = np.linalg.norm(centres[:, None] - occupied[None], axis=2).min(axis=1)
    expected = np.where(np.isnan(labels), np.maximum(0.0, 1 - distance / PROXIMITY_RANGE), 0.0)
    np.testing.assert_allclose(proximity(occupancy), expected, atol=1e-12)
    assert (expected > 0).sum() > 20
    wide = np.maximum(0.0, 1 - distance / 0.3)
    np.testing.assert_allclose(
        proximity(occupancy, 0.3), np.where(np.isnan(labels), wide, 0.0), atol=1e-12
    )
    # Nothing occupied: nothing weighs.
    assert not proximity(_map()).any()


# --------------------------------------------------------------------------------------------
# Area Factor
# --------------------------------------------------------------------------------------------


def _published_area_factor(x: float, a: float) -> float:
    """Vasquez-Gomez et al.'s piecewise cubic as published, in its coefficients."""
    if x <= a:
        return -2 * x**3 / a**3 + 3 * x**2 / a**2
    d = (a - 1) ** 3
    return (-2 * x**3 + (3 * a + 3) * x**2 - 6 * a * x + (3 * a - 1)) / d


@pytest.mark.parametrize("desired", [AREA_OCCUPIED, AREA_OCCPLANE, 0.5])
def test_area_factor_is_the_published_cubic(desired):
    x = np.linspace(0.0, 1.0, 101)
    expected = [_published_area_factor(v, desired) for v in x]
    np.testing.assert_allclose(area_factor(x, desired), expected, atol=1e-12)
    assert area_factor(0.0, desired) == 0.0 and area_factor(1.0, desired) == 0.0
    assert area_factor(desired, desired) == pytest.approx(1.0)
    assert area_factor(desired / 2, desired) == pytest.approx(0.5)
    assert area_factor((1 + desired) / 2, desired) == pytest.approx(0.5)
    assert np.all(area_factor(x, desired) <= 1.0 + 1e-12)


def test_area_factor_classes_rays_by_what_they_meet_first():
    occupancy = _map()
    surface = [(14, 14, 14), (14, 15, 14), (14, 16, 14)]
    for ijk in surface:
        occupancy.log_odds[_flat(occupancy, *ijk)] = OCCUPIED
    for i in range(8, 14):  # seen free space in front of the surface
        for j in (14, 15, 16):
            occupancy.log_odds[_flat(occupancy, i, j, 14)] = FREE
    rays = _rays(occupancy, [
        # Through free space onto the surface: occupied.
        [(i, 14, 14) for i in range(8, 20)],
        # Starting on the surface: occupied.
        [(14, 16, 14), (15, 16, 14)],
        # Through free space past the surface's edge into the unknown voxel beside it (which
        # touches an occupied voxel): occplane.
        [(i, 17, 14) for i in range(8, 20)],
        # Unknown voxels far from the surface only: unobserved.
        [(i, 3, 3) for i in range(0, 28)],
        # Free voxels only: unobserved.
        [(i, 15, 14) for i in range(8, 14)],
    ])  # fmt: skip
    for i in range(8, 14):  # the third ray's start is free too
        occupancy.log_odds[_flat(occupancy, i, 17, 14)] = FREE
    classes = ray_gains(occupancy, rays, "area_factor")
    assert classes.tolist() == [OCCUPIED_RAY, OCCUPIED_RAY, OCCPLANE_RAY, UNOBSERVED_RAY,
                                UNOBSERVED_RAY]  # fmt: skip
    assert frontier(occupancy)[_flat(occupancy, 14, 17, 14)]
    # Two of five rays occupied, one occplane: AF(0.4; 0.2) + AF(0.2; 0.8) = 0.84375 + 0.15625.
    assert AREA_OCCUPIED == 0.2 and AREA_OCCPLANE == 0.8
    gains = view_gains(occupancy, rays[None], "area_factor")
    assert gains.tolist() == [pytest.approx(1.0, abs=1e-12)]
    # Views of one ray each: all occupied scores AF(1; 0.2) + AF(0; 0.8) = 0; all occplane
    # AF(0; 0.2) + AF(1; 0.8) = 0; nothing seen 0: the score asks for a mix.
    assert view_gains(occupancy, rays[:, None], "area_factor").tolist() == [0.0] * 5


def test_frontier_is_every_unknown_neighbour_of_an_occupied_voxel():
    """Against brute force: every voxel's 26 neighbours looked at one by one, on random maps
    with occupied voxels on the grid's faces and corners too."""
    rng = np.random.default_rng(7)
    occupancy = _map(resolution=0.08)  # 14^3 voxels
    n = occupancy.settings.n
    for fraction in (0.0, 0.02, 0.3):
        values = rng.choice([OCCUPIED, FREE, np.nan], size=n**3, p=[fraction, 0.3, 0.7 - fraction])
        values[_flat(occupancy, 0, 0, 0)] = OCCUPIED
        values[_flat(occupancy, n - 1, 5, n - 1)] = OCCUPIED
        occupancy.log_odds[:] = values
        grid = values.reshape(n, n, n)
        expected = np.zeros((n, n, n), dtype=bool)
        for i, j, k in np.ndindex(n, n, n):
            if not np.isnan(grid[i, j, k]):
                continue
            block = grid[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2, max(k - 1, 0) : k + 2]
            expected[i, j, k] = bool((block >= 0).any())
        assert np.array_equal(frontier(occupancy), expected.ravel())
    assert expected.any()
