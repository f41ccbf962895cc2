"""Aircraft and watercraft: airplane and vessel, long along z, nose or bow to +z.

Builders as :mod:`nbv.assets.synthetic.primitives` describes them.
"""

from __future__ import annotations

import numpy as np

import nbv.assets.synthetic.primitives as pr


def _airplane_tail(
    rng: np.random.Generator, kind: int, r: float, tail_lift: float
) -> tuple[list[pr.Part], pr.Part]:
    """The vertical fin(s) and one half of the horizontal tail of an airplane of ``kind``
    (fuselage radius ``r``, tail cone lifted by ``tail_lift``)."""
    u = rng.uniform
    # Vertical fin(s); fighters may have two, canted.
    hf, crf = u(0.1, 0.18), u(0.12, 0.2)
    tan_f = np.tan(np.deg2rad(u(30, 50)))
    tip_f = crf * u(0.35, 0.6)
    z_le_f = -0.5 + crf + 0.01
    twin = kind == 1 and rng.random() < 0.5
    xf, cant = (0.8 * r, 0.35) if twin else (0.0, 0.0)
    y0f = tail_lift * 0.5 + 0.4 * r
    fin = pr.slab(
        (xf, y0f, z_le_f),
        crf,
        (xf + hf * np.sin(cant), y0f + hf * np.cos(cant), z_le_f - hf * tan_f),
        tip_f,
        (0.012, 0.008),
        thick_dir=(1, 0, 0),
    )

    # Horizontal tail, at the fuselage or on top of the fin (T-tail).
    t_tail = kind != 1 and not twin and rng.random() < 0.25
    bt, crt = u(0.12, 0.2), u(0.07, 0.12)
    if t_tail:
        y_t, z_le_t = y0f + hf - 0.005, z_le_f - hf * tan_f + 0.005
        crt = min(crt, tip_f * 1.3)
    else:
        y_t, z_le_t = tail_lift * 0.6, -0.5 + crt + u(0.0, 0.05)
    tan_t = np.tan(np.deg2rad(u(20, 40) if kind != 2 else u(0, 10)))
    tailplane = pr.slab(
        (0, y_t, z_le_t), crt, (bt, y_t, z_le_t - bt * tan_t), crt * 0.5, (0.012, 0.008)
    )
    return [fin] + (pr.mirror_x([fin]) if twin else []), tailplane


def _airplane(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    kind = rng.choice(3, p=[0.5, 0.25, 0.25])  # airliner, fighter, light aircraft
    r = (u(0.04, 0.065), u(0.035, 0.05), u(0.04, 0.06))[kind]
    z_tail, z_nose = -0.5 + u(0.18, 0.26), 0.5 - u(0.15, 0.22)
    parts = [pr.cyl(r, (0, 0, z_tail), (0, 0, z_nose), 24)]
    if kind == 1:
        parts.append(pr.cone(r, (0, 0, z_nose), (0, -0.2 * r, 0.5), 24))
    else:
        parts.append(pr.ellipsoid((0, 0, z_nose), (r, r, 0.5 - z_nose)))
    tail_lift = r * u(0.2, 0.7)
    parts.append(pr.frustum(r, r * u(0.25, 0.45), (0, 0, z_tail), (0, tail_lift, -0.5), 24))

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
    wing = pr.slab(
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
            half.append(pr.cyl(re, (x, y, z_le - 0.5 * le), (x, y, z_le + 0.5 * le), 20))
            half.append(pr.span((x - 0.004, y, z_le - 0.4 * le), (x + 0.004, y + re + 0.012, z_le)))
    elif kind == 2:
        if rng.random() < 0.6:  # wing struts
            half.append(pr.cyl(0.006, (r * 0.8, -0.7 * r, zc), (0.45 * b, y_w, zc), 8))
        parts.append(pr.cone(0.35 * r, (0, 0, 0.5), (0, 0, 0.5 + 0.5 * r), 12))
        blade = u(0.08, 0.12)
        for k in range(rng.choice([2, 3])):
            rot = pr.rot("z", k * 2 * np.pi / 3 + u(0, 1))
            parts.append(pr.box((0.014, blade, 0.006), (0, 0, 0.5 + 0.2 * r), rot))
            parts[-1].apply_translation(rot @ np.array([0, blade / 2, 0]))

    fins, tailplane = _airplane_tail(rng, kind, r, tail_lift)
    parts.extend(fins)
    half.append(tailplane)
    return parts + pr.symmetric(half)


def _ship_decks(rng: np.random.Generator, beam: float, hd: float, zb: float) -> list[pr.Part]:
    """A ship's decks, funnels, mast and deck cargo on a hull of ``beam`` and deck height ``hd``."""
    u = rng.uniform
    parts: list[pr.Part] = []
    zh = u(-0.3, 0.05)
    y = hd
    lz, bw = u(0.15, 0.35), beam * u(0.6, 0.85)
    for _ in range(rng.integers(1, 4)):
        th = u(0.04, 0.07)
        parts.append(pr.span((-bw / 2, y, zh - lz / 2), (bw / 2, y + th, zh + lz / 2)))
        y += th
        lz *= u(0.6, 0.9)
        bw *= u(0.75, 0.95)
    if rng.random() < 0.7:
        for k in range(rng.integers(1, 3)):
            zf = zh - 0.05 - 0.07 * k
            parts.append(pr.cyl(u(0.015, 0.03), (0, hd, zf), (0, y + u(0.04, 0.1), zf), 20))
    mast_top = y + u(0.1, 0.25)
    parts.append(pr.cyl(0.005, (0, y, zh + 0.02), (0, mast_top, zh + 0.02), 8))
    parts.append(pr.span((-0.05, mast_top - 0.04, zh + 0.015), (0.05, mast_top - 0.03, zh + 0.025)))
    if rng.random() < 0.35:  # deck cargo
        for k in range(rng.integers(1, 4)):
            z0 = zh + 0.2 + 0.07 * k
            if z0 + 0.05 < zb + 0.05:
                parts.append(pr.span((-beam * 0.35, hd, z0), (beam * 0.35, hd + 0.04, z0 + 0.05)))
    return parts


def _sailboat_rig(rng: np.random.Generator, beam: float, hd: float) -> list[pr.Part]:
    """A sailboat's mast, boom, sails, cockpit and keel fin."""
    u = rng.uniform
    parts: list[pr.Part] = []
    zm = u(0.0, 0.2)
    top = hd + u(0.5, 0.9)
    parts.append(pr.cyl(0.006, (0, hd, zm), (0, top, zm), 8))
    boom_y = hd + u(0.04, 0.08)
    chord = u(0.25, 0.4)
    parts.append(pr.cyl(0.005, (0, boom_y, zm), (0, boom_y, zm - chord), 8))
    parts.append(
        pr.slab(
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
            pr.slab(
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
    parts.append(pr.span((-beam * 0.3, hd, zc - lc), (beam * 0.3, hd + u(0.03, 0.05), zc)))
    if rng.random() < 0.6:  # keel fin
        parts.append(
            pr.slab(
                (0, 0.01, zm + 0.05),
                0.15,
                (0, -u(0.1, 0.2), zm),
                0.1,
                (0.012, 0.01),
                thick_dir=(1, 0, 0),
            )
        )
    return parts


def _speedboat_cabin(rng: np.random.Generator, beam: float, hd: float) -> list[pr.Part]:
    """A speedboat's cabin and outboard motor."""
    u = rng.uniform
    parts: list[pr.Part] = []
    zc, lc = u(-0.1, 0.1), u(0.2, 0.35)
    hc = u(0.05, 0.09)
    cab = pr.corners((-beam * 0.4, hd, zc - lc / 2), (beam * 0.4, hd + hc, zc + lc / 2))
    cab[[3, 7], 2] -= lc * u(0.4, 0.7)
    cab[[2, 3, 6, 7], 0] *= 0.85
    parts.append(pr.hexa(cab))
    if rng.random() < 0.7:  # outboard motor
        parts.append(pr.span((-0.03, hd * 0.2, -0.55), (0.03, hd + 0.06, -0.49)))
        parts.append(pr.span((-0.01, -0.05, -0.535), (0.01, hd * 0.2, -0.505)))
    return parts


def _vessel(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    kind = rng.choice(3, p=[0.45, 0.3, 0.25])  # ship, sailboat, speedboat
    beam = u(0.14, 0.24) if kind != 2 else u(0.22, 0.32)
    hd = u(0.06, 0.12)
    bow_len = u(0.18, 0.35)
    zb = 0.5 - bow_len
    bf = u(0.4, 0.8)
    stern = pr.corners((-beam / 2, 0, -0.5), (beam / 2, hd, zb))
    stern[[0, 1, 4, 5], 0] *= bf
    stern[[0, 4], 2] += u(0.0, 0.05)
    bow = stern.copy()
    bow[[0, 2, 4, 6]] = stern[[1, 3, 5, 7]]
    bow[[3, 7], 0] = np.array([-1, 1]) * 0.01 * beam
    bow[[3, 7], 2] = 0.5
    bow[[1, 5], 0] = np.array([-1, 1]) * 0.01 * beam
    bow[[1, 5], 2] = 0.5 - u(0.05, 0.2)
    bow[[1, 5], 1] = hd * u(0.0, 0.4)
    parts = [pr.hexa(stern), pr.hexa(bow)]

    if kind == 0:
        parts += _ship_decks(rng, beam, hd, zb)
    elif kind == 1:
        parts += _sailboat_rig(rng, beam, hd)
    else:
        parts += _speedboat_cabin(rng, beam, hd)
    return parts
