"""Point sets of simple shapes with known answers, for the tests of the hull planner."""

import numpy as np


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit vectors (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5.0**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def cube_corners(half: float) -> np.ndarray:
    """The 8 corners of the cube ``[-half, half]^3``, (8, 3)."""
    return np.array(
        [[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    )
