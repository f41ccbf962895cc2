"""A depth-sensor noise model applied to rendered depth images (``renderer.noise``).

Structured-light and active-stereo sensors (Kinect, RealSense) are modelled, after Nguyen, Izadi
and Lovell (3DIMPACT 2012, the Kinect's axial noise), as

* **axial noise**: Gaussian along the ray with standard deviation
  ``sigma(z, theta) = a + b (z - z0)^2 + c / sqrt(z) * theta^2 / (pi/2 - theta)^2``, where ``z``
  is the planar depth and ``theta`` the angle between the surface normal and the ray (the third
  term is the paper's angle-dependent part). Nguyen et al. fit ``a = 0.0012``, ``b = 0.0019``,
  ``z0 = 0.4``, ``c = 0.0001`` with depth in metres: the object frame here (radius 0.5, cameras
  at distance 1) is read as metres, a table-top object at a metre;
* **dropout at grazing angles**: a pixel is lost with probability rising linearly from 0 at
  ``dropout_start`` degrees to 1 at 90 degrees; pixels on the silhouette (a neighbour shows
  background) count as grazing, as sensors lose most edge pixels.

The normal comes from the depth image itself (central differences of the back-projected points),
so the model works the same on both render backends. Seeded: one generator per model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv.geometry.camera import Intrinsics, pixel_rays, valid_depth


@dataclass(frozen=True)
class DepthNoise:
    """The parameters of :func:`noisy_depth` (see the module docstring; lengths in world units).

    Attributes:
        a, b, z0: the axial noise's constant and quadratic terms.
        c: the angle-dependent term's scale (0 turns it off).
        dropout_start: incidence angle, degrees, where dropout begins (90 turns dropout off).
        max_angle: incidence angle, degrees, where the angular term is capped (it diverges at 90).
    """

    a: float = 0.0012
    b: float = 0.0019
    z0: float = 0.4
    c: float = 0.0001
    dropout_start: float = 70.0
    max_angle: float = 85.0

    def __post_init__(self) -> None:
        for key in ("a", "b", "c"):
            if not getattr(self, key) >= 0:
                raise ValueError(f"renderer.noise.{key}={getattr(self, key)!r}: must be >= 0")
        if not 0 <= self.dropout_start <= 90:
            raise ValueError(
                f"renderer.noise.dropout_start={self.dropout_start!r}: must be in [0, 90] degrees"
            )
        if not 0 < self.max_angle < 90:
            raise ValueError(
                f"renderer.noise.max_angle={self.max_angle!r}: must be in (0, 90) degrees"
            )


def incidence_angles(depth: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """Angle between each pixel's surface normal and its ray, radians; pi/2 on the silhouette.

    Args:
        depth: (H, W) planar depth, background as in :mod:`nbv.geometry.camera`.
        intrinsics: the camera.

    Returns:
        (H, W) float64 in [0, pi/2]; background pixels get pi/2 too.
    """
    valid = valid_depth(depth)
    rays = pixel_rays(intrinsics)
    points = rays * np.where(valid, depth, 0.0).astype(np.float64)[..., None]
    du = np.zeros_like(points)
    dv = np.zeros_like(points)
    du[:, 1:-1] = points[:, 2:] - points[:, :-2]
    dv[1:-1] = points[2:] - points[:-2]
    normal = np.cross(du, dv)
    norm = np.linalg.norm(normal, axis=-1)
    ray = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    cos = np.abs(np.einsum("hwk,hwk->hw", normal, ray)) / np.maximum(norm, 1e-300)
    angle = np.arccos(np.clip(cos, 0.0, 1.0))
    # A pixel with a background (or image-border) neighbour has no full stencil: silhouette.
    edge = ~valid.copy()
    edge[:, 1:-1] |= ~valid[:, 2:] | ~valid[:, :-2]
    edge[1:-1] |= ~valid[2:] | ~valid[:-2]
    edge[:, [0, -1]] = True
    edge[[0, -1]] = True
    return np.where(edge | (norm == 0), np.pi / 2, angle)


def noisy_depth(
    depth: np.ndarray, intrinsics: Intrinsics, noise: DepthNoise, rng: np.random.Generator
) -> np.ndarray:
    """Depth images as the sensor model would return them.

    Args:
        depth: (V, H, W) planar depth, inf for background.
        intrinsics: the camera.
        noise: the model's parameters.
        rng: the generator of the noise and the dropout.

    Returns:
        (V, H, W) float32: valid pixels moved along their rays (planar depth scaled by the same
        factor as the range), dropped pixels set to inf.
    """
    out = np.array(depth, dtype=np.float32, copy=True)
    for v in range(len(out)):
        valid = valid_depth(out[v])
        theta = incidence_angles(out[v], intrinsics)
        z = out[v][valid].astype(np.float64)
        t = np.minimum(theta[valid], np.radians(noise.max_angle))
        sigma = noise.a + noise.b * (z - noise.z0) ** 2
        sigma = sigma + noise.c / np.sqrt(z) * t**2 / (np.pi / 2 - t) ** 2
        noisy = z + rng.normal(size=z.shape) * sigma
        start = np.radians(noise.dropout_start)
        p_drop = np.clip((theta[valid] - start) / max(np.pi / 2 - start, 1e-12), 0.0, 1.0)
        dropped = rng.random(z.shape) < p_drop
        noisy[dropped | (noisy <= 0)] = np.inf
        image = out[v]
        image[valid] = noisy.astype(np.float32)
    return out
