"""Furniture other than seats: table, cabinet, bed and bookshelf (cabinets, beds and
bookshelves face +z).

Builders as :mod:`nbv.assets.synthetic.primitives` describes them.
"""

from __future__ import annotations

import numpy as np

import nbv.assets.synthetic.primitives as pr


def _table(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    coffee = rng.random() < 0.2
    h = u(0.4, 0.5) if coffee else u(0.7, 0.78)
    round_top = rng.random() < 0.35
    tt = u(0.025, 0.06)
    if round_top:
        r = u(0.35, 0.7)
        parts = [pr.cyl(r, (0, h - tt, 0), (0, h, 0), 48)]
        wx = wz = r * 0.7
    else:
        w = u(0.9, 2.0)
        d = min(w * u(0.5, 1.0), u(0.55, 1.0))
        parts = [pr.span((-w / 2, h - tt, -d / 2), (w / 2, h, d / 2))]
        wx, wz = w / 2, d / 2
    y_under = h - tt

    column = rng.random() < (0.6 if round_top else 0.2)
    if column and round_top:
        cr = u(0.03, 0.08)
        parts.append(pr.cyl(cr, (0, 0.02, 0), (0, y_under, 0), 24))
        if rng.random() < 0.5:
            parts.append(pr.cyl(u(0.2, 0.32), (0, 0, 0), (0, 0.03, 0), 32))
        else:
            foot = u(0.25, 0.4)
            for k in range(4):
                a = k * np.pi / 2 + np.pi / 4
                parts.append(
                    pr.beam((0, 0.03, 0), (foot * np.cos(a), 0.015, foot * np.sin(a)), 0.05, 0.03)
                )
    elif column:  # trestle: two end frames joined by a stretcher
        xt = wx - u(0.1, 0.25)
        pw = u(0.04, 0.08)
        for sx in (-1, 1):
            parts.append(
                pr.span((sx * xt - pw / 2, 0.06, -0.04), (sx * xt + pw / 2, y_under, 0.04))
            )
            parts.append(
                pr.span((sx * xt - pw / 2, 0, -wz * 0.85), (sx * xt + pw / 2, 0.06, wz * 0.85))
            )
            parts.append(
                pr.span(
                    (sx * xt - pw / 2, y_under - 0.05, -wz * 0.85),
                    (sx * xt + pw / 2, y_under, wz * 0.85),
                )
            )
        parts.append(pr.span((-xt, 0.25, -0.025), (xt, 0.3, 0.025)))
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
            parts.append(pr.cyl(lt / 2, foot, top, 16) if rnd else pr.beam(foot, top, lt))
        if not round_top and rng.random() < 0.5:  # apron
            ah = u(0.05, 0.1)
            xa, za = pos[3]
            parts.extend(pr.symmetric([pr.span((xa - 0.02, y_under - ah, -za), (xa, y_under, za))]))
            parts.append(pr.span((-xa, y_under - ah, za - 0.02), (xa, y_under, za)))
            parts.append(pr.span((-xa, y_under - ah, -za), (xa, y_under, -za + 0.02)))
        if not round_top and rng.random() < 0.3:  # lower shelf
            xa, za = pos[3]
            ys = u(0.1, 0.25)
            parts.append(pr.span((-xa, ys, -za), (xa, ys + 0.025, za)))
    return parts


def _cabinet_feet(feet: int, w: float, d: float, y0: float) -> list[pr.Part]:
    """A cabinet's support of height ``y0``: none (``feet`` 0), four feet (1) or a plinth (2)."""
    out: list[pr.Part] = []
    if feet == 1:
        for sx in (-1, 1):
            for sz in (-1, 1):
                out.append(
                    pr.cyl(
                        0.025,
                        (sx * (w / 2 - 0.05), 0, sz * (d / 2 - 0.05)),
                        (sx * (w / 2 - 0.05), y0, sz * (d / 2 - 0.05)),
                        12,
                    )
                )
    elif feet == 2:
        out.append(pr.span((-w / 2 + 0.03, 0, -d / 2 + 0.03), (w / 2 - 0.03, y0, d / 2 - 0.03)))
    return out


def _carcass(
    styles: np.ndarray, w: float, d: float, t: float, y0: float, y1: float
) -> list[pr.Part]:
    """A cabinet's body from ``y0`` to ``y1``: one block when every column is closed, else panels
    of thickness ``t`` around the columns of ``styles`` (3: an open column)."""
    out: list[pr.Part] = []
    nc = len(styles)
    cw = (w - 2 * t) / nc
    front = d / 2
    if not (styles == 3).any():
        out.append(pr.span((-w / 2, y0, -d / 2), (w / 2, y1, front)))
    else:  # carcass of panels, with the closed columns filled in
        out.append(pr.span((-w / 2, y0, -d / 2), (-w / 2 + t, y1, front)))
        out.append(pr.span((w / 2 - t, y0, -d / 2), (w / 2, y1, front)))
        out.append(pr.span((-w / 2, y0, -d / 2), (w / 2, y0 + t, front)))
        out.append(pr.span((-w / 2, y1 - t, -d / 2), (w / 2, y1, front)))
        out.append(pr.span((-w / 2, y0, -d / 2), (w / 2, y1, -d / 2 + t)))
        for k in range(1, nc):
            x = -w / 2 + t + k * cw
            out.append(pr.span((x - t / 2, y0, -d / 2), (x + t / 2, y1, front)))
    return out


def _cabinet(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    w, h, d = u(0.4, 1.6), u(0.5, 2.0), u(0.35, 0.6)
    t = u(0.015, 0.03)
    feet = rng.choice(3)  # none, four feet, plinth
    y0 = 0.0 if feet == 0 else u(0.05, 0.15)
    y1 = y0 + h
    parts: list[pr.Part] = _cabinet_feet(feet, w, d, y0)

    nc = int(np.clip(round(w / u(0.4, 0.6)), 1, 4))
    styles = rng.choice(4, size=nc, p=[0.45, 0.3, 0.15, 0.1])  # doors, drawers, mixed, open
    cw = (w - 2 * t) / nc
    front = d / 2
    parts += _carcass(styles, w, d, t, y0, y1)
    if rng.random() < 0.4:  # overhanging top
        o = u(0.015, 0.04)
        parts.append(pr.span((-w / 2 - o, y1, -d / 2), (w / 2 + o, y1 + u(0.02, 0.04), front + o)))

    g, ft = 0.006, 0.018
    handle_bar = rng.random() < 0.5
    inner_h = h - 2 * t

    def fronts(x0: float, x1: float, ya: float, yb: float, hx: float | None) -> list[pr.Part]:
        out = [pr.span((x0 + g, ya + g, front), (x1 - g, yb - g, front + ft))]
        hx = (x0 + x1) / 2 if hx is None else hx
        hy = yb - min(0.08, (yb - ya) / 3) if hx == (x0 + x1) / 2 else (ya + yb) / 2
        if handle_bar:
            lx, ly = (0.08, 0.015) if hx == (x0 + x1) / 2 else (0.015, 0.1)
            out.append(
                pr.span(
                    (hx - lx / 2, hy - ly / 2, front + ft),
                    (hx + lx / 2, hy + ly / 2, front + ft + 0.02),
                )
            )
        else:
            out.append(pr.cyl(0.01, (hx, hy, front + ft), (hx, hy, front + ft + 0.025), 12))
        return out

    for k, style in enumerate(styles):
        x0 = -w / 2 + t + k * cw
        x1 = x0 + cw
        ya, yb = y0 + t, y1 - t
        if style == 3:
            for y in np.linspace(ya, yb, rng.integers(2, 5) + 1)[1:-1]:
                parts.append(pr.span((x0, y, -d / 2 + t), (x1, y + t, front - 0.01)))
            continue
        if styles.tolist().count(3):
            parts.append(pr.span((x0, ya, -d / 2 + t), (x1, yb, front)))
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


def _bed_board(
    rng: np.random.Generator,
    z: float,
    top: float,
    w: float,
    ov: float,
    bt: float,
    frame_top: float,
) -> list[pr.Part]:
    """A bed's head- or footboard at ``z`` up to ``top``: a panel, or posts, rails and
    spindles."""
    u = rng.uniform
    if rng.random() < 0.6:
        return [pr.span((-w / 2 - ov, 0, z - bt / 2), (w / 2 + ov, top, z + bt / 2))]
    post_r = u(0.025, 0.045)
    out = [
        pr.cyl(post_r, (s * (w / 2 + ov), 0, z), (s * (w / 2 + ov), top + 0.04, z), 16)
        for s in (-1, 1)
    ]
    out.append(pr.span((-w / 2 - ov, top - 0.08, z - bt / 3), (w / 2 + ov, top, z + bt / 3)))
    out.append(
        pr.span((-w / 2 - ov, frame_top, z - bt / 3), (w / 2 + ov, frame_top + 0.06, z + bt / 3))
    )
    for x in np.linspace(-w / 2, w / 2, rng.integers(4, 10) + 2)[1:-1]:
        out.append(pr.cyl(0.012, (x, frame_top + 0.06, z), (x, top - 0.08, z), 8))
    return out


def _canopy(top: float, w: float, ov: float, length: float, bt: float) -> list[pr.Part]:
    """A four-poster bed's posts and rails up to ``top``, outside its boards."""
    out: list[pr.Part] = []
    zs = (-length / 2 - bt / 2, length / 2 + bt / 2)
    for sx in (-1, 1):
        for z in zs:
            out.append(pr.cyl(0.035, (sx * (w / 2 + ov), 0, z), (sx * (w / 2 + ov), top, z), 12))
        out.append(
            pr.span(
                (sx * (w / 2 + ov) - 0.03, top - 0.06, zs[0]),
                (sx * (w / 2 + ov) + 0.03, top, zs[1]),
            )
        )
    for z in zs:
        out.append(pr.span((-w / 2 - ov, top - 0.06, z - 0.03), (w / 2 + ov, top, z + 0.03)))
    return out


def _bed(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    w, length = u(0.9, 1.9), u(1.9, 2.2)
    legs = rng.random() < 0.6
    leg_h = u(0.05, 0.25) if legs else 0.0
    frame_top = leg_h + u(0.15, 0.3)
    parts = [pr.span((-w / 2, leg_h, -length / 2), (w / 2, frame_top, length / 2))]
    if legs:
        for sx in (-1, 1):
            for sz in (-1, 1):
                parts.append(
                    pr.span(
                        (sx * (w / 2 - 0.03) - 0.03, 0, sz * (length / 2 - 0.03) - 0.03),
                        (sx * (w / 2 - 0.03) + 0.03, leg_h, sz * (length / 2 - 0.03) + 0.03),
                    )
                )
    mt = u(0.15, 0.25)
    m_top = frame_top + mt
    parts.append(
        pr.span(
            (-w / 2 + 0.02, frame_top, -length / 2 + 0.02), (w / 2 - 0.02, m_top, length / 2 - 0.02)
        )
    )

    bt = u(0.04, 0.08)
    z_head = -length / 2 - bt / 2
    ov = u(0.0, 0.06)

    head_top = u(0.9, 1.4)
    parts.extend(_bed_board(rng, z_head, head_top, w, ov, bt, frame_top))
    foot_top = u(0.45, 0.7)
    footboard = rng.random() < 0.45
    if footboard:
        parts.extend(_bed_board(rng, length / 2 + bt / 2, foot_top, w, ov, bt, frame_top))
    if rng.random() < 0.1:  # four-poster canopy
        parts += _canopy(rng.uniform(1.8, 2.1), w, ov, length, bt)

    n_p = 1 if w < 1.3 else 2
    pw = (w - 0.1) / n_p
    for k in range(n_p):
        xc = -w / 2 + 0.05 + (k + 0.5) * pw
        parts.append(pr.ellipsoid((xc, m_top + 0.05, -length / 2 + 0.25), (pw * 0.42, 0.07, 0.17)))
    if rng.random() < 0.5:  # blanket over the lower part, hanging over the sides
        zb = length / 2 - 0.01 - (0.02 if footboard else -0.04)
        parts.append(
            pr.span(
                (-w / 2 - 0.02, frame_top - u(0.0, 0.15), -length / 2 + length * u(0.3, 0.45)),
                (w / 2 + 0.02, m_top + 0.02, zb),
            )
        )
    return parts


def _bookshelf(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    w, h, d = u(0.6, 1.4), u(0.9, 2.0), u(0.25, 0.4)
    t = u(0.018, 0.035)
    plinth = u(0.0, 0.1) if rng.random() < 0.5 else 0.0
    back = rng.random() < 0.7
    parts = [
        pr.span((-w / 2, 0, -d / 2), (-w / 2 + t, h, d / 2)),
        pr.span((w / 2 - t, 0, -d / 2), (w / 2, h, d / 2)),
        pr.span((-w / 2, h - t, -d / 2), (w / 2, h, d / 2)),
        pr.span((-w / 2, plinth, -d / 2), (w / 2, plinth + t, d / 2)),
    ]
    if plinth > 0:
        parts.append(pr.span((-w / 2, 0, d / 2 - 0.03), (w / 2, plinth, d / 2 - 0.01)))
    if back:
        parts.append(pr.span((-w / 2, 0, -d / 2), (w / 2, h, -d / 2 + 0.01)))
    n_shelves = max(2, round((h - plinth) / u(0.28, 0.4)))
    ys = np.linspace(plinth + t, h - t, n_shelves + 1)
    for y in ys[1:-1]:
        parts.append(
            pr.span((-w / 2 + t, y - t / 2, -d / 2), (w / 2 - t, y + t / 2, d / 2 - 0.005))
        )
    columns = 2 if w > 1.0 and rng.random() < 0.6 else 1
    if columns == 2:
        parts.append(pr.span((-t / 2, plinth, -d / 2), (t / 2, h - t, d / 2)))
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
                parts.append(pr.span((x, floor, zf - bd), (x + bw, floor + bh, zf)))
                x += bw + (u(0.0, 0.003) if rng.random() < 0.9 else u(0.03, 0.1))
    return parts
