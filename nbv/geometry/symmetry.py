"""Exact symmetries of a viewspace, and what they do to a training sample.

A symmetry is an orthogonal map ``M`` (a rotation or a reflection about the object's centre) that
takes the set of camera positions onto itself: ``M @ p_i = p_perm[i]`` for every view ``i``. Seen
through it, a scene ``S`` viewed from ``p_i`` is the scene ``M S`` viewed from ``p_perm[i]``, so a
sample of ``S`` (its cloud, visited views and per-view gains) gives an exact sample of ``M S``:
the cloud mapped by ``M`` and every per-view array permuted by ``perm``. PC-NBV's original 33 views
(a pole and four rings of 8 about the up axis) have 16: the 8 rotations about the up axis by
multiples of 45 degrees and their 8 mirror images.

Symmetries are found numerically: two non-parallel reference positions ``a``, ``b`` fix an
orthogonal map by their images ``a'``, ``b'`` (and the sign of ``a' x b'``, which separates
rotations from reflections), so every pair of positions with the same lengths and angle as
``(a, b)`` is a candidate, kept when it maps the whole set onto itself within ``tol``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from nbv.geometry.sph import equiangular_directions, real_sph_harm_dirs, unit_vectors


@dataclass(frozen=True)
class Symmetry:
    """One symmetry of a viewspace.

    Attributes:
        matrix: (3, 3) float64 orthogonal, ``det = +1`` (rotation) or ``-1`` (reflection).
        permutation: (V,) int64; ``matrix @ p_i = p_permutation[i]``.
    """

    matrix: np.ndarray
    permutation: np.ndarray

    @property
    def is_identity(self) -> bool:
        """True for the identity map."""
        return bool(np.allclose(self.matrix, np.eye(3), atol=1e-9))


def viewspace_symmetries(positions: np.ndarray, tol: float = 1e-6) -> list[Symmetry]:
    """Every orthogonal map that takes a viewspace's camera positions onto themselves.

    Args:
        positions: (V, 3) camera positions about the object's centre, world units, V >= 2 and
            not all on one line through the centre.
        tol: largest distance, world units, between a mapped position and the position it lands
            on.

    Returns:
        The symmetries, the identity first, then in a fixed order (by permutation, rotations
        before reflections); a viewspace without symmetry gives ``[identity]``. A flat
        viewspace also has the mirror in its plane, which moves no camera.

    Raises:
        ValueError: fewer than 2 positions, non-finite values, or all positions on one line
            through the centre (the map about that line is then not fixed by the set).
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2 or not np.isfinite(p).all():
        raise ValueError(f"positions: must be a finite (V, 3) array with V >= 2, got {p.shape}")
    a = int(np.argmax(np.linalg.norm(p, axis=1)))
    cross = np.linalg.norm(np.cross(p[a], p), axis=1)
    b = int(np.argmax(cross))
    if cross[b] <= tol * max(1.0, float(np.linalg.norm(p[a]))):
        raise ValueError("positions: all on one line through the centre; symmetries not fixed")
    norms = np.linalg.norm(p, axis=1)
    frame = np.column_stack([p[a], p[b], np.cross(p[a], p[b])])
    inverse = np.linalg.inv(frame)
    tree = cKDTree(p)
    found: dict[bytes, Symmetry] = {}
    for a2 in np.flatnonzero(np.abs(norms - norms[a]) <= tol):
        for b2 in np.flatnonzero(np.abs(norms - norms[b]) <= tol):
            if abs(p[a2] @ p[b2] - p[a] @ p[b]) > tol or a2 == b2:
                continue
            for sign in (1.0, -1.0):
                image = np.column_stack([p[a2], p[b2], sign * np.cross(p[a2], p[b2])])
                matrix = image @ inverse
                if not np.allclose(matrix.T @ matrix, np.eye(3), atol=max(tol, 1e-9) * 10):
                    continue
                distance, perm = tree.query(p @ matrix.T)
                if distance.max() <= tol and len(set(perm.tolist())) == len(p):
                    # Keyed by the map, not the permutation: the mirror in the plane of a flat
                    # viewspace fixes every camera but not the object.
                    key = np.round(matrix, 6).tobytes()
                    found.setdefault(key, Symmetry(matrix, perm.astype(np.int64)))
    ordered = sorted(
        found.values(),
        key=lambda s: (not s.is_identity, s.permutation.tolist(), np.linalg.det(s.matrix) < 0),
    )
    return ordered


def permute_views(values: np.ndarray, symmetry: Symmetry) -> np.ndarray:
    """Per-view values of a scene -> those of the mapped scene: ``out[..., perm[i]] =
    values[..., i]`` on the last axis, ``(..., V)`` in and out, any dtype."""
    out = np.empty_like(values)
    out[..., symmetry.permutation] = values
    return out


def signature_map(matrix: np.ndarray, lmax: int) -> np.ndarray:
    """The linear map of a signature's radii under an orthogonal ``matrix``: ``(G, G)`` float64
    with ``G = 4 (lmax + 1)^2``.

    A signature (:func:`nbv.geometry.sph.signature`) is ``r(d_k) d_k`` on the fixed grid ``d_k``
    with ``r`` in the span of the harmonics up to ``lmax``, a space that orthogonal maps keep.
    The mapped cloud's radius function is ``r(M^T d)``, so its radii on the grid are this matrix
    times the old radii (the least-squares fit through the grid is exact for such ``r``).
    """
    directions = unit_vectors(*equiangular_directions(lmax))
    basis = real_sph_harm_dirs(lmax, directions)
    return real_sph_harm_dirs(lmax, directions @ np.asarray(matrix)) @ np.linalg.pinv(basis)


def map_signature(signature: np.ndarray, radii_map: np.ndarray, lmax: int) -> np.ndarray:
    """The signature of the mapped cloud from the signature of the cloud: ``(..., G, 3)`` in and
    out, float32 (``radii_map`` from :func:`signature_map`)."""
    directions = unit_vectors(*equiangular_directions(lmax))
    radii = np.einsum("...kc,kc->...k", signature.astype(np.float64), directions)
    mapped = np.einsum("jk,...k->...j", radii_map, radii)
    return (mapped[..., None] * directions).astype(np.float32)
