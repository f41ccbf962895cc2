"""Hand-sized and standing objects: lamp, guitar (upright, neck along +y, strings facing +z)
and pistol (barrel along +z).

Builders as :mod:`nbv.assets.synthetic.primitives` describes them.
"""

from __future__ import annotations

import numpy as np

import nbv.assets.synthetic.primitives as pr


def _lamp(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    kind = rng.choice(3, p=[0.45, 0.3, 0.25])  # desk, floor, table lamp
    parts: list[pr.Part] = []
    if kind == 0:
        rb, hb = u(0.07, 0.12), u(0.015, 0.04)
        if rng.random() < 0.3:
            parts.append(pr.span((-rb, 0, -rb), (rb, hb, rb)))
        else:
            parts.append(pr.cyl(rb, (0, 0, 0), (0, hb, 0), 32))
        ra = u(0.008, 0.015)
        joint = np.array([0.0, hb, -rb * 0.5])
        angles = [u(-0.4, 0.3)] + ([u(0.6, 1.6)] if rng.random() < 0.7 else [])
        for a in angles:
            nxt = joint + u(0.22, 0.38) * np.array([0.0, np.cos(a), np.sin(a)])
            parts.append(pr.cyl(ra, joint, nxt, 12))
            parts.append(pr.ellipsoid(nxt, (2 * ra,) * 3, 1))
            joint = nxt
        b = u(0.0, 0.9)
        axis = np.array([0.0, -np.cos(b), np.sin(b)])
        hs = u(0.1, 0.16)
        parts.append(
            pr.frustum(u(0.02, 0.035), u(0.06, 0.11), joint - 0.02 * axis, joint + hs * axis, 32)
        )
    elif kind == 1:
        rb, hp = u(0.12, 0.2), u(1.3, 1.8)
        rp = u(0.012, 0.02)
        parts.append(pr.cyl(rb, (0, 0, 0), (0, 0.03, 0), 32))
        style = rng.choice(3, p=[0.45, 0.3, 0.25])  # drum shade, torchiere bowl, arc
        if style == 0:
            parts.append(pr.cyl(rp, (0, 0, 0), (0, hp, 0), 12))
            hs = u(0.2, 0.3)
            parts.append(
                pr.frustum(
                    u(0.18, 0.25), u(0.12, 0.18), (0, hp - hs * 0.6, 0), (0, hp + hs * 0.4, 0), 32
                )
            )
        elif style == 1:
            parts.append(pr.cyl(rp, (0, 0, 0), (0, hp, 0), 12))
            parts.append(
                pr.frustum(
                    u(0.04, 0.08), u(0.18, 0.28), (0, hp - 0.05, 0), (0, hp + u(0.08, 0.14), 0), 32
                )
            )
        else:
            top = np.array([0.0, hp, -0.1])
            parts.append(pr.cyl(rp, (0, 0, -0.1), top, 12))
            reach = u(0.4, 0.7)
            end = top + np.array([0.0, u(-0.1, 0.15), reach])
            mid = (top + end) / 2 + np.array([0.0, 0.15, 0.0])
            parts.append(pr.cyl(rp, top, mid, 12))
            parts.append(pr.cyl(rp, mid, end, 12))
            parts.append(
                pr.frustum(0.03, u(0.15, 0.22), end, end - np.array([0.0, u(0.15, 0.22), 0.0]), 32)
            )
    else:
        rv, hv = u(0.06, 0.12), u(0.15, 0.3)
        parts.append(pr.cyl(rv * 1.1, (0, 0, 0), (0, 0.02, 0), 32))
        if rng.random() < 0.6:
            parts.append(pr.ellipsoid((0, 0.02 + hv / 2, 0), (rv, hv / 2, rv)))
        else:
            parts.append(pr.cyl(rv * 0.6, (0, 0, 0), (0, hv, 0), 24))
        y_shade = hv + u(0.05, 0.15)
        parts.append(pr.cyl(0.01, (0, hv, 0), (0, y_shade + 0.1, 0), 12))
        rs, hs = u(0.14, 0.22), u(0.15, 0.25)
        parts.append(pr.frustum(rs, rs * u(0.55, 0.9), (0, y_shade, 0), (0, y_shade + hs, 0), 32))
        parts.append(pr.ellipsoid((0, y_shade + hs + 0.02, 0), (0.015,) * 3, 1))
    return parts


def _guitar(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    kind = rng.choice(3, p=[0.5, 0.35, 0.15])  # acoustic, electric, bass
    parts: list[pr.Part] = []
    if kind == 0:
        r1 = u(0.17, 0.21)
        r2 = r1 * u(0.7, 0.85)
        depth = u(0.08, 0.12)
        c1y = r1
        c2y = c1y + (r1 + r2) * u(0.6, 0.75)
        parts.append(pr.cyl(r1, (0, c1y, -depth / 2), (0, c1y, depth / 2), 40))
        parts.append(pr.cyl(r2, (0, c2y, -depth / 2), (0, c2y, depth / 2), 40))
        parts.append(pr.span((-r2 * 0.8, c1y, -depth / 2), (r2 * 0.8, c2y, depth / 2)))
        parts.append(pr.annulus(0.04, 0.055, (0, c2y - 0.02, depth / 2), (0, 0, 1), 0.006))
        parts.append(pr.span((-0.06, c1y - 0.06, depth / 2), (0.06, c1y - 0.04, depth / 2 + 0.01)))
        body_top, front = c2y + r2, depth / 2
        neck_len, pegs = u(0.42, 0.5), 3
    else:
        r1 = u(0.14, 0.17)
        depth = u(0.04, 0.05)
        parts.append(pr.cyl(r1, (0, r1, -depth / 2), (0, r1, depth / 2), 40))
        parts.append(pr.cyl(r1 * 0.75, (0, r1 * 1.9, -depth / 2), (0, r1 * 1.9, depth / 2), 40))
        for s, lift in ((-1, u(0.1, 0.35)), (1, u(0.4, 0.7))):  # two horns, one longer
            c = (s * r1 * 0.5, r1 * (1.9 + lift), 0.0)
            parts.append(pr.ellipsoid(c, (0.24 * r1, 0.5 * r1, depth / 2)))
        for k in range(rng.integers(1, 4)):  # pickups
            y = r1 * (1.1 + 0.35 * k)
            parts.append(pr.span((-0.045, y, depth / 2), (0.045, y + 0.02, depth / 2 + 0.008)))
        parts.append(pr.span((-0.05, r1 * 0.7, depth / 2), (0.05, r1 * 0.78, depth / 2 + 0.012)))
        body_top, front = r1 * 2.5, depth / 2
        neck_len, pegs = (u(0.42, 0.48), 3) if kind == 1 else (u(0.6, 0.7), 4)
    nw, nt = u(0.045, 0.055), u(0.02, 0.026)
    y0 = body_top - 0.04
    parts.append(pr.span((-nw / 2, y0, front - nt), (nw / 2, y0 + neck_len, front)))
    hl, hw = u(0.15, 0.2), u(0.07, 0.09)
    head = [pr.span((-hw / 2, 0, -0.01), (hw / 2, hl, 0.01))]
    rows = np.linspace(0.03, hl - 0.03, pegs)
    one_side = kind != 0 and rng.random() < 0.6
    for y in rows:
        for s in (1,) if one_side else (-1, 1):
            head.append(pr.cyl(0.006, (s * hw / 2, y, 0), (s * (hw / 2 + 0.025), y, 0), 8))
    tilt = u(0.1, 0.25)
    for p in head:
        p.apply_transform(pr.pose(pr.rot("x", -tilt), (0, y0 + neck_len, front - 0.012)))
    return parts + head


def _pistol(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    kind = rng.choice(2, p=[0.75, 0.25])  # semi-automatic, revolver
    ls, hs, ws = u(0.15, 0.22), u(0.028, 0.04), u(0.022, 0.03)
    parts: list[pr.Part] = []
    z0 = -ls / 2
    if kind == 0:
        parts.append(pr.span((-ws / 2, 0, z0), (ws / 2, hs, z0 + ls)))
        parts.append(
            pr.span((-ws / 2 * 0.9, -0.018, z0 + 0.02), (ws / 2 * 0.9, 0.0, z0 + ls * u(0.7, 0.95)))
        )
        if rng.random() < 0.3:  # silencer
            parts.append(
                pr.cyl(
                    u(0.014, 0.02),
                    (0, hs * 0.6, z0 + ls - 0.01),
                    (0, hs * 0.6, z0 + ls + u(0.08, 0.15)),
                    24,
                )
            )
        else:
            parts.append(pr.cyl(0.006, (0, hs * 0.6, z0 + ls), (0, hs * 0.6, z0 + ls + 0.006), 12))
        top = hs
    else:
        barrel = u(0.1, 0.18)
        rb = u(0.008, 0.012)
        parts.append(pr.span((-ws / 2 * 0.8, -0.015, z0), (ws / 2 * 0.8, hs * 0.9, z0 + 0.09)))
        parts.append(
            pr.cyl(u(0.018, 0.024), (0, hs * 0.45, z0 + 0.02), (0, hs * 0.45, z0 + 0.07), 24)
        )
        parts.append(pr.cyl(rb, (0, hs * 0.75, z0 + 0.07), (0, hs * 0.75, z0 + 0.07 + barrel), 20))
        parts.append(
            pr.span(
                (-0.004, hs * 0.75, z0 + 0.07), (0.004, hs * 0.75 + rb + 0.004, z0 + 0.07 + barrel)
            )
        )
        top = hs * 0.9
    parts.append(pr.span((-0.002, top, z0 + ls * 0.93), (0.002, top + 0.008, z0 + ls * 0.98)))
    parts.append(pr.span((-0.006, top, z0 + 0.005), (0.006, top + 0.007, z0 + 0.015)))

    gl, gw = u(0.09, 0.13), u(0.028, 0.036)
    ga = u(0.15, 0.4)
    g = pr.corners((-ws / 2, -gl, -gw), (ws / 2, 0.0, 0.0))
    grip = pr.hexa(g)
    grip.apply_transform(pr.pose(pr.rot("x", ga), (0, 0.005, z0 + gw + 0.01)))
    parts.append(grip)
    if kind == 0 and rng.random() < 0.25:  # extended magazine
        mag = pr.span(
            (-ws / 2 * 0.8, -gl - u(0.02, 0.05), -gw * 0.8), (ws / 2 * 0.8, -gl + 0.01, -gw * 0.1)
        )
        mag.apply_transform(pr.pose(pr.rot("x", ga), (0, 0.005, z0 + gw + 0.01)))
        parts.append(mag)
    # Trigger guard (a ring below the frame) and trigger.
    rg = u(0.018, 0.024)
    zg = z0 + gw + 0.01 + rg * 0.9
    parts.append(pr.annulus(rg - 0.004, rg, (0, -0.012, zg), (1, 0, 0), 0.006))
    parts.append(
        pr.beam((0, -0.012, zg - rg * 0.2), (0, -0.012 - rg * 0.7, zg - rg * 0.05), 0.005, 0.006)
    )
    if rng.random() < 0.5:  # hammer
        parts.append(pr.beam((0, top - 0.005, z0 + 0.005), (0, top + 0.012, z0 - 0.01), 0.008))
    return parts
