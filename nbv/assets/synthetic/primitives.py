"""Mesh primitives the synthetic shapes are assembled from.

Boxes, cylinders, frusta, cones, ellipsoids, capsules, tori, annuli and "hexahedra" (boxes whose 8
corners are moved, used for swept wings, hulls and slanted cabins), and the mirroring that makes
parts symmetric about x = 0. Every helper returns a ``trimesh.Trimesh`` (a :data:`Part`) in the
model's own units, before scaling; points and sizes are (x, y, z), angles in radians.

The builders of each family of categories (:mod:`~nbv.assets.synthetic.craft`,
:mod:`~nbv.assets.synthetic.vehicles`, :mod:`~nbv.assets.synthetic.seating`,
:mod:`~nbv.assets.synthetic.furniture`, :mod:`~nbv.assets.synthetic.objects`) take the model's
``numpy.random.Generator`` and return its parts in ShapeNet's frame: Y up, front +z. Units are
roughly metres (airplanes and vessels: length 1); only proportions matter, since every model is
normalised at the end (:func:`nbv.assets.synthetic.catalogue.make_model`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

# Vertex order of trimesh.creation.box: index 4 * ix + 2 * iy + iz, 0 = low side, 1 = high side.
_BOX_FACES = trimesh.creation.box().faces.copy()
_BOX_FACES.setflags(write=False)
_SIGNS = np.array([[ix, iy, iz] for ix in (0, 1) for iy in (0, 1) for iz in (0, 1)], dtype=bool)
_SIGNS.setflags(write=False)

Part = trimesh.Trimesh


def rot(axis: str, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` radians about the x, y or z axis (right-handed)."""
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    if axis == "y":
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def pose(rotation: np.ndarray | None, center: Sequence[float]) -> np.ndarray:
    m = np.eye(4)
    if rotation is not None:
        m[:3, :3] = rotation
    m[:3, 3] = center
    return m


def _z_to(direction: np.ndarray) -> np.ndarray:
    """3x3 rotation taking +z to the unit vector along ``direction``."""
    return trimesh.geometry.align_vectors([0.0, 0.0, 1.0], np.asarray(direction, float))[:3, :3]


def box(size: Sequence[float], center: Sequence[float], rotation: np.ndarray | None = None) -> Part:
    """Box of edge lengths ``size`` (x, y, z) centred at ``center``, optionally rotated."""
    return trimesh.creation.box(extents=size, transform=pose(rotation, center))


def span(lo: Sequence[float], hi: Sequence[float]) -> Part:
    """Axis-aligned box between corners ``lo`` and ``hi``."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return box(np.abs(hi - lo), (lo + hi) / 2)


def corners(lo: Sequence[float], hi: Sequence[float]) -> np.ndarray:
    """The 8 corners (8, 3) of an axis-aligned box in trimesh's box vertex order."""
    return np.where(_SIGNS, np.asarray(hi, float), np.asarray(lo, float))


def hexa(corners: np.ndarray) -> Part:
    """A box whose 8 corners, in trimesh's box order, have been moved; faces flip when the
    corners are mirrored so that normals keep pointing outwards."""
    c = np.asarray(corners, float)
    faces = _BOX_FACES
    if np.linalg.det(np.stack([c[4] - c[0], c[2] - c[0], c[1] - c[0]])) < 0:
        faces = faces[:, ::-1]
    return trimesh.Trimesh(vertices=c, faces=np.array(faces), process=False)


def slab(
    root_le: Sequence[float],
    root_chord: float,
    tip_le: Sequence[float],
    tip_chord: float,
    thickness: tuple[float, float],
    chord_dir: Sequence[float] = (0.0, 0.0, 1.0),
    thick_dir: Sequence[float] = (0.0, 1.0, 0.0),
) -> Part:
    """A tapered, swept plate (wing, fin, sail): leading edges at ``root_le`` and ``tip_le``,
    chords running backwards from them against ``chord_dir``, thicknesses (root, tip) along
    ``thick_dir``."""
    chord_dir, thick_dir = np.asarray(chord_dir, float), np.asarray(thick_dir, float)
    c = np.empty((8, 3))
    for ix, (le, chord, th) in enumerate(
        ((root_le, root_chord, thickness[0]), (tip_le, tip_chord, thickness[1]))
    ):
        for iy, side in enumerate((-0.5, 0.5)):
            for iz, back in enumerate((1.0, 0.0)):
                c[4 * ix + 2 * iy + iz] = (
                    np.asarray(le, float) - back * chord * chord_dir + side * th * thick_dir
                )
    return hexa(c)


def cyl(radius: float, p0: Sequence[float], p1: Sequence[float], sections: int = 24) -> Part:
    """Closed cylinder of ``radius`` from point ``p0`` to point ``p1``."""
    return trimesh.creation.cylinder(radius=radius, segment=[p0, p1], sections=sections)


def beam(
    p0: Sequence[float], p1: Sequence[float], width: float, depth: float | None = None
) -> Part:
    """Box of cross-section ``width`` x ``depth`` running from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    return box(
        (width, width if depth is None else depth, np.linalg.norm(d)), (p0 + p1) / 2, _z_to(d)
    )


def frustum(
    r0: float, r1: float, p0: Sequence[float], p1: Sequence[float], sections: int = 32
) -> Part:
    """Closed truncated cone: radius ``r0`` at ``p0``, ``r1`` at ``p1``."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    m = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=sections)
    v = m.vertices.copy()
    t = v[:, 2] + 0.5
    v[:, :2] *= (r0 + t * (r1 - r0))[:, None]
    v[:, 2] = t * np.linalg.norm(p1 - p0)
    v = v @ _z_to(p1 - p0).T + p0
    return trimesh.Trimesh(vertices=v, faces=m.faces.copy(), process=False)


def cone(radius: float, base: Sequence[float], apex: Sequence[float], sections: int = 24) -> Part:
    """Closed cone with a base of ``radius`` centred at ``base`` and its tip at ``apex``."""
    base, apex = np.asarray(base, float), np.asarray(apex, float)
    d = apex - base
    return trimesh.creation.cone(
        radius=radius, height=np.linalg.norm(d), sections=sections, transform=pose(_z_to(d), base)
    )


def ellipsoid(center: Sequence[float], radii: Sequence[float], subdivisions: int = 2) -> Part:
    """Ellipsoid with semi-axes ``radii`` (x, y, z) centred at ``center``."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return trimesh.Trimesh(
        vertices=m.vertices * np.asarray(radii, float) + np.asarray(center, float),
        faces=m.faces.copy(),
        process=False,
    )


def capsule(radius: float, p0: Sequence[float], p1: Sequence[float]) -> Part:
    """Capsule of ``radius`` whose axis runs from ``p0`` to ``p1`` (the caps reach beyond)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    return trimesh.creation.capsule(
        height=np.linalg.norm(d),
        radius=radius,
        count=[16, 16],
        transform=pose(_z_to(d), (p0 + p1) / 2),
    )


def torus(major: float, minor: float, center: Sequence[float], axis: Sequence[float]) -> Part:
    """Torus (a tyre) around ``axis`` through ``center``."""
    return trimesh.creation.torus(
        major_radius=major,
        minor_radius=minor,
        major_sections=32,
        minor_sections=10,
        transform=pose(_z_to(axis), center),
    )


def annulus(
    r_in: float, r_out: float, center: Sequence[float], axis: Sequence[float], height: float
) -> Part:
    """Flat ring (washer) of ``height`` around ``axis`` through ``center``."""
    return trimesh.creation.annulus(
        r_min=r_in, r_max=r_out, height=height, sections=32, transform=pose(_z_to(axis), center)
    )


def mirror_x(parts: list[Part]) -> list[Part]:
    """Copies of ``parts`` mirrored through the plane x = 0 (faces flipped by trimesh)."""
    out = []
    for p in parts:
        q = p.copy()
        q.apply_transform(np.diag([-1.0, 1.0, 1.0, 1.0]))
        out.append(q)
    return out


def symmetric(parts: list[Part]) -> list[Part]:
    """``parts`` and their mirror images through x = 0."""
    return parts + mirror_x(parts)
