"""Seats: chair, sofa and bench, facing +z.

Builders as :mod:`nbv.assets.synthetic.primitives` describes them.
"""

from __future__ import annotations

import numpy as np

import nbv.assets.synthetic.primitives as pr


def _chair_back(rng: np.random.Generator, w: float, d: float, sh: float) -> list[pr.Part]:
    """A chair's back (solid, spindles or bars), built upright at the rear edge of a seat of
    width ``w``, depth ``d`` and height ``sh`` and tilted backwards."""
    u = rng.uniform
    bh, bt, tilt = u(0.3, 0.6), u(0.02, 0.06), u(0.0, 0.3)
    style = rng.choice(3, p=[0.45, 0.35, 0.2])
    back: list[pr.Part] = []
    if style == 0:
        back.append(pr.span((-w / 2, 0, -bt / 2), (w / 2, bh, bt / 2)))
    else:
        pw = u(0.025, 0.045)
        rail = u(0.05, 0.12)
        back.extend(pr.symmetric([pr.span((w / 2 - pw, 0, -bt / 2), (w / 2, bh, bt / 2))]))
        back.append(pr.span((-w / 2, bh - rail, -bt / 2), (w / 2, bh, bt / 2)))
        k = rng.integers(2, 6)
        if style == 1:  # vertical spindles
            for x in np.linspace(-w / 2 + pw, w / 2 - pw, k + 2)[1:-1]:
                back.append(pr.span((x - 0.012, 0, -bt / 4), (x + 0.012, bh - rail, bt / 4)))
        else:  # horizontal bars
            for y in np.linspace(0.05, bh - rail, k + 1)[:-1]:
                back.append(pr.span((-w / 2 + pw, y, -bt / 3), (w / 2 - pw, y + 0.035, bt / 3)))
    for p in back:
        p.apply_transform(pr.pose(pr.rot("x", -tilt), (0, sh, -d / 2 + bt / 2)))
    return back


def _chair(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    w, d, sh, st = u(0.4, 0.56), u(0.4, 0.55), u(0.38, 0.5), u(0.03, 0.08)
    parts = [pr.span((-w / 2, sh - st, -d / 2), (w / 2, sh, d / 2))]

    parts.extend(_chair_back(rng, w, d, sh))

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
                parts.append(pr.cyl(lt / 2, foot, top, 16) if rnd else pr.beam(foot, top, lt))
        if rng.random() < 0.4:  # stretchers
            ys = u(0.08, 0.2)
            parts.extend(pr.symmetric([pr.span((xs - 0.01, ys, -zs), (xs + 0.01, ys + 0.02, zs))]))
            parts.append(pr.span((-xs, ys, -0.01), (xs, ys + 0.02, 0.01)))
    elif legs == 1:
        col_r, y_star = u(0.02, 0.035), u(0.05, 0.08)
        parts.append(pr.cyl(col_r, (0, y_star, 0), (0, y_under, 0), 24))
        parts.append(pr.span((-0.12, y_under - 0.03, -0.12), (0.12, y_under, 0.12)))
        arm = u(0.25, 0.33)
        casters = rng.random() < 0.7
        for k in range(5):
            a = k * 2 * np.pi / 5 + np.pi / 2
            tip = (arm * np.cos(a), y_star - 0.03, arm * np.sin(a))
            parts.append(pr.beam((0, y_star, 0), tip, 0.035))
            if casters:
                parts.append(pr.ellipsoid((tip[0], 0.025, tip[2]), (0.025, 0.025, 0.025), 1))
    else:
        r_tube = u(0.01, 0.016)
        xs = w / 2 - 0.03
        for sx in (-1, 1):
            parts.append(
                pr.cyl(r_tube, (sx * xs, r_tube, -d / 2), (sx * xs, r_tube, d / 2 + 0.02), 12)
            )
            for sz in (-1, 1):
                parts.append(
                    pr.cyl(
                        r_tube,
                        (sx * xs, 0, sz * (d / 2 - 0.02)),
                        (sx * xs, y_under, sz * (d / 2 - 0.05)),
                        12,
                    )
                )

    if rng.random() < 0.35:  # armrests
        ya, aw = sh + u(0.18, 0.25), u(0.04, 0.08)
        solid = rng.random() < 0.3
        arm = [pr.span((w / 2, ya - 0.03, -d / 2), (w / 2 + aw, ya, 0.45 * d))]
        if solid:
            arm.append(pr.span((w / 2, sh - st, -d / 2), (w / 2 + aw, ya, 0.4 * d)))
        else:
            arm.append(
                pr.span(
                    (w / 2 + aw / 2 - 0.012, sh - 0.01, 0.35 * d),
                    (w / 2 + aw / 2 + 0.012, ya, 0.35 * d + 0.024),
                )
            )
        parts.extend(pr.symmetric(arm))
    return parts


def _sofa(rng: np.random.Generator) -> list[pr.Part]:
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

    parts = [pr.span((-inner, y0, -depth / 2), (inner, base_top, depth / 2))]
    back = pr.corners((-inner, y0, -depth / 2), (inner, back_h, -depth / 2 + back_t))
    back[[2, 3, 6, 7], 2] -= u(0.0, 0.08)
    parts.append(pr.hexa(back))
    if arms:
        arm = [pr.span((inner, y0, -depth / 2), (width / 2, arm_h, depth / 2))]
        if rng.random() < 0.35:  # rolled arm
            arm.append(
                pr.cyl(
                    arm_w * 0.6,
                    (inner + arm_w / 2, arm_h, -depth / 2),
                    (inner + arm_w / 2, arm_h, depth / 2),
                    24,
                )
            )
        parts.extend(pr.symmetric(arm))

    n = rng.integers(1, 4)
    ct = u(0.1, 0.18)
    gap = 0.01
    cw = 2 * inner / n
    z_back = -depth / 2 + back_t
    for k in range(n):
        x0 = -inner + k * cw
        parts.append(
            pr.span(
                (x0 + gap, base_top, z_back + gap), (x0 + cw - gap, base_top + ct, depth / 2 + 0.02)
            )
        )
        if rng.random() < 0.7:
            bc = pr.corners(
                (x0 + gap, base_top + ct, z_back),
                (x0 + cw - gap, back_h - 0.05, z_back + u(0.12, 0.18)),
            )
            bc[[2, 3, 6, 7], 2] -= 0.06
            parts.append(pr.hexa(bc))

    if rng.random() < 0.25:  # chaise longue on one side
        s = rng.choice([-1, 1])
        chaise_w, ext = u(0.6, 0.8), u(0.5, 0.8)
        x_out = s * inner
        x_in = x_out - s * chaise_w
        lo, hi = (min(x_in, x_out), y0, depth / 2), (max(x_in, x_out), base_top, depth / 2 + ext)
        parts.append(pr.span(lo, hi))
        parts.append(
            pr.span((lo[0] + gap, base_top, depth / 2), (hi[0] - gap, base_top + ct, hi[2]))
        )
        if legs:
            for x in (lo[0] + 0.05, hi[0] - 0.05):
                parts.append(pr.cyl(0.025, (x, 0, hi[2] - 0.05), (x, y0, hi[2] - 0.05), 12))

    if legs:
        for sx in (-1, 1):
            for sz in (-1, 1):
                p = (sx * (width / 2 - 0.06), 0.0, sz * (depth / 2 - 0.06))
                parts.append(pr.frustum(0.018, 0.028, p, (p[0], y0, p[2]), 12))
    return parts


def _bench(rng: np.random.Generator) -> list[pr.Part]:
    u = rng.uniform
    w, d, sh = u(1.1, 2.0), u(0.35, 0.5), u(0.4, 0.48)
    st = u(0.03, 0.06)
    parts: list[pr.Part] = []
    if rng.random() < 0.6:
        n = rng.integers(3, 6)
        sw = d / n
        for k in range(n):
            z0 = -d / 2 + k * sw
            parts.append(pr.span((-w / 2, sh - st, z0 + 0.006), (w / 2, sh, z0 + sw - 0.006)))
    else:
        parts.append(pr.span((-w / 2, sh - st, -d / 2), (w / 2, sh, d / 2)))
    y_under = sh - st
    legs = rng.choice(3)  # four legs, two panels, two A-frames
    xl = w / 2 - u(0.05, 0.25)
    lt = u(0.04, 0.07)
    if legs == 0:
        for sx in (-1, 1):
            for sz in (-1, 1):
                parts.append(
                    pr.span(
                        (sx * xl - lt / 2, 0, sz * (d / 2 - 0.03) - lt / 2),
                        (sx * xl + lt / 2, y_under, sz * (d / 2 - 0.03) + lt / 2),
                    )
                )
        if rng.random() < 0.5:
            parts.append(pr.span((-xl, 0.12, -0.015), (xl, 0.15, 0.015)))
    elif legs == 1:
        for sx in (-1, 1):
            parts.append(
                pr.span(
                    (sx * xl - lt / 2, 0, -d / 2 + 0.02), (sx * xl + lt / 2, y_under, d / 2 - 0.02)
                )
            )
    else:
        for sx in (-1, 1):
            for sz in (-1, 1):
                parts.append(
                    pr.beam((sx * xl, 0, sz * d / 2), (sx * xl, y_under, sz * 0.1 * d), lt, 0.03)
                )
            parts.append(
                pr.span((sx * xl - 0.02, y_under - 0.05, -d / 2), (sx * xl + 0.02, y_under, d / 2))
            )

    if rng.random() < 0.5:  # backrest on posts rising from the rear
        tilt = u(0.05, 0.3)
        bh = u(0.3, 0.45)
        back: list[pr.Part] = [
            pr.span((sx * xl - 0.025, -0.05, -0.02), (sx * xl + 0.025, bh, 0.02)) for sx in (-1, 1)
        ]
        for y in np.linspace(0.06, bh - 0.06, rng.integers(2, 4)):
            back.append(pr.span((-w / 2, y - 0.04, 0.02), (w / 2, y + 0.04, 0.045)))
        for p in back:
            p.apply_transform(pr.pose(pr.rot("x", -tilt), (0, sh, -d / 2)))
        parts.extend(back)
        if rng.random() < 0.5:  # armrests
            ya = sh + u(0.18, 0.25)
            for sx in (-1, 1):
                parts.append(
                    pr.span((sx * xl - 0.025, ya - 0.03, -d / 2), (sx * xl + 0.025, ya, d / 2))
                )
                parts.append(
                    pr.span(
                        (sx * xl - 0.015, sh, d / 2 - 0.05), (sx * xl + 0.015, ya, d / 2 - 0.02)
                    )
                )
    return parts
