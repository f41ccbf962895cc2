"""Wheeled vehicles: car, bus, motorbike and skateboard, long along z, front to +z.

Builders as :mod:`nbv.assets.synthetic.primitives` describes them.
"""

from __future__ import annotations

import numpy as np

import nbv.assets.synthetic.primitives as pr


def _wheel_pair(radius: float, width: float, x_out: float, y: float, z: float) -> list[pr.Part]:
    """Two wheels (tyre + hub) on an axle along x at height ``y`` and position ``z``."""
    tyre = pr.cyl(radius, (x_out - width, y, z), (x_out, y, z), 32)
    hub = pr.cyl(0.55 * radius, (x_out - width, y, z), (x_out + 0.01 * radius, y, z), 16)
    return pr.symmetric([tyre, hub])


def _car(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    kind = rng.choice(5, p=[0.3, 0.2, 0.2, 0.15, 0.15])  # sedan, hatch, suv, pickup, sports
    length, width = u(3.8, 4.9), u(1.7, 1.95)
    rw = u(0.36, 0.42) if kind in (2, 3) else u(0.3, 0.36)
    clear = rw * (u(0.6, 0.8) if kind in (2, 3) else u(0.35, 0.55))
    hb = u(0.35, 0.45) if kind == 4 else u(0.45, 0.65)
    y1 = clear + hb
    c = pr.corners((-width / 2, clear, -length / 2), (width / 2, y1, length / 2))
    c[[3, 7], 1] -= u(0.0, 0.15)  # hood slopes down to the front
    c[[1, 5], 2] -= u(0.05, 0.25)  # front bumper undercut
    parts = [pr.hexa(c)]

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
    cab = pr.corners((-0.47 * width, y1 - 0.02, zc - lc / 2), (0.47 * width, top_y, zc + lc / 2))
    cab[[2, 3, 6, 7], 0] *= 0.85
    cab[[3, 7], 2] -= wind
    cab[[2, 6], 2] += rear
    parts.append(pr.hexa(cab))

    if kind == 3:  # pickup bed: an open box behind the cabin
        wall_h, t = u(0.25, 0.35), 0.05
        z0, z1 = -length / 2, zc - lc / 2 - 0.05
        for s in (-1, 1):
            parts.append(
                pr.span(
                    (s * width / 2 - t * (s > 0), y1, z0),
                    (s * width / 2 + t * (s < 0), y1 + wall_h, z1),
                )
            )
        parts.append(pr.span((-width / 2, y1, z0), (width / 2, y1 + wall_h, z0 + t)))
        parts.append(pr.span((-width / 2, y1, z1 - t), (width / 2, y1 + wall_h, z1)))
    if kind in (0, 4) and rng.random() < 0.4:  # rear spoiler on two posts
        zs = -length / 2 + 0.15
        h = u(0.08, 0.18)
        parts.append(
            pr.span((-0.45 * width, y1 + h, zs - 0.12), (0.45 * width, y1 + h + 0.03, zs + 0.12))
        )
        parts.extend(
            pr.symmetric(
                [pr.span((0.3 * width, y1 - 0.02, zs - 0.03), (0.33 * width, y1 + h, zs + 0.03))]
            )
        )
    if rng.random() < 0.7:  # mirrors
        zm = zc + lc / 2 - wind * 0.7
        parts.extend(
            pr.symmetric(
                [
                    pr.span(
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


def _bus(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    length, width = u(9.0, 13.0), u(2.4, 2.6)
    clear, rw = u(0.3, 0.45), u(0.45, 0.55)
    decker = rng.random() < 0.3
    height = u(4.1, 4.4) if decker else u(2.8, 3.3)
    c = pr.corners((-width / 2, clear, -length / 2), (width / 2, height, length / 2))
    c[[3, 7], 2] -= u(0.0, 0.35)  # raked windscreen
    c[[2, 3, 6, 7], 0] *= u(0.97, 1.0)  # roof slightly narrower
    parts = [pr.hexa(c)]

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
                pr.symmetric(
                    [
                        pr.span(
                            (width / 2 - 0.02, y0, z0),
                            (width / 2 + 0.03, y0 + wh, z0 + 0.88 * pitch),
                        )
                    ]
                )
            )
    # Door on the right side, windscreen and rear window.
    parts.append(
        pr.span(
            (width / 2 - 0.02, clear + 0.2, z_front + 0.1),
            (width / 2 + 0.04, height - 0.3, z_front + 1.0),
        )
    )
    rake = c[1, 2] - c[3, 2]
    ws = pr.corners((-0.44 * width, 1.1, -0.02), (0.44 * width, height - 0.25, 0.03))
    ws[:, 2] += length / 2 - rake * (ws[:, 1] - clear) / (height - clear)  # follow the raked front
    parts.append(pr.hexa(ws))
    parts.append(
        pr.span(
            (-0.4 * width, height - 0.3 - wh, -length / 2 - 0.03),
            (0.4 * width, height - 0.4, -length / 2 + 0.02),
        )
    )
    parts.append(
        pr.span(
            (-width / 2 - 0.03, clear - 0.05, length / 2 - 0.1),
            (width / 2 + 0.03, clear + 0.35, length / 2 + 0.12),
        )
    )
    if rng.random() < 0.5:  # roof air conditioner
        la = u(1.5, 3.0)
        za = u(-length / 4, length / 4)
        parts.append(
            pr.span(
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


def _motorbike(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    wb, rw, tyre = u(1.3, 1.6), u(0.28, 0.34), u(0.05, 0.08)
    zf, zr = wb / 2, -wb / 2
    parts: list[pr.Part] = []
    for z in (zf, zr):
        c = (0.0, rw, z)
        parts.append(pr.torus(rw - tyre, tyre, c, (1, 0, 0)))
        parts.append(pr.annulus(0.25 * rw, rw - tyre, c, (1, 0, 0), 0.02))
        parts.append(pr.cyl(0.05, (-0.07, rw, z), (0.07, rw, z), 16))
    rake = u(0.4, 0.55)
    fork = u(0.6, 0.75)
    head = np.array([0.0, rw + fork * np.cos(rake), zf - fork * np.sin(rake)])
    parts.extend(pr.symmetric([pr.cyl(0.022, (0.07, rw, zf), head + (0.07, 0, 0), 12)]))
    parts.append(pr.cyl(0.035, head - (0, 0.12, -0.05), head + (0, 0.05, -0.02), 12))
    bar_w, bar_up = u(0.3, 0.4), u(0.0, 0.12)
    bar = head + (0, bar_up + 0.04, -0.05)
    parts.append(pr.cyl(0.012, (-bar_w, bar[1], bar[2] - 0.05), (bar_w, bar[1], bar[2] - 0.05), 12))
    parts.extend(
        pr.symmetric(
            [
                pr.cyl(
                    0.018,
                    (bar_w - 0.1, bar[1], bar[2] - 0.05),
                    (bar_w + 0.01, bar[1], bar[2] - 0.05),
                    12,
                )
            ]
        )
    )
    parts.append(pr.cyl(0.015, head + (0, 0.04, -0.02), bar + (0, 0, -0.05), 8))

    pivot = np.array([0.0, rw + 0.12, zr + u(0.45, 0.55)])
    parts.extend(pr.symmetric([pr.cyl(0.02, (0.08, rw, zr), pivot + (0.08, 0, 0), 12)]))
    seat_y = rw + u(0.45, 0.55)
    parts.append(pr.cyl(0.025, head, pivot, 12))
    parts.append(pr.cyl(0.025, head - (0, 0.1, 0), (0, rw + 0.1, pivot[2] + 0.15), 12))
    # Engine block, tank and seat.
    ez = (pivot[2] + head[2]) / 2
    parts.append(pr.span((-0.13, rw - 0.08, ez - 0.2), (0.13, rw + 0.25, ez + 0.18)))
    tank_z = head[2] - u(0.2, 0.28)
    parts.append(pr.ellipsoid((0, seat_y + 0.05, tank_z), (0.14, 0.1, u(0.18, 0.24))))
    seat_len = u(0.45, 0.6)
    seat = pr.corners(
        (-0.13, seat_y - 0.06, tank_z - 0.15 - seat_len), (0.13, seat_y + 0.02, tank_z - 0.15)
    )
    seat[[2, 6], 1] += u(0.0, 0.08)  # raised pillion
    parts.append(pr.hexa(seat))
    parts.append(pr.span((-0.1, seat_y - 0.15, zr - 0.05), (0.1, seat_y - 0.06, tank_z - 0.15)))
    # Exhausts.
    for s in (1,) if rng.random() < 0.6 else (-1, 1):
        parts.append(
            pr.cyl(0.035, (s * 0.15, rw - 0.05, ez), (s * 0.18, rw + 0.1, zr + u(0.0, 0.15)), 16)
        )
    if rng.random() < 0.5:  # front fairing
        f = pr.corners(
            (-0.2, head[1] - 0.25, head[2] - 0.05), (0.2, head[1] + 0.15, head[2] + 0.15)
        )
        f[[2, 3, 6, 7], 0] *= 0.5
        f[[3, 7], 2] -= 0.12
        f[[1, 5], 2] += 0.05
        parts.append(pr.hexa(f))
    if rng.random() < 0.7:  # mudguard over the front wheel
        parts.append(
            pr.beam((0, 2 * rw + 0.03, zf + 0.2), (0, 2 * rw + 0.05, zf - 0.15), 0.1, 0.02)
        )
    return parts


def _skateboard(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    longboard = rng.random() < 0.3
    length = u(1.0, 1.15) if longboard else u(0.75, 0.85)
    w = u(0.2, 0.25) if longboard else u(0.19, 0.23)
    dt = u(0.01, 0.015)
    rwh = u(0.025, 0.035)
    truck = u(0.04, 0.06)
    y_deck = 2 * rwh + truck
    flat = length * (0.8 if longboard else 0.68)
    parts = [pr.span((-w / 2, y_deck, -flat / 2), (w / 2, y_deck + dt, flat / 2))]
    tail = (length - flat) / 2
    kick = u(0.0, 0.08) if longboard else u(0.2, 0.4)
    for s in (-1, 1):
        p = [
            pr.span((-w / 2, 0, 0), (w / 2, dt, tail)),
            pr.cyl(w / 2, (0, 0, tail), (0, dt, tail), 32),
        ]
        for q in p:
            q.apply_transform(pr.pose(pr.rot("x", -kick), (0, 0, 0)))
            if s < 0:
                q.apply_transform(np.diag([1.0, 1.0, -1.0, 1.0]))
            q.apply_translation((0, y_deck, s * flat / 2))
        parts.extend(p)
    zt = flat / 2 - u(0.04, 0.1)
    ww = u(0.03, 0.045)
    for z in (-zt, zt):
        parts.append(pr.span((-0.03, y_deck - 0.012, z - 0.04), (0.03, y_deck, z + 0.04)))
        parts.append(pr.beam((0, y_deck - 0.012, z), (0, rwh, z), 0.03))
        parts.append(pr.cyl(0.02, (-w / 2 + ww * 0.6, rwh, z), (w / 2 - ww * 0.6, rwh, z), 12))
        parts.extend(
            pr.symmetric(
                [pr.cyl(rwh, (w / 2 - ww * 0.8, rwh, z), (w / 2 - ww * 0.8 + ww, rwh, z), 24)]
            )
        )
    return parts
