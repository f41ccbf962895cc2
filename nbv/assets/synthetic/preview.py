"""A contact sheet of the synthetic shapes, drawn by Open3D ray casting.

``python -m nbv.preview preview=out.png [seed=S] [per_category=K] [tile=T]`` (or ``make
preview``, :mod:`nbv.preview`) writes one row per category (training ones blue, unseen ones
orange).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv.assets.categories import CATEGORIES, TRAIN_CATEGORIES
from nbv.assets.synthetic.catalogue import make_model, model_rng

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
