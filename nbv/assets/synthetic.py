"""Procedural stand-ins for ShapeNet: 16 categories of meshes assembled from primitives.

Nobody can download ShapeNet here, so the default dataset is made on the fly. Each category
imitates one of PC-NBV's 8 training or 8 unseen ShapeNet categories. A model is a concatenation of
trimesh primitives (boxes, cylinders, frusta, cones, ellipsoids, capsules, tori, annuli and
"hexahedra": boxes whose 8 corners are moved, used for swept wings, hulls and slanted cabins), with
randomised proportions and optional or variable parts, so that shapes within a category differ and
categories differ in their structure (legs, gaps, shelves, wheels, wings). Overlapping parts are
simply concatenated: no booleans, so surfaces hidden inside other parts exist, as in ShapeNet.

Frame (ShapeNet's OBJ frame): Y is up, the object's front faces +z (cars, airplanes, vessels,
buses, motorbikes, skateboards and pistols are long along z and point to +z; chairs, sofas, beds,
cabinets and bookshelves face +z; guitars stand upright, neck along +y, strings facing +z). Like
ShapeNetCore v2's ``model_normalized.obj`` every model is centred on its bounding-box centre and
scaled so that the bounding-box diagonal is 1, so it fits in a sphere of radius 0.5.

* :func:`make_model` builds one model of a category from a ``numpy.random.Generator``.
* :func:`catalogue` lists the models of the default dataset (:data:`DEFAULT_COUNTS`);
  :func:`build` makes one of them from a seed, independently of every other model.
* :func:`preview` draws a contact sheet (``python -m nbv.synthetic --preview out.png``).
"""

from __future__ import annotations

import argparse
import time
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from nbv.assets.categories import CATEGORIES, TRAIN_CATEGORIES

#: Models per category of the default dataset: per split for the training categories, and
#: ``unseen`` (all in split "test") for the unseen ones; 8 * 6 + 8 * 2 = 64 models.
DEFAULT_COUNTS: dict[str, int] = {"train": 4, "valid": 1, "test": 1, "unseen": 2}
#: Splits of the catalogue.
SPLITS: tuple[str, ...] = ("train", "valid", "test")

# Vertex order of trimesh.creation.box: index 4 * ix + 2 * iy + iz, 0 = low side, 1 = high side.
_BOX_FACES = trimesh.creation.box().faces.copy()
_BOX_FACES.setflags(write=False)
_SIGNS = np.array([[ix, iy, iz] for ix in (0, 1) for iy in (0, 1) for iz in (0, 1)], dtype=bool)
_SIGNS.setflags(write=False)

Part = trimesh.Trimesh


# --------------------------------------------------------------------------------------------
# Primitives. Every helper returns a trimesh.Trimesh in the model's own units (before scaling).
# --------------------------------------------------------------------------------------------


def _rot(axis: str, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` radians about the x, y or z axis (right-handed)."""
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    if axis == "y":
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _pose(rotation: np.ndarray | None, center: Sequence[float]) -> np.ndarray:
    m = np.eye(4)
    if rotation is not None:
        m[:3, :3] = rotation
    m[:3, 3] = center
    return m


def _z_to(direction: np.ndarray) -> np.ndarray:
    """3x3 rotation taking +z to the unit vector along ``direction``."""
    return trimesh.geometry.align_vectors([0.0, 0.0, 1.0], np.asarray(direction, float))[:3, :3]


def _box(
    size: Sequence[float], center: Sequence[float], rotation: np.ndarray | None = None
) -> Part:
    """Box of edge lengths ``size`` (x, y, z) centred at ``center``, optionally rotated."""
    return trimesh.creation.box(extents=size, transform=_pose(rotation, center))


def _span(lo: Sequence[float], hi: Sequence[float]) -> Part:
    """Axis-aligned box between corners ``lo`` and ``hi``."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return _box(np.abs(hi - lo), (lo + hi) / 2)


def _corners(lo: Sequence[float], hi: Sequence[float]) -> np.ndarray:
    """The 8 corners (8, 3) of an axis-aligned box in trimesh's box vertex order."""
    return np.where(_SIGNS, np.asarray(hi, float), np.asarray(lo, float))


def _hexa(corners: np.ndarray) -> Part:
    """A box whose 8 corners, in trimesh's box order, have been moved; faces flip when the
    corners are mirrored so that normals keep pointing outwards."""
    c = np.asarray(corners, float)
    faces = _BOX_FACES
    if np.linalg.det(np.stack([c[4] - c[0], c[2] - c[0], c[1] - c[0]])) < 0:
        faces = faces[:, ::-1]
    return trimesh.Trimesh(vertices=c, faces=np.array(faces), process=False)


def _slab(
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
    return _hexa(c)


def _cyl(radius: float, p0: Sequence[float], p1: Sequence[float], sections: int = 24) -> Part:
    """Closed cylinder of ``radius`` from point ``p0`` to point ``p1``."""
    return trimesh.creation.cylinder(radius=radius, segment=[p0, p1], sections=sections)


def _beam(
    p0: Sequence[float], p1: Sequence[float], width: float, depth: float | None = None
) -> Part:
    """Box of cross-section ``width`` x ``depth`` running from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    return _box(
        (width, width if depth is None else depth, np.linalg.norm(d)), (p0 + p1) / 2, _z_to(d)
    )


def _frustum(
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


def _cone(radius: float, base: Sequence[float], apex: Sequence[float], sections: int = 24) -> Part:
    """Closed cone with a base of ``radius`` centred at ``base`` and its tip at ``apex``."""
    base, apex = np.asarray(base, float), np.asarray(apex, float)
    d = apex - base
    return trimesh.creation.cone(
        radius=radius, height=np.linalg.norm(d), sections=sections, transform=_pose(_z_to(d), base)
    )


def _ellipsoid(center: Sequence[float], radii: Sequence[float], subdivisions: int = 2) -> Part:
    """Ellipsoid with semi-axes ``radii`` (x, y, z) centred at ``center``."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return trimesh.Trimesh(
        vertices=m.vertices * np.asarray(radii, float) + np.asarray(center, float),
        faces=m.faces.copy(),
        process=False,
    )


def _capsule(radius: float, p0: Sequence[float], p1: Sequence[float]) -> Part:
    """Capsule of ``radius`` whose axis runs from ``p0`` to ``p1`` (the caps reach beyond)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    return trimesh.creation.capsule(
        height=np.linalg.norm(d),
        radius=radius,
        count=[16, 16],
        transform=_pose(_z_to(d), (p0 + p1) / 2),
    )


def _torus(major: float, minor: float, center: Sequence[float], axis: Sequence[float]) -> Part:
    """Torus (a tyre) around ``axis`` through ``center``."""
    return trimesh.creation.torus(
        major_radius=major,
        minor_radius=minor,
        major_sections=32,
        minor_sections=10,
        transform=_pose(_z_to(axis), center),
    )


def _annulus(
    r_in: float, r_out: float, center: Sequence[float], axis: Sequence[float], height: float
) -> Part:
    """Flat ring (washer) of ``height`` around ``axis`` through ``center``."""
    return trimesh.creation.annulus(
        r_min=r_in, r_max=r_out, height=height, sections=32, transform=_pose(_z_to(axis), center)
    )


def _mirror_x(parts: list[Part]) -> list[Part]:
    """Copies of ``parts`` mirrored through the plane x = 0 (faces flipped by trimesh)."""
    out = []
    for p in parts:
        q = p.copy()
        q.apply_transform(np.diag([-1.0, 1.0, 1.0, 1.0]))
        out.append(q)
    return out


def _symmetric(parts: list[Part]) -> list[Part]:
    """``parts`` and their mirror images through x = 0."""
    return parts + _mirror_x(parts)


# --------------------------------------------------------------------------------------------
# Categories. Units are roughly metres (airplanes and vessels: length 1); only proportions
# matter, since every model is normalised at the end.
# --------------------------------------------------------------------------------------------


def _airplane(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    kind = rng.choice(3, p=[0.5, 0.25, 0.25])  # airliner, fighter, light aircraft
    r = (u(0.04, 0.065), u(0.035, 0.05), u(0.04, 0.06))[kind]
    z_tail, z_nose = -0.5 + u(0.18, 0.26), 0.5 - u(0.15, 0.22)
    parts = [_cyl(r, (0, 0, z_tail), (0, 0, z_nose), 24)]
    if kind == 1:
        parts.append(_cone(r, (0, 0, z_nose), (0, -0.2 * r, 0.5), 24))
    else:
        parts.append(_ellipsoid((0, 0, z_nose), (r, r, 0.5 - z_nose)))
    tail_lift = r * u(0.2, 0.7)
    parts.append(_frustum(r, r * u(0.25, 0.45), (0, 0, z_tail), (0, tail_lift, -0.5), 24))

    if kind == 0:
        b, cr, taper = u(0.38, 0.55), u(0.16, 0.24), u(0.25, 0.45)
        sweep, dihedral, y_w, zc = u(15, 35), u(2, 7), -0.5 * r, u(-0.02, 0.08)
    elif kind == 1:
        b, cr, taper = u(0.2, 0.3), u(0.35, 0.5), u(0.05, 0.2)
        sweep, dihedral, y_w, zc = u(40, 60), u(-5, 0), 0.0, u(-0.2, -0.1)
    else:
        b, cr, taper = u(0.45, 0.6), u(0.11, 0.16), u(0.6, 1.0)
        sweep, dihedral, y_w, zc = u(0, 5), u(1, 4), 0.9 * r, u(0.05, 0.15)
    tan_s, tan_d = np.tan(np.deg2rad(sweep)), np.tan(np.deg2rad(dihedral))
    th = 0.1 * min(cr, 0.25)
    wing = _slab(
        (0, y_w, zc + cr / 2),
        cr,
        (b, y_w + b * tan_d, zc + cr / 2 - b * tan_s),
        cr * taper,
        (th, th * max(taper, 0.3)),
    )
    half = [wing]

    if kind == 0:  # engines under the wings
        n_pairs = rng.choice(3, p=[0.15, 0.65, 0.2])
        re, le = u(0.022, 0.035), u(0.1, 0.16)
        for f in (u(0.3, 0.4),) if n_pairs == 1 else (0.28, 0.6)[:n_pairs]:
            x = f * b
            z_le = zc + cr / 2 - x * tan_s
            y = y_w + x * tan_d - re - 0.01
            half.append(_cyl(re, (x, y, z_le - 0.5 * le), (x, y, z_le + 0.5 * le), 20))
            half.append(_span((x - 0.004, y, z_le - 0.4 * le), (x + 0.004, y + re + 0.012, z_le)))
    elif kind == 2:
        if rng.random() < 0.6:  # wing struts
            half.append(_cyl(0.006, (r * 0.8, -0.7 * r, zc), (0.45 * b, y_w, zc), 8))
        parts.append(_cone(0.35 * r, (0, 0, 0.5), (0, 0, 0.5 + 0.5 * r), 12))
        blade = u(0.08, 0.12)
        for k in range(rng.choice([2, 3])):
            rot = _rot("z", k * 2 * np.pi / 3 + u(0, 1))
            parts.append(_box((0.014, blade, 0.006), (0, 0, 0.5 + 0.2 * r), rot))
            parts[-1].apply_translation(rot @ np.array([0, blade / 2, 0]))

    # Vertical fin(s); fighters may have two, canted.
    hf, crf = u(0.1, 0.18), u(0.12, 0.2)
    tan_f = np.tan(np.deg2rad(u(30, 50)))
    tip_f = crf * u(0.35, 0.6)
    z_le_f = -0.5 + crf + 0.01
    twin = kind == 1 and rng.random() < 0.5
    xf, cant = (0.8 * r, 0.35) if twin else (0.0, 0.0)
    y0f = tail_lift * 0.5 + 0.4 * r
    fin = _slab(
        (xf, y0f, z_le_f),
        crf,
        (xf + hf * np.sin(cant), y0f + hf * np.cos(cant), z_le_f - hf * tan_f),
        tip_f,
        (0.012, 0.008),
        thick_dir=(1, 0, 0),
    )
    parts.extend([fin] + (_mirror_x([fin]) if twin else []))

    # Horizontal tail, at the fuselage or on top of the fin (T-tail).
    t_tail = kind != 1 and not twin and rng.random() < 0.25
    bt, crt = u(0.12, 0.2), u(0.07, 0.12)
    if t_tail:
        y_t, z_le_t = y0f + hf - 0.005, z_le_f - hf * tan_f + 0.005
        crt = min(crt, tip_f * 1.3)
    else:
        y_t, z_le_t = tail_lift * 0.6, -0.5 + crt + u(0.0, 0.05)
    tan_t = np.tan(np.deg2rad(u(20, 40) if kind != 2 else u(0, 10)))
    half.append(
        _slab((0, y_t, z_le_t), crt, (bt, y_t, z_le_t - bt * tan_t), crt * 0.5, (0.012, 0.008))
    )
    return parts + _symmetric(half)


def _wheel_pair(radius: float, width: float, x_out: float, y: float, z: float) -> list[Part]:
    """Two wheels (tyre + hub) on an axle along x at height ``y`` and position ``z``."""
    tyre = _cyl(radius, (x_out - width, y, z), (x_out, y, z), 32)
    hub = _cyl(0.55 * radius, (x_out - width, y, z), (x_out + 0.01 * radius, y, z), 16)
    return _symmetric([tyre, hub])


def _car(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    kind = rng.choice(5, p=[0.3, 0.2, 0.2, 0.15, 0.15])  # sedan, hatch, suv, pickup, sports
    length, width = u(3.8, 4.9), u(1.7, 1.95)
    rw = u(0.36, 0.42) if kind in (2, 3) else u(0.3, 0.36)
    clear = rw * (u(0.6, 0.8) if kind in (2, 3) else u(0.35, 0.55))
    hb = u(0.35, 0.45) if kind == 4 else u(0.45, 0.65)
    y1 = clear + hb
    c = _corners((-width / 2, clear, -length / 2), (width / 2, y1, length / 2))
    c[[3, 7], 1] -= u(0.0, 0.15)  # hood slopes down to the front
    c[[1, 5], 2] -= u(0.05, 0.25)  # front bumper undercut
    parts = [_hexa(c)]

    frac = ((0.45, 0.55), (0.5, 0.6), (0.6, 0.72), (0.28, 0.35), (0.35, 0.45))[kind]
    lc = length * u(*frac)
    if kind in (1, 2):
        zc = -length / 2 + lc / 2 + u(0.05, 0.2)
    elif kind == 3:
        zc = length * u(-0.05, 0.08)
    elif kind == 4:
        zc = length * u(-0.15, -0.05)
    else:
        zc = length * u(-0.08, 0.02)
    hc = (u(0.4, 0.5), u(0.45, 0.55), u(0.5, 0.65), u(0.45, 0.55), u(0.3, 0.38))[kind]
    wind = u(0.35, 0.7) * (1.6 if kind == 4 else 1.0)
    rear = (u(0.35, 0.6), u(0.05, 0.25), u(0.0, 0.15), u(0.0, 0.1), u(0.4, 0.8))[kind]
    wind, rear = min(wind, 0.45 * lc), min(rear, 0.45 * lc)
    top_y = y1 - 0.02 + hc
    cab = _corners((-0.47 * width, y1 - 0.02, zc - lc / 2), (0.47 * width, top_y, zc + lc / 2))
    cab[[2, 3, 6, 7], 0] *= 0.85
    cab[[3, 7], 2] -= wind
    cab[[2, 6], 2] += rear
    parts.append(_hexa(cab))

    if kind == 3:  # pickup bed: an open box behind the cabin
        wall_h, t = u(0.25, 0.35), 0.05
        z0, z1 = -length / 2, zc - lc / 2 - 0.05
        for s in (-1, 1):
            parts.append(
                _span(
                    (s * width / 2 - t * (s > 0), y1, z0),
                    (s * width / 2 + t * (s < 0), y1 + wall_h, z1),
                )
            )
        parts.append(_span((-width / 2, y1, z0), (width / 2, y1 + wall_h, z0 + t)))
        parts.append(_span((-width / 2, y1, z1 - t), (width / 2, y1 + wall_h, z1)))
    if kind in (0, 4) and rng.random() < 0.4:  # rear spoiler on two posts
        zs = -length / 2 + 0.15
        h = u(0.08, 0.18)
        parts.append(
            _span((-0.45 * width, y1 + h, zs - 0.12), (0.45 * width, y1 + h + 0.03, zs + 0.12))
        )
        parts.extend(
            _symmetric(
                [_span((0.3 * width, y1 - 0.02, zs - 0.03), (0.33 * width, y1 + h, zs + 0.03))]
            )
        )
    if rng.random() < 0.7:  # mirrors
        zm = zc + lc / 2 - wind * 0.7
        parts.extend(
            _symmetric(
                [
                    _span(
                        (0.47 * width, y1 + 0.05, zm - 0.06),
                        (0.47 * width + 0.14, y1 + 0.16, zm + 0.04),
                    )
                ]
            )
        )

    ww = u(0.18, 0.26)
    for z in (length / 2 - u(0.65, 0.95), -length / 2 + u(0.6, 0.95)):
        parts.extend(_wheel_pair(rw, ww, width / 2 + 0.02, rw, z))
    return parts


def _bus(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    length, width = u(9.0, 13.0), u(2.4, 2.6)
    clear, rw = u(0.3, 0.45), u(0.45, 0.55)
    decker = rng.random() < 0.3
    height = u(4.1, 4.4) if decker else u(2.8, 3.3)
    c = _corners((-width / 2, clear, -length / 2), (width / 2, height, length / 2))
    c[[3, 7], 2] -= u(0.0, 0.35)  # raked windscreen
    c[[2, 3, 6, 7], 0] *= u(0.97, 1.0)  # roof slightly narrower
    parts = [_hexa(c)]

    # Window bands: dark panes standing a little proud of both sides.
    wh = u(0.8, 1.1)
    rows = [height - 0.3 - wh] + ([height / 2 - 0.2 - wh * 0.9] if decker else [])
    pitch = u(1.1, 1.5)
    z_front = length / 2 - u(1.1, 1.6)
    n = int((z_front + length / 2 - 0.4) / pitch)
    for y0 in rows:
        for k in range(n):
            z0 = -length / 2 + 0.3 + k * pitch
            parts.extend(
                _symmetric(
                    [
                        _span(
                            (width / 2 - 0.02, y0, z0),
                            (width / 2 + 0.03, y0 + wh, z0 + 0.88 * pitch),
                        )
                    ]
                )
            )
    # Door on the right side, windscreen and rear window.
    parts.append(
        _span(
            (width / 2 - 0.02, clear + 0.2, z_front + 0.1),
            (width / 2 + 0.04, height - 0.3, z_front + 1.0),
        )
    )
    rake = c[1, 2] - c[3, 2]
    ws = _corners((-0.44 * width, 1.1, -0.02), (0.44 * width, height - 0.25, 0.03))
    ws[:, 2] += length / 2 - rake * (ws[:, 1] - clear) / (height - clear)  # follow the raked front
    parts.append(_hexa(ws))
    parts.append(
        _span(
            (-0.4 * width, height - 0.3 - wh, -length / 2 - 0.03),
            (0.4 * width, height - 0.4, -length / 2 + 0.02),
        )
    )
    parts.append(
        _span(
            (-width / 2 - 0.03, clear - 0.05, length / 2 - 0.1),
            (width / 2 + 0.03, clear + 0.35, length / 2 + 0.12),
        )
    )
    if rng.random() < 0.5:  # roof air conditioner
        la = u(1.5, 3.0)
        za = u(-length / 4, length / 4)
        parts.append(
            _span(
                (-0.35 * width, height - 0.05, za - la / 2),
                (0.35 * width, height + u(0.2, 0.35), za + la / 2),
            )
        )

    ww = 0.3
    axles = [length / 2 - u(2.0, 2.6), -length / 2 + u(2.2, 3.2)]
    if length > 11.5 and rng.random() < 0.6:
        axles.append(axles[1] + 1.3)
    for z in axles:
        parts.extend(_wheel_pair(rw, ww, width / 2 + 0.01, rw, z))
    return parts


def _chair(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    w, d, sh, st = u(0.4, 0.56), u(0.4, 0.55), u(0.38, 0.5), u(0.03, 0.08)
    parts = [_span((-w / 2, sh - st, -d / 2), (w / 2, sh, d / 2))]

    # Back, built upright at the rear edge of the seat and tilted backwards.
    bh, bt, tilt = u(0.3, 0.6), u(0.02, 0.06), u(0.0, 0.3)
    style = rng.choice(3, p=[0.45, 0.35, 0.2])
    back: list[Part] = []
    if style == 0:
        back.append(_span((-w / 2, 0, -bt / 2), (w / 2, bh, bt / 2)))
    else:
        pw = u(0.025, 0.045)
        rail = u(0.05, 0.12)
        back.extend(_symmetric([_span((w / 2 - pw, 0, -bt / 2), (w / 2, bh, bt / 2))]))
        back.append(_span((-w / 2, bh - rail, -bt / 2), (w / 2, bh, bt / 2)))
        k = rng.integers(2, 6)
        if style == 1:  # vertical spindles
            for x in np.linspace(-w / 2 + pw, w / 2 - pw, k + 2)[1:-1]:
                back.append(_span((x - 0.012, 0, -bt / 4), (x + 0.012, bh - rail, bt / 4)))
        else:  # horizontal bars
            for y in np.linspace(0.05, bh - rail, k + 1)[:-1]:
                back.append(_span((-w / 2 + pw, y, -bt / 3), (w / 2 - pw, y + 0.035, bt / 3)))
    for p in back:
        p.apply_transform(_pose(_rot("x", -tilt), (0, sh, -d / 2 + bt / 2)))
    parts.extend(back)

    legs = rng.choice(3, p=[0.6, 0.25, 0.15])  # four legs, pedestal, sled
    y_under = sh - st
    if legs == 0:
        lt, ins, splay = u(0.025, 0.05), u(0.0, 0.03), u(0.0, 0.05)
        rnd = rng.random() < 0.4
        xs, zs = w / 2 - ins - lt / 2, d / 2 - ins - lt / 2
        for sx in (-1, 1):
            for sz in (-1, 1):
                top = (sx * xs, y_under, sz * zs)
                foot = (sx * (xs + splay), 0.0, sz * (zs + splay))
                parts.append(_cyl(lt / 2, foot, top, 16) if rnd else _beam(foot, top, lt))
        if rng.random() < 0.4:  # stretchers
            ys = u(0.08, 0.2)
            parts.extend(_symmetric([_span((xs - 0.01, ys, -zs), (xs + 0.01, ys + 0.02, zs))]))
            parts.append(_span((-xs, ys, -0.01), (xs, ys + 0.02, 0.01)))
    elif legs == 1:
        col_r, y_star = u(0.02, 0.035), u(0.05, 0.08)
        parts.append(_cyl(col_r, (0, y_star, 0), (0, y_under, 0), 24))
        parts.append(_span((-0.12, y_under - 0.03, -0.12), (0.12, y_under, 0.12)))
        arm = u(0.25, 0.33)
        casters = rng.random() < 0.7
        for k in range(5):
            a = k * 2 * np.pi / 5 + np.pi / 2
            tip = (arm * np.cos(a), y_star - 0.03, arm * np.sin(a))
            parts.append(_beam((0, y_star, 0), tip, 0.035))
            if casters:
                parts.append(_ellipsoid((tip[0], 0.025, tip[2]), (0.025, 0.025, 0.025), 1))
    else:
        r_tube = u(0.01, 0.016)
        xs = w / 2 - 0.03
        for sx in (-1, 1):
            parts.append(
                _cyl(r_tube, (sx * xs, r_tube, -d / 2), (sx * xs, r_tube, d / 2 + 0.02), 12)
            )
            for sz in (-1, 1):
                parts.append(
                    _cyl(
                        r_tube,
                        (sx * xs, 0, sz * (d / 2 - 0.02)),
                        (sx * xs, y_under, sz * (d / 2 - 0.05)),
                        12,
                    )
                )

    if rng.random() < 0.35:  # armrests
        ya, aw = sh + u(0.18, 0.25), u(0.04, 0.08)
        solid = rng.random() < 0.3
        arm = [_span((w / 2, ya - 0.03, -d / 2), (w / 2 + aw, ya, 0.45 * d))]
        if solid:
            arm.append(_span((w / 2, sh - st, -d / 2), (w / 2 + aw, ya, 0.4 * d)))
        else:
            arm.append(
                _span(
                    (w / 2 + aw / 2 - 0.012, sh - 0.01, 0.35 * d),
                    (w / 2 + aw / 2 + 0.012, ya, 0.35 * d + 0.024),
                )
            )
        parts.extend(_symmetric(arm))
    return parts


def _sofa(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    width, depth = u(1.5, 2.6), u(0.8, 1.0)
    leg_h = u(0.0, 0.12)
    legs = leg_h > 0.04
    y0 = leg_h if legs else 0.0
    base_top = y0 + u(0.2, 0.3)
    arms = rng.random() < 0.85
    arm_w = u(0.1, 0.25) if arms else 0.0
    arm_h = base_top + u(0.15, 0.3)
    back_t, back_h = u(0.15, 0.25), u(0.7, 0.95)
    inner = width / 2 - arm_w

    parts = [_span((-inner, y0, -depth / 2), (inner, base_top, depth / 2))]
    back = _corners((-inner, y0, -depth / 2), (inner, back_h, -depth / 2 + back_t))
    back[[2, 3, 6, 7], 2] -= u(0.0, 0.08)
    parts.append(_hexa(back))
    if arms:
        arm = [_span((inner, y0, -depth / 2), (width / 2, arm_h, depth / 2))]
        if rng.random() < 0.35:  # rolled arm
            arm.append(
                _cyl(
                    arm_w * 0.6,
                    (inner + arm_w / 2, arm_h, -depth / 2),
                    (inner + arm_w / 2, arm_h, depth / 2),
                    24,
                )
            )
        parts.extend(_symmetric(arm))

    n = rng.integers(1, 4)
    ct = u(0.1, 0.18)
    gap = 0.01
    cw = 2 * inner / n
    z_back = -depth / 2 + back_t
    for k in range(n):
        x0 = -inner + k * cw
        parts.append(
            _span(
                (x0 + gap, base_top, z_back + gap), (x0 + cw - gap, base_top + ct, depth / 2 + 0.02)
            )
        )
        if rng.random() < 0.7:
            bc = _corners(
                (x0 + gap, base_top + ct, z_back),
                (x0 + cw - gap, back_h - 0.05, z_back + u(0.12, 0.18)),
            )
            bc[[2, 3, 6, 7], 2] -= 0.06
            parts.append(_hexa(bc))

    if rng.random() < 0.25:  # chaise longue on one side
        s = rng.choice([-1, 1])
        chaise_w, ext = u(0.6, 0.8), u(0.5, 0.8)
        x_out = s * inner
        x_in = x_out - s * chaise_w
        lo, hi = (min(x_in, x_out), y0, depth / 2), (max(x_in, x_out), base_top, depth / 2 + ext)
        parts.append(_span(lo, hi))
        parts.append(_span((lo[0] + gap, base_top, depth / 2), (hi[0] - gap, base_top + ct, hi[2])))
        if legs:
            for x in (lo[0] + 0.05, hi[0] - 0.05):
                parts.append(_cyl(0.025, (x, 0, hi[2] - 0.05), (x, y0, hi[2] - 0.05), 12))

    if legs:
        for sx in (-1, 1):
            for sz in (-1, 1):
                p = (sx * (width / 2 - 0.06), 0.0, sz * (depth / 2 - 0.06))
                parts.append(_frustum(0.018, 0.028, p, (p[0], y0, p[2]), 12))
    return parts


def _table(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    coffee = rng.random() < 0.2
    h = u(0.4, 0.5) if coffee else u(0.7, 0.78)
    round_top = rng.random() < 0.35
    tt = u(0.025, 0.06)
    if round_top:
        r = u(0.35, 0.7)
        parts = [_cyl(r, (0, h - tt, 0), (0, h, 0), 48)]
        wx = wz = r * 0.7
    else:
        w = u(0.9, 2.0)
        d = min(w * u(0.5, 1.0), u(0.55, 1.0))
        parts = [_span((-w / 2, h - tt, -d / 2), (w / 2, h, d / 2))]
        wx, wz = w / 2, d / 2
    y_under = h - tt

    column = rng.random() < (0.6 if round_top else 0.2)
    if column and round_top:
        cr = u(0.03, 0.08)
        parts.append(_cyl(cr, (0, 0.02, 0), (0, y_under, 0), 24))
        if rng.random() < 0.5:
            parts.append(_cyl(u(0.2, 0.32), (0, 0, 0), (0, 0.03, 0), 32))
        else:
            foot = u(0.25, 0.4)
            for k in range(4):
                a = k * np.pi / 2 + np.pi / 4
                parts.append(
                    _beam((0, 0.03, 0), (foot * np.cos(a), 0.015, foot * np.sin(a)), 0.05, 0.03)
                )
    elif column:  # trestle: two end frames joined by a stretcher
        xt = wx - u(0.1, 0.25)
        pw = u(0.04, 0.08)
        for sx in (-1, 1):
            parts.append(_span((sx * xt - pw / 2, 0.06, -0.04), (sx * xt + pw / 2, y_under, 0.04)))
            parts.append(
                _span((sx * xt - pw / 2, 0, -wz * 0.85), (sx * xt + pw / 2, 0.06, wz * 0.85))
            )
            parts.append(
                _span(
                    (sx * xt - pw / 2, y_under - 0.05, -wz * 0.85),
                    (sx * xt + pw / 2, y_under, wz * 0.85),
                )
            )
        parts.append(_span((-xt, 0.25, -0.025), (xt, 0.3, 0.025)))
    else:
        lt, splay = u(0.03, 0.07), u(0.0, 0.04)
        rnd = rng.random() < 0.4
        ins = u(0.02, 0.08)
        if round_top:
            pos = [
                (np.cos(a) * (r - ins - lt), np.sin(a) * (r - ins - lt))
                for a in np.pi / 4 + np.arange(4) * np.pi / 2
            ]
        else:
            pos = [
                (sx * (wx - ins - lt / 2), sz * (wz - ins - lt / 2))
                for sx in (-1, 1)
                for sz in (-1, 1)
            ]
        for x, z in pos:
            s = np.array([x, z]) / np.hypot(x, z)
            foot = (x + splay * s[0], 0.0, z + splay * s[1])
            top = (x, y_under, z)
            parts.append(_cyl(lt / 2, foot, top, 16) if rnd else _beam(foot, top, lt))
        if not round_top and rng.random() < 0.5:  # apron
            ah = u(0.05, 0.1)
            xa, za = pos[3]
            parts.extend(_symmetric([_span((xa - 0.02, y_under - ah, -za), (xa, y_under, za))]))
            parts.append(_span((-xa, y_under - ah, za - 0.02), (xa, y_under, za)))
            parts.append(_span((-xa, y_under - ah, -za), (xa, y_under, -za + 0.02)))
        if not round_top and rng.random() < 0.3:  # lower shelf
            xa, za = pos[3]
            ys = u(0.1, 0.25)
            parts.append(_span((-xa, ys, -za), (xa, ys + 0.025, za)))
    return parts


def _lamp(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    kind = rng.choice(3, p=[0.45, 0.3, 0.25])  # desk, floor, table lamp
    parts: list[Part] = []
    if kind == 0:
        rb, hb = u(0.07, 0.12), u(0.015, 0.04)
        if rng.random() < 0.3:
            parts.append(_span((-rb, 0, -rb), (rb, hb, rb)))
        else:
            parts.append(_cyl(rb, (0, 0, 0), (0, hb, 0), 32))
        ra = u(0.008, 0.015)
        joint = np.array([0.0, hb, -rb * 0.5])
        angles = [u(-0.4, 0.3)] + ([u(0.6, 1.6)] if rng.random() < 0.7 else [])
        for a in angles:
            nxt = joint + u(0.22, 0.38) * np.array([0.0, np.cos(a), np.sin(a)])
            parts.append(_cyl(ra, joint, nxt, 12))
            parts.append(_ellipsoid(nxt, (2 * ra,) * 3, 1))
            joint = nxt
        b = u(0.0, 0.9)
        axis = np.array([0.0, -np.cos(b), np.sin(b)])
        hs = u(0.1, 0.16)
        parts.append(
            _frustum(u(0.02, 0.035), u(0.06, 0.11), joint - 0.02 * axis, joint + hs * axis, 32)
        )
    elif kind == 1:
        rb, hp = u(0.12, 0.2), u(1.3, 1.8)
        rp = u(0.012, 0.02)
        parts.append(_cyl(rb, (0, 0, 0), (0, 0.03, 0), 32))
        style = rng.choice(3, p=[0.45, 0.3, 0.25])  # drum shade, torchiere bowl, arc
        if style == 0:
            parts.append(_cyl(rp, (0, 0, 0), (0, hp, 0), 12))
            hs = u(0.2, 0.3)
            parts.append(
                _frustum(
                    u(0.18, 0.25), u(0.12, 0.18), (0, hp - hs * 0.6, 0), (0, hp + hs * 0.4, 0), 32
                )
            )
        elif style == 1:
            parts.append(_cyl(rp, (0, 0, 0), (0, hp, 0), 12))
            parts.append(
                _frustum(
                    u(0.04, 0.08), u(0.18, 0.28), (0, hp - 0.05, 0), (0, hp + u(0.08, 0.14), 0), 32
                )
            )
        else:
            top = np.array([0.0, hp, -0.1])
            parts.append(_cyl(rp, (0, 0, -0.1), top, 12))
            reach = u(0.4, 0.7)
            end = top + np.array([0.0, u(-0.1, 0.15), reach])
            mid = (top + end) / 2 + np.array([0.0, 0.15, 0.0])
            parts.append(_cyl(rp, top, mid, 12))
            parts.append(_cyl(rp, mid, end, 12))
            parts.append(
                _frustum(0.03, u(0.15, 0.22), end, end - np.array([0.0, u(0.15, 0.22), 0.0]), 32)
            )
    else:
        rv, hv = u(0.06, 0.12), u(0.15, 0.3)
        parts.append(_cyl(rv * 1.1, (0, 0, 0), (0, 0.02, 0), 32))
        if rng.random() < 0.6:
            parts.append(_ellipsoid((0, 0.02 + hv / 2, 0), (rv, hv / 2, rv)))
        else:
            parts.append(_cyl(rv * 0.6, (0, 0, 0), (0, hv, 0), 24))
        y_shade = hv + u(0.05, 0.15)
        parts.append(_cyl(0.01, (0, hv, 0), (0, y_shade + 0.1, 0), 12))
        rs, hs = u(0.14, 0.22), u(0.15, 0.25)
        parts.append(_frustum(rs, rs * u(0.55, 0.9), (0, y_shade, 0), (0, y_shade + hs, 0), 32))
        parts.append(_ellipsoid((0, y_shade + hs + 0.02, 0), (0.015,) * 3, 1))
    return parts


def _vessel(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    kind = rng.choice(3, p=[0.45, 0.3, 0.25])  # ship, sailboat, speedboat
    beam = u(0.14, 0.24) if kind != 2 else u(0.22, 0.32)
    hd = u(0.06, 0.12)
    bow_len = u(0.18, 0.35)
    zb = 0.5 - bow_len
    bf = u(0.4, 0.8)
    stern = _corners((-beam / 2, 0, -0.5), (beam / 2, hd, zb))
    stern[[0, 1, 4, 5], 0] *= bf
    stern[[0, 4], 2] += u(0.0, 0.05)
    bow = stern.copy()
    bow[[0, 2, 4, 6]] = stern[[1, 3, 5, 7]]
    bow[[3, 7], 0] = np.array([-1, 1]) * 0.01 * beam
    bow[[3, 7], 2] = 0.5
    bow[[1, 5], 0] = np.array([-1, 1]) * 0.01 * beam
    bow[[1, 5], 2] = 0.5 - u(0.05, 0.2)
    bow[[1, 5], 1] = hd * u(0.0, 0.4)
    parts = [_hexa(stern), _hexa(bow)]

    if kind == 0:
        zh = u(-0.3, 0.05)
        y = hd
        lz, bw = u(0.15, 0.35), beam * u(0.6, 0.85)
        for _ in range(rng.integers(1, 4)):
            th = u(0.04, 0.07)
            parts.append(_span((-bw / 2, y, zh - lz / 2), (bw / 2, y + th, zh + lz / 2)))
            y += th
            lz *= u(0.6, 0.9)
            bw *= u(0.75, 0.95)
        if rng.random() < 0.7:
            for k in range(rng.integers(1, 3)):
                zf = zh - 0.05 - 0.07 * k
                parts.append(_cyl(u(0.015, 0.03), (0, hd, zf), (0, y + u(0.04, 0.1), zf), 20))
        mast_top = y + u(0.1, 0.25)
        parts.append(_cyl(0.005, (0, y, zh + 0.02), (0, mast_top, zh + 0.02), 8))
        parts.append(
            _span((-0.05, mast_top - 0.04, zh + 0.015), (0.05, mast_top - 0.03, zh + 0.025))
        )
        if rng.random() < 0.35:  # deck cargo
            for k in range(rng.integers(1, 4)):
                z0 = zh + 0.2 + 0.07 * k
                if z0 + 0.05 < zb + 0.05:
                    parts.append(_span((-beam * 0.35, hd, z0), (beam * 0.35, hd + 0.04, z0 + 0.05)))
    elif kind == 1:
        zm = u(0.0, 0.2)
        top = hd + u(0.5, 0.9)
        parts.append(_cyl(0.006, (0, hd, zm), (0, top, zm), 8))
        boom_y = hd + u(0.04, 0.08)
        chord = u(0.25, 0.4)
        parts.append(_cyl(0.005, (0, boom_y, zm), (0, boom_y, zm - chord), 8))
        parts.append(
            _slab(
                (0, boom_y + 0.01, zm - 0.008),
                chord,
                (0, top - 0.03, zm - 0.008),
                0.02,
                (0.004, 0.003),
                thick_dir=(1, 0, 0),
            )
        )
        if rng.random() < 0.6:  # jib from the bow to the mast head
            z_bow = 0.45
            parts.append(
                _slab(
                    (0, hd + 0.02, z_bow),
                    z_bow - zm - 0.03,
                    (0, top - 0.05, zm + 0.03),
                    0.01,
                    (0.004, 0.003),
                    thick_dir=(1, 0, 0),
                )
            )
        zc = zm - u(0.08, 0.15)
        lc = u(0.15, 0.25)
        parts.append(_span((-beam * 0.3, hd, zc - lc), (beam * 0.3, hd + u(0.03, 0.05), zc)))
        if rng.random() < 0.6:  # keel fin
            parts.append(
                _slab(
                    (0, 0.01, zm + 0.05),
                    0.15,
                    (0, -u(0.1, 0.2), zm),
                    0.1,
                    (0.012, 0.01),
                    thick_dir=(1, 0, 0),
                )
            )
    else:
        zc, lc = u(-0.1, 0.1), u(0.2, 0.35)
        hc = u(0.05, 0.09)
        cab = _corners((-beam * 0.4, hd, zc - lc / 2), (beam * 0.4, hd + hc, zc + lc / 2))
        cab[[3, 7], 2] -= lc * u(0.4, 0.7)
        cab[[2, 3, 6, 7], 0] *= 0.85
        parts.append(_hexa(cab))
        if rng.random() < 0.7:  # outboard motor
            parts.append(_span((-0.03, hd * 0.2, -0.55), (0.03, hd + 0.06, -0.49)))
            parts.append(_span((-0.01, -0.05, -0.535), (0.01, hd * 0.2, -0.505)))
    return parts


def _cabinet(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    w, h, d = u(0.4, 1.6), u(0.5, 2.0), u(0.35, 0.6)
    t = u(0.015, 0.03)
    feet = rng.choice(3)  # none, four feet, plinth
    y0 = 0.0 if feet == 0 else u(0.05, 0.15)
    y1 = y0 + h
    parts: list[Part] = []
    if feet == 1:
        for sx in (-1, 1):
            for sz in (-1, 1):
                parts.append(
                    _cyl(
                        0.025,
                        (sx * (w / 2 - 0.05), 0, sz * (d / 2 - 0.05)),
                        (sx * (w / 2 - 0.05), y0, sz * (d / 2 - 0.05)),
                        12,
                    )
                )
    elif feet == 2:
        parts.append(_span((-w / 2 + 0.03, 0, -d / 2 + 0.03), (w / 2 - 0.03, y0, d / 2 - 0.03)))

    nc = int(np.clip(round(w / u(0.4, 0.6)), 1, 4))
    styles = rng.choice(4, size=nc, p=[0.45, 0.3, 0.15, 0.1])  # doors, drawers, mixed, open
    cw = (w - 2 * t) / nc
    front = d / 2
    if not (styles == 3).any():
        parts.append(_span((-w / 2, y0, -d / 2), (w / 2, y1, front)))
    else:  # carcass of panels, with the closed columns filled in
        parts.append(_span((-w / 2, y0, -d / 2), (-w / 2 + t, y1, front)))
        parts.append(_span((w / 2 - t, y0, -d / 2), (w / 2, y1, front)))
        parts.append(_span((-w / 2, y0, -d / 2), (w / 2, y0 + t, front)))
        parts.append(_span((-w / 2, y1 - t, -d / 2), (w / 2, y1, front)))
        parts.append(_span((-w / 2, y0, -d / 2), (w / 2, y1, -d / 2 + t)))
        for k in range(1, nc):
            x = -w / 2 + t + k * cw
            parts.append(_span((x - t / 2, y0, -d / 2), (x + t / 2, y1, front)))
    if rng.random() < 0.4:  # overhanging top
        o = u(0.015, 0.04)
        parts.append(_span((-w / 2 - o, y1, -d / 2), (w / 2 + o, y1 + u(0.02, 0.04), front + o)))

    g, ft = 0.006, 0.018
    handle_bar = rng.random() < 0.5
    inner_h = h - 2 * t

    def fronts(x0: float, x1: float, ya: float, yb: float, hx: float | None) -> list[Part]:
        out = [_span((x0 + g, ya + g, front), (x1 - g, yb - g, front + ft))]
        hx = (x0 + x1) / 2 if hx is None else hx
        hy = yb - min(0.08, (yb - ya) / 3) if hx == (x0 + x1) / 2 else (ya + yb) / 2
        if handle_bar:
            lx, ly = (0.08, 0.015) if hx == (x0 + x1) / 2 else (0.015, 0.1)
            out.append(
                _span(
                    (hx - lx / 2, hy - ly / 2, front + ft),
                    (hx + lx / 2, hy + ly / 2, front + ft + 0.02),
                )
            )
        else:
            out.append(_cyl(0.01, (hx, hy, front + ft), (hx, hy, front + ft + 0.025), 12))
        return out

    for k, style in enumerate(styles):
        x0 = -w / 2 + t + k * cw
        x1 = x0 + cw
        ya, yb = y0 + t, y1 - t
        if style == 3:
            for y in np.linspace(ya, yb, rng.integers(2, 5) + 1)[1:-1]:
                parts.append(_span((x0, y, -d / 2 + t), (x1, y + t, front - 0.01)))
            continue
        if styles.tolist().count(3):
            parts.append(_span((x0, ya, -d / 2 + t), (x1, yb, front)))
        if style == 1 or style == 2:
            n = rng.integers(2, 6) if style == 1 else rng.integers(1, 3)
            dh = inner_h / n if style == 1 else min(0.2, inner_h / 4)
            for j in range(n):
                top = yb - j * dh
                parts.extend(fronts(x0, x1, top - dh, top, None))
            yb = yb - n * dh
        if style in (0, 2) and yb - ya > 0.05:
            if cw > 0.6:
                xm = (x0 + x1) / 2
                parts.extend(fronts(x0, xm, ya, yb, xm - 0.04))
                parts.extend(fronts(xm, x1, ya, yb, xm + 0.04))
            else:
                side = x1 - 0.05 if k % 2 == 0 else x0 + 0.05
                parts.extend(fronts(x0, x1, ya, yb, side))
    return parts


def _bed(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    w, length = u(0.9, 1.9), u(1.9, 2.2)
    legs = rng.random() < 0.6
    leg_h = u(0.05, 0.25) if legs else 0.0
    frame_top = leg_h + u(0.15, 0.3)
    parts = [_span((-w / 2, leg_h, -length / 2), (w / 2, frame_top, length / 2))]
    if legs:
        for sx in (-1, 1):
            for sz in (-1, 1):
                parts.append(
                    _span(
                        (sx * (w / 2 - 0.03) - 0.03, 0, sz * (length / 2 - 0.03) - 0.03),
                        (sx * (w / 2 - 0.03) + 0.03, leg_h, sz * (length / 2 - 0.03) + 0.03),
                    )
                )
    mt = u(0.15, 0.25)
    m_top = frame_top + mt
    parts.append(
        _span(
            (-w / 2 + 0.02, frame_top, -length / 2 + 0.02), (w / 2 - 0.02, m_top, length / 2 - 0.02)
        )
    )

    bt = u(0.04, 0.08)
    z_head = -length / 2 - bt / 2
    ov = u(0.0, 0.06)

    def board(z: float, top: float) -> list[Part]:
        if rng.random() < 0.6:
            return [_span((-w / 2 - ov, 0, z - bt / 2), (w / 2 + ov, top, z + bt / 2))]
        post_r = u(0.025, 0.045)
        out = [
            _cyl(post_r, (s * (w / 2 + ov), 0, z), (s * (w / 2 + ov), top + 0.04, z), 16)
            for s in (-1, 1)
        ]
        out.append(_span((-w / 2 - ov, top - 0.08, z - bt / 3), (w / 2 + ov, top, z + bt / 3)))
        out.append(
            _span((-w / 2 - ov, frame_top, z - bt / 3), (w / 2 + ov, frame_top + 0.06, z + bt / 3))
        )
        for x in np.linspace(-w / 2, w / 2, rng.integers(4, 10) + 2)[1:-1]:
            out.append(_cyl(0.012, (x, frame_top + 0.06, z), (x, top - 0.08, z), 8))
        return out

    head_top = u(0.9, 1.4)
    parts.extend(board(z_head, head_top))
    foot_top = u(0.45, 0.7)
    footboard = rng.random() < 0.45
    if footboard:
        parts.extend(board(length / 2 + bt / 2, foot_top))
    if rng.random() < 0.1:  # four-poster canopy
        top = u(1.8, 2.1)
        zs = (-length / 2 - bt / 2, length / 2 + bt / 2)
        for sx in (-1, 1):
            for z in zs:
                parts.append(
                    _cyl(0.035, (sx * (w / 2 + ov), 0, z), (sx * (w / 2 + ov), top, z), 12)
                )
            parts.append(
                _span(
                    (sx * (w / 2 + ov) - 0.03, top - 0.06, zs[0]),
                    (sx * (w / 2 + ov) + 0.03, top, zs[1]),
                )
            )
        for z in zs:
            parts.append(_span((-w / 2 - ov, top - 0.06, z - 0.03), (w / 2 + ov, top, z + 0.03)))

    n_p = 1 if w < 1.3 else 2
    pw = (w - 0.1) / n_p
    for k in range(n_p):
        xc = -w / 2 + 0.05 + (k + 0.5) * pw
        parts.append(_ellipsoid((xc, m_top + 0.05, -length / 2 + 0.25), (pw * 0.42, 0.07, 0.17)))
    if rng.random() < 0.5:  # blanket over the lower part, hanging over the sides
        zb = length / 2 - 0.01 - (0.02 if footboard else -0.04)
        parts.append(
            _span(
                (-w / 2 - 0.02, frame_top - u(0.0, 0.15), -length / 2 + length * u(0.3, 0.45)),
                (w / 2 + 0.02, m_top + 0.02, zb),
            )
        )
    return parts


def _bookshelf(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    w, h, d = u(0.6, 1.4), u(0.9, 2.0), u(0.25, 0.4)
    t = u(0.018, 0.035)
    plinth = u(0.0, 0.1) if rng.random() < 0.5 else 0.0
    back = rng.random() < 0.7
    parts = [
        _span((-w / 2, 0, -d / 2), (-w / 2 + t, h, d / 2)),
        _span((w / 2 - t, 0, -d / 2), (w / 2, h, d / 2)),
        _span((-w / 2, h - t, -d / 2), (w / 2, h, d / 2)),
        _span((-w / 2, plinth, -d / 2), (w / 2, plinth + t, d / 2)),
    ]
    if plinth > 0:
        parts.append(_span((-w / 2, 0, d / 2 - 0.03), (w / 2, plinth, d / 2 - 0.01)))
    if back:
        parts.append(_span((-w / 2, 0, -d / 2), (w / 2, h, -d / 2 + 0.01)))
    n_shelves = max(2, round((h - plinth) / u(0.28, 0.4)))
    ys = np.linspace(plinth + t, h - t, n_shelves + 1)
    for y in ys[1:-1]:
        parts.append(_span((-w / 2 + t, y - t / 2, -d / 2), (w / 2 - t, y + t / 2, d / 2 - 0.005)))
    columns = 2 if w > 1.0 and rng.random() < 0.6 else 1
    if columns == 2:
        parts.append(_span((-t / 2, plinth, -d / 2), (t / 2, h - t, d / 2)))
    xs = np.linspace(-w / 2 + t, w / 2 - t, columns + 1)

    # Books: runs of upright boxes of random thickness and height on each compartment's floor.
    fill = u(0.2, 0.9)
    for i in range(n_shelves):
        floor = ys[i] + (t / 2 if i > 0 else 0.0)
        ceil = ys[i + 1] - (t / 2 if i + 1 < n_shelves else 0.0)
        for c in range(columns):
            x0, x1 = (
                xs[c] + (t / 2 if c > 0 else 0.0),
                xs[c + 1] - (t / 2 if c + 1 < columns else 0.0),
            )
            x = x0 + u(0.0, 0.2) * (x1 - x0)
            stop = x0 + (x1 - x0) * min(1.0, u(0.5, 1.3) * fill)
            while x < stop:
                bw = u(0.015, 0.05)
                if x + bw > x1:
                    break
                bh = (ceil - floor) * u(0.55, 0.9)
                bd = d * u(0.55, 0.85)
                zf = d / 2 - u(0.01, 0.05)
                parts.append(_span((x, floor, zf - bd), (x + bw, floor + bh, zf)))
                x += bw + (u(0.0, 0.003) if rng.random() < 0.9 else u(0.03, 0.1))
    return parts


def _bench(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    w, d, sh = u(1.1, 2.0), u(0.35, 0.5), u(0.4, 0.48)
    st = u(0.03, 0.06)
    parts: list[Part] = []
    if rng.random() < 0.6:
        n = rng.integers(3, 6)
        sw = d / n
        for k in range(n):
            z0 = -d / 2 + k * sw
            parts.append(_span((-w / 2, sh - st, z0 + 0.006), (w / 2, sh, z0 + sw - 0.006)))
    else:
        parts.append(_span((-w / 2, sh - st, -d / 2), (w / 2, sh, d / 2)))
    y_under = sh - st
    legs = rng.choice(3)  # four legs, two panels, two A-frames
    xl = w / 2 - u(0.05, 0.25)
    lt = u(0.04, 0.07)
    if legs == 0:
        for sx in (-1, 1):
            for sz in (-1, 1):
                parts.append(
                    _span(
                        (sx * xl - lt / 2, 0, sz * (d / 2 - 0.03) - lt / 2),
                        (sx * xl + lt / 2, y_under, sz * (d / 2 - 0.03) + lt / 2),
                    )
                )
        if rng.random() < 0.5:
            parts.append(_span((-xl, 0.12, -0.015), (xl, 0.15, 0.015)))
    elif legs == 1:
        for sx in (-1, 1):
            parts.append(
                _span(
                    (sx * xl - lt / 2, 0, -d / 2 + 0.02), (sx * xl + lt / 2, y_under, d / 2 - 0.02)
                )
            )
    else:
        for sx in (-1, 1):
            for sz in (-1, 1):
                parts.append(
                    _beam((sx * xl, 0, sz * d / 2), (sx * xl, y_under, sz * 0.1 * d), lt, 0.03)
                )
            parts.append(
                _span((sx * xl - 0.02, y_under - 0.05, -d / 2), (sx * xl + 0.02, y_under, d / 2))
            )

    if rng.random() < 0.5:  # backrest on posts rising from the rear
        tilt = u(0.05, 0.3)
        bh = u(0.3, 0.45)
        back: list[Part] = [
            _span((sx * xl - 0.025, -0.05, -0.02), (sx * xl + 0.025, bh, 0.02)) for sx in (-1, 1)
        ]
        for y in np.linspace(0.06, bh - 0.06, rng.integers(2, 4)):
            back.append(_span((-w / 2, y - 0.04, 0.02), (w / 2, y + 0.04, 0.045)))
        for p in back:
            p.apply_transform(_pose(_rot("x", -tilt), (0, sh, -d / 2)))
        parts.extend(back)
        if rng.random() < 0.5:  # armrests
            ya = sh + u(0.18, 0.25)
            for sx in (-1, 1):
                parts.append(
                    _span((sx * xl - 0.025, ya - 0.03, -d / 2), (sx * xl + 0.025, ya, d / 2))
                )
                parts.append(
                    _span((sx * xl - 0.015, sh, d / 2 - 0.05), (sx * xl + 0.015, ya, d / 2 - 0.02))
                )
    return parts


def _guitar(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    kind = rng.choice(3, p=[0.5, 0.35, 0.15])  # acoustic, electric, bass
    parts: list[Part] = []
    if kind == 0:
        r1 = u(0.17, 0.21)
        r2 = r1 * u(0.7, 0.85)
        depth = u(0.08, 0.12)
        c1y = r1
        c2y = c1y + (r1 + r2) * u(0.6, 0.75)
        parts.append(_cyl(r1, (0, c1y, -depth / 2), (0, c1y, depth / 2), 40))
        parts.append(_cyl(r2, (0, c2y, -depth / 2), (0, c2y, depth / 2), 40))
        parts.append(_span((-r2 * 0.8, c1y, -depth / 2), (r2 * 0.8, c2y, depth / 2)))
        parts.append(_annulus(0.04, 0.055, (0, c2y - 0.02, depth / 2), (0, 0, 1), 0.006))
        parts.append(_span((-0.06, c1y - 0.06, depth / 2), (0.06, c1y - 0.04, depth / 2 + 0.01)))
        body_top, front = c2y + r2, depth / 2
        neck_len, pegs = u(0.42, 0.5), 3
    else:
        r1 = u(0.14, 0.17)
        depth = u(0.04, 0.05)
        parts.append(_cyl(r1, (0, r1, -depth / 2), (0, r1, depth / 2), 40))
        parts.append(_cyl(r1 * 0.75, (0, r1 * 1.9, -depth / 2), (0, r1 * 1.9, depth / 2), 40))
        for s, lift in ((-1, u(0.1, 0.35)), (1, u(0.4, 0.7))):  # two horns, one longer
            c = (s * r1 * 0.5, r1 * (1.9 + lift), 0.0)
            parts.append(_ellipsoid(c, (0.24 * r1, 0.5 * r1, depth / 2)))
        for k in range(rng.integers(1, 4)):  # pickups
            y = r1 * (1.1 + 0.35 * k)
            parts.append(_span((-0.045, y, depth / 2), (0.045, y + 0.02, depth / 2 + 0.008)))
        parts.append(_span((-0.05, r1 * 0.7, depth / 2), (0.05, r1 * 0.78, depth / 2 + 0.012)))
        body_top, front = r1 * 2.5, depth / 2
        neck_len, pegs = (u(0.42, 0.48), 3) if kind == 1 else (u(0.6, 0.7), 4)
    nw, nt = u(0.045, 0.055), u(0.02, 0.026)
    y0 = body_top - 0.04
    parts.append(_span((-nw / 2, y0, front - nt), (nw / 2, y0 + neck_len, front)))
    hl, hw = u(0.15, 0.2), u(0.07, 0.09)
    head = [_span((-hw / 2, 0, -0.01), (hw / 2, hl, 0.01))]
    rows = np.linspace(0.03, hl - 0.03, pegs)
    one_side = kind != 0 and rng.random() < 0.6
    for y in rows:
        for s in (1,) if one_side else (-1, 1):
            head.append(_cyl(0.006, (s * hw / 2, y, 0), (s * (hw / 2 + 0.025), y, 0), 8))
    tilt = u(0.1, 0.25)
    for p in head:
        p.apply_transform(_pose(_rot("x", -tilt), (0, y0 + neck_len, front - 0.012)))
    return parts + head


def _motorbike(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    wb, rw, tyre = u(1.3, 1.6), u(0.28, 0.34), u(0.05, 0.08)
    zf, zr = wb / 2, -wb / 2
    parts: list[Part] = []
    for z in (zf, zr):
        c = (0.0, rw, z)
        parts.append(_torus(rw - tyre, tyre, c, (1, 0, 0)))
        parts.append(_annulus(0.25 * rw, rw - tyre, c, (1, 0, 0), 0.02))
        parts.append(_cyl(0.05, (-0.07, rw, z), (0.07, rw, z), 16))
    rake = u(0.4, 0.55)
    fork = u(0.6, 0.75)
    head = np.array([0.0, rw + fork * np.cos(rake), zf - fork * np.sin(rake)])
    parts.extend(_symmetric([_cyl(0.022, (0.07, rw, zf), head + (0.07, 0, 0), 12)]))
    parts.append(_cyl(0.035, head - (0, 0.12, -0.05), head + (0, 0.05, -0.02), 12))
    bar_w, bar_up = u(0.3, 0.4), u(0.0, 0.12)
    bar = head + (0, bar_up + 0.04, -0.05)
    parts.append(_cyl(0.012, (-bar_w, bar[1], bar[2] - 0.05), (bar_w, bar[1], bar[2] - 0.05), 12))
    parts.extend(
        _symmetric(
            [
                _cyl(
                    0.018,
                    (bar_w - 0.1, bar[1], bar[2] - 0.05),
                    (bar_w + 0.01, bar[1], bar[2] - 0.05),
                    12,
                )
            ]
        )
    )
    parts.append(_cyl(0.015, head + (0, 0.04, -0.02), bar + (0, 0, -0.05), 8))

    pivot = np.array([0.0, rw + 0.12, zr + u(0.45, 0.55)])
    parts.extend(_symmetric([_cyl(0.02, (0.08, rw, zr), pivot + (0.08, 0, 0), 12)]))
    seat_y = rw + u(0.45, 0.55)
    parts.append(_cyl(0.025, head, pivot, 12))
    parts.append(_cyl(0.025, head - (0, 0.1, 0), (0, rw + 0.1, pivot[2] + 0.15), 12))
    # Engine block, tank and seat.
    ez = (pivot[2] + head[2]) / 2
    parts.append(_span((-0.13, rw - 0.08, ez - 0.2), (0.13, rw + 0.25, ez + 0.18)))
    tank_z = head[2] - u(0.2, 0.28)
    parts.append(_ellipsoid((0, seat_y + 0.05, tank_z), (0.14, 0.1, u(0.18, 0.24))))
    seat_len = u(0.45, 0.6)
    seat = _corners(
        (-0.13, seat_y - 0.06, tank_z - 0.15 - seat_len), (0.13, seat_y + 0.02, tank_z - 0.15)
    )
    seat[[2, 6], 1] += u(0.0, 0.08)  # raised pillion
    parts.append(_hexa(seat))
    parts.append(_span((-0.1, seat_y - 0.15, zr - 0.05), (0.1, seat_y - 0.06, tank_z - 0.15)))
    # Exhausts.
    for s in (1,) if rng.random() < 0.6 else (-1, 1):
        parts.append(
            _cyl(0.035, (s * 0.15, rw - 0.05, ez), (s * 0.18, rw + 0.1, zr + u(0.0, 0.15)), 16)
        )
    if rng.random() < 0.5:  # front fairing
        f = _corners((-0.2, head[1] - 0.25, head[2] - 0.05), (0.2, head[1] + 0.15, head[2] + 0.15))
        f[[2, 3, 6, 7], 0] *= 0.5
        f[[3, 7], 2] -= 0.12
        f[[1, 5], 2] += 0.05
        parts.append(_hexa(f))
    if rng.random() < 0.7:  # mudguard over the front wheel
        parts.append(_beam((0, 2 * rw + 0.03, zf + 0.2), (0, 2 * rw + 0.05, zf - 0.15), 0.1, 0.02))
    return parts


def _skateboard(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    longboard = rng.random() < 0.3
    length = u(1.0, 1.15) if longboard else u(0.75, 0.85)
    w = u(0.2, 0.25) if longboard else u(0.19, 0.23)
    dt = u(0.01, 0.015)
    rwh = u(0.025, 0.035)
    truck = u(0.04, 0.06)
    y_deck = 2 * rwh + truck
    flat = length * (0.8 if longboard else 0.68)
    parts = [_span((-w / 2, y_deck, -flat / 2), (w / 2, y_deck + dt, flat / 2))]
    tail = (length - flat) / 2
    kick = u(0.0, 0.08) if longboard else u(0.2, 0.4)
    for s in (-1, 1):
        p = [_span((-w / 2, 0, 0), (w / 2, dt, tail)), _cyl(w / 2, (0, 0, tail), (0, dt, tail), 32)]
        for q in p:
            q.apply_transform(_pose(_rot("x", -kick), (0, 0, 0)))
            if s < 0:
                q.apply_transform(np.diag([1.0, 1.0, -1.0, 1.0]))
            q.apply_translation((0, y_deck, s * flat / 2))
        parts.extend(p)
    zt = flat / 2 - u(0.04, 0.1)
    ww = u(0.03, 0.045)
    for z in (-zt, zt):
        parts.append(_span((-0.03, y_deck - 0.012, z - 0.04), (0.03, y_deck, z + 0.04)))
        parts.append(_beam((0, y_deck - 0.012, z), (0, rwh, z), 0.03))
        parts.append(_cyl(0.02, (-w / 2 + ww * 0.6, rwh, z), (w / 2 - ww * 0.6, rwh, z), 12))
        parts.extend(
            _symmetric([_cyl(rwh, (w / 2 - ww * 0.8, rwh, z), (w / 2 - ww * 0.8 + ww, rwh, z), 24)])
        )
    return parts


def _pistol(rng: np.random.Generator) -> list[Part]:
    u = rng.uniform
    kind = rng.choice(2, p=[0.75, 0.25])  # semi-automatic, revolver
    ls, hs, ws = u(0.15, 0.22), u(0.028, 0.04), u(0.022, 0.03)
    parts: list[Part] = []
    z0 = -ls / 2
    if kind == 0:
        parts.append(_span((-ws / 2, 0, z0), (ws / 2, hs, z0 + ls)))
        parts.append(
            _span((-ws / 2 * 0.9, -0.018, z0 + 0.02), (ws / 2 * 0.9, 0.0, z0 + ls * u(0.7, 0.95)))
        )
        if rng.random() < 0.3:  # silencer
            parts.append(
                _cyl(
                    u(0.014, 0.02),
                    (0, hs * 0.6, z0 + ls - 0.01),
                    (0, hs * 0.6, z0 + ls + u(0.08, 0.15)),
                    24,
                )
            )
        else:
            parts.append(_cyl(0.006, (0, hs * 0.6, z0 + ls), (0, hs * 0.6, z0 + ls + 0.006), 12))
        top = hs
    else:
        barrel = u(0.1, 0.18)
        rb = u(0.008, 0.012)
        parts.append(_span((-ws / 2 * 0.8, -0.015, z0), (ws / 2 * 0.8, hs * 0.9, z0 + 0.09)))
        parts.append(
            _cyl(u(0.018, 0.024), (0, hs * 0.45, z0 + 0.02), (0, hs * 0.45, z0 + 0.07), 24)
        )
        parts.append(_cyl(rb, (0, hs * 0.75, z0 + 0.07), (0, hs * 0.75, z0 + 0.07 + barrel), 20))
        parts.append(
            _span(
                (-0.004, hs * 0.75, z0 + 0.07), (0.004, hs * 0.75 + rb + 0.004, z0 + 0.07 + barrel)
            )
        )
        top = hs * 0.9
    parts.append(_span((-0.002, top, z0 + ls * 0.93), (0.002, top + 0.008, z0 + ls * 0.98)))
    parts.append(_span((-0.006, top, z0 + 0.005), (0.006, top + 0.007, z0 + 0.015)))

    gl, gw = u(0.09, 0.13), u(0.028, 0.036)
    ga = u(0.15, 0.4)
    g = _corners((-ws / 2, -gl, -gw), (ws / 2, 0.0, 0.0))
    grip = _hexa(g)
    grip.apply_transform(_pose(_rot("x", ga), (0, 0.005, z0 + gw + 0.01)))
    parts.append(grip)
    if kind == 0 and rng.random() < 0.25:  # extended magazine
        mag = _span(
            (-ws / 2 * 0.8, -gl - u(0.02, 0.05), -gw * 0.8), (ws / 2 * 0.8, -gl + 0.01, -gw * 0.1)
        )
        mag.apply_transform(_pose(_rot("x", ga), (0, 0.005, z0 + gw + 0.01)))
        parts.append(mag)
    # Trigger guard (a ring below the frame) and trigger.
    rg = u(0.018, 0.024)
    zg = z0 + gw + 0.01 + rg * 0.9
    parts.append(_annulus(rg - 0.004, rg, (0, -0.012, zg), (1, 0, 0), 0.006))
    parts.append(
        _beam((0, -0.012, zg - rg * 0.2), (0, -0.012 - rg * 0.7, zg - rg * 0.05), 0.005, 0.006)
    )
    if rng.random() < 0.5:  # hammer
        parts.append(_beam((0, top - 0.005, z0 + 0.005), (0, top + 0.012, z0 - 0.01), 0.008))
    return parts


_BUILDERS: dict[str, Callable[[np.random.Generator], list[Part]]] = {
    "airplane": _airplane,
    "cabinet": _cabinet,
    "car": _car,
    "chair": _chair,
    "lamp": _lamp,
    "sofa": _sofa,
    "table": _table,
    "vessel": _vessel,
    "bus": _bus,
    "bed": _bed,
    "bookshelf": _bookshelf,
    "bench": _bench,
    "guitar": _guitar,
    "motorbike": _motorbike,
    "skateboard": _skateboard,
    "pistol": _pistol,
}


def _check_category(category: str) -> None:
    if category not in _BUILDERS:
        raise ValueError(
            f"unknown synthetic category {category!r}; allowed: {', '.join(CATEGORIES)}"
        )


def make_model(category: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One random model of ``category``, drawn with ``rng``.

    Args:
        category: one of :data:`CATEGORIES`.
        rng: the only source of randomness; the same generator state gives the same model.

    Returns:
        ``(vertices, faces)``: (N, 3) float64 in ShapeNet's frame (Y up, front +z), centred on the
        bounding-box centre with a bounding-box diagonal of 1 (unitless); (F, 3) int64 indices.
        Parts are concatenated, not merged: vertices are not shared between parts.
    """
    _check_category(category)
    parts = _BUILDERS[category](rng)
    counts = np.cumsum([0] + [len(p.vertices) for p in parts])
    vertices = np.concatenate([np.asarray(p.vertices, np.float64) for p in parts])
    faces = np.concatenate(
        [np.asarray(p.faces, np.int64) + o for p, o in zip(parts, counts, strict=False)]
    )
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    vertices = (vertices - (lo + hi) / 2) / np.linalg.norm(hi - lo)
    return vertices, faces


@dataclass(frozen=True)
class SyntheticEntry:
    """One model of the synthetic dataset: ``key`` like ``"chair_0003"``, its ``category``,
    ``split`` ("train", "valid" or "test") and ``index`` within the category."""

    key: str
    category: str
    split: str
    index: int


def _check_counts(counts: dict[str, int] | None) -> dict[str, int]:
    merged = dict(DEFAULT_COUNTS)
    for key, value in (counts or {}).items():
        if key not in DEFAULT_COUNTS:
            raise ValueError(
                f"unknown key {key!r} in synthetic counts; allowed: {', '.join(DEFAULT_COUNTS)}"
            )
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
            raise ValueError(f"synthetic counts[{key!r}] = {value!r}; allowed: an integer >= 0")
        merged[key] = int(value)
    return merged


def catalogue(counts: dict[str, int] | None = None) -> list[SyntheticEntry]:
    """The models of the synthetic dataset, in a fixed order (category order, then index).

    Args:
        counts: models per split for each training category (keys "train", "valid", "test") and
            per unseen category ("unseen", all in split "test"); missing keys take
            :data:`DEFAULT_COUNTS`.

    Returns:
        The entries. In a training category, indices ``0 .. test-1`` are the test models, then
        come the valid models, then the train models, so that a larger training set keeps the
        same valid and test models.
    """
    c = _check_counts(counts)
    entries = []
    for category in CATEGORIES:
        if category in TRAIN_CATEGORIES:
            splits = ["test"] * c["test"] + ["valid"] * c["valid"] + ["train"] * c["train"]
        else:
            splits = ["test"] * c["unseen"]
        entries.extend(
            SyntheticEntry(f"{category}_{i:04d}", category, split, i)
            for i, split in enumerate(splits)
        )
    return entries


def model_rng(category: str, index: int, seed: int) -> np.random.Generator:
    """The generator of model ``index`` of ``category`` for dataset ``seed``: it depends on these
    three only, through a stable hash of the name (CRC-32), so it is the same in every process."""
    _check_category(category)
    if index < 0 or seed < 0:
        raise ValueError(f"model index {index} and seed {seed} must be >= 0")
    return np.random.default_rng(
        np.random.SeedSequence([int(seed), zlib.crc32(category.encode("utf-8")), int(index)])
    )


def build(entry: SyntheticEntry, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The mesh of ``entry`` for dataset ``seed``: see :func:`make_model` for the arrays.

    The model depends only on (seed, category, index), not on the split or the other models.
    """
    return make_model(entry.category, model_rng(entry.category, entry.index, seed))


# --------------------------------------------------------------------------------------------
# Contact sheet.
# --------------------------------------------------------------------------------------------

_TINTS = {"train": (0.55, 0.7, 0.95), "unseen": (0.98, 0.72, 0.45)}


def render_tile(
    vertices: np.ndarray,
    faces: np.ndarray,
    size: int,
    tint: tuple[float, float, float] = _TINTS["train"],
    azimuth: float = 35.0,
    elevation: float = 25.0,
) -> np.ndarray:
    """A shaded picture of a normalised mesh, by ray casting (Open3D, no window needed).

    Args:
        vertices: (N, 3) float, the model within a sphere of radius 0.5 about the origin.
        faces: (F, 3) int.
        size: image width and height, pixels.
        tint: (3,) RGB in [0, 1], the surface colour.
        azimuth: camera azimuth in degrees, from +z towards +x.
        elevation: camera elevation above the XZ plane, degrees.

    Returns:
        (size, size, 3) uint8 RGB on a white background.
    """
    import open3d as o3d

    ss = 2  # supersampling, for smooth edges
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(vertices, np.float32)),
        o3d.core.Tensor(np.asarray(faces, np.uint32)),
    )
    a, e = np.deg2rad(azimuth), np.deg2rad(elevation)
    eye = 1.6 * np.array([np.cos(e) * np.sin(a), np.sin(e), np.cos(e) * np.cos(a)])
    rays = scene.create_rays_pinhole(
        fov_deg=38.0,
        center=[0.0, 0.0, 0.0],
        eye=eye.tolist(),
        up=[0.0, 1.0, 0.0],
        width_px=size * ss,
        height_px=size * ss,
    )
    hit = scene.cast_rays(rays)
    t = hit["t_hit"].numpy()
    normals = hit["primitive_normals"].numpy()
    dirs = rays.numpy()[..., 3:]
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    mask = np.isfinite(t)
    # Face the normals towards the camera: inner faces of open parts are seen from behind.
    normals *= -np.sign(np.sum(normals * dirs, axis=-1, keepdims=True) + 1e-12)
    light = np.array([-0.4, 0.8, 0.6]) + eye / np.linalg.norm(eye)
    light /= np.linalg.norm(light)
    diffuse = np.clip(normals @ light, 0.0, 1.0)
    facing = np.clip(-np.sum(normals * dirs, axis=-1), 0.0, 1.0)
    shade = 0.18 + 0.6 * diffuse + 0.22 * facing
    rgb = np.where(mask[..., None], shade[..., None] * np.asarray(tint), 1.0)
    # Dark outlines where depth jumps, so that thin parts and overlaps read clearly.
    depth = np.where(mask, t, 10.0)
    jump = np.zeros_like(mask)
    jump[1:, :] |= np.abs(np.diff(depth, axis=0)) > 0.05
    jump[:, 1:] |= np.abs(np.diff(depth, axis=1)) > 0.05
    rgb[jump] *= 0.35
    # Open3D's pinhole rays come out rotated by 180 degrees against the usual image layout.
    rgb = rgb[::-1, ::-1].reshape(size, ss, size, ss, 3).mean(axis=(1, 3))
    return (np.clip(rgb, 0.0, 1.0) * 255).round().astype(np.uint8)


def preview(
    path: str | Path,
    seed: int = 0,
    per_category: int = 4,
    tile: int = 160,
    label_width: int = 150,
) -> None:
    """Write a contact sheet PNG: one row per category (training ones blue, unseen ones orange),
    models ``0 .. per_category-1`` of each (as :func:`build` makes them for ``seed``) in columns.

    The image is ``label_width + per_category * tile`` pixels wide and ``16 * tile`` high.
    """
    from PIL import Image, ImageDraw, ImageFont

    if per_category < 1 or tile < 8 or label_width < 0:
        raise ValueError(
            f"preview needs per_category >= 1, tile >= 8 and label_width >= 0; got "
            f"per_category={per_category}, tile={tile}, label_width={label_width}"
        )
    sheet = Image.new("RGB", (label_width + per_category * tile, len(CATEGORIES) * tile), "white")
    draw = ImageDraw.Draw(sheet)
    font = ImageFont.load_default(size=max(8, min(20, tile // 7)))
    small = ImageFont.load_default(size=max(6, min(12, tile // 12)))
    for row, category in enumerate(CATEGORIES):
        group = "train" if category in TRAIN_CATEGORIES else "unseen"
        y = row * tile
        draw.text(
            (8, y + tile // 2), f"{category}\n({group})", fill=(0, 0, 0), font=font, anchor="lm"
        )
        for col in range(per_category):
            v, f = make_model(category, model_rng(category, col, seed))
            x = label_width + col * tile
            sheet.paste(Image.fromarray(render_tile(v, f, tile, _TINTS[group])), (x, y))
            draw.text((x + 4, y + 2), f"#{col} {len(f)} tris", fill=(90, 90, 90), font=small)
        draw.line([(0, y), (sheet.width, y)], fill=(200, 200, 200))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m nbv.synthetic --preview out.png [--seed S] [--per-category K]``."""
    parser = argparse.ArgumentParser(
        prog="python -m nbv.synthetic",
        description="Procedural ShapeNet stand-ins: draw a contact sheet of the 16 categories.",
    )
    parser.add_argument("--preview", type=Path, required=True, help="PNG file to write")
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    parser.add_argument("--per-category", type=int, default=4, help="models per row (default 4)")
    parser.add_argument("--tile", type=int, default=160, help="tile size in pixels (default 160)")
    args = parser.parse_args(argv)
    if args.seed < 0 or args.per_category < 1 or args.tile < 8:
        parser.error("--seed must be >= 0, --per-category >= 1 and --tile >= 8")
    start = time.perf_counter()
    preview(args.preview, seed=args.seed, per_category=args.per_category, tile=args.tile)
    print(f"wrote {args.preview} in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
