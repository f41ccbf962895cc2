"""Draw meshes side by side as a PNG, shaded, from one viewpoint (a developer tool for the docs).

    python scripts/draw_meshes.py MESH [MESH ...] --titles "the mesh" "its reconstruction" \
        --out docs/ycb_drill_reconstruction.png

Each mesh is read with :func:`nbv.assets.meshes.load_mesh` (so any file the toolkit reads) and
shown in its own units, every panel on the same axes limits (the first mesh's bounding box), lit
by a fixed direction. ``--up y`` (default) or ``z`` names the up axis.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from nbv.assets.meshes import MeshError, load_mesh  # noqa: E402

#: Light direction (in the drawn frame, z up), normalised below.
_LIGHT = np.array([0.4, -0.6, 0.7])


def shaded_faces(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, 3, 3) triangle corners and (F,) brightness in [0.25, 1] (Lambert, two-sided)."""
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = normals / np.where(lengths > 0, lengths, 1.0)
    light = _LIGHT / np.linalg.norm(_LIGHT)
    return tri, 0.25 + 0.75 * np.abs(normals @ light)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("meshes", nargs="+", type=Path)
    p.add_argument("--titles", nargs="*", default=None)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--up", choices=("y", "z"), default="y")
    p.add_argument("--elev", type=float, default=20.0, help="view elevation, degrees")
    p.add_argument("--azim", type=float, default=-60.0, help="view azimuth, degrees")
    args = p.parse_args(argv)
    titles = args.titles or [m.name for m in args.meshes]
    if len(titles) != len(args.meshes):
        p.error(f"--titles: {len(titles)} titles for {len(args.meshes)} meshes")
    try:
        meshes = [load_mesh(m) for m in args.meshes]
    except MeshError as err:
        print(f"draw_meshes: {err}", file=sys.stderr)
        return 2
    # Drawn with z up: a y-up mesh (x, y, z) is drawn as (x, -z, y).
    turn = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]) if args.up == "y" else np.eye(3)
    first = meshes[0].vertices @ turn.T
    centre = 0.5 * (first.min(axis=0) + first.max(axis=0))
    half = 0.5 * np.ptp(first, axis=0).max()
    fig = plt.figure(figsize=(4.0 * len(meshes), 3.4))
    for i, (mesh, title) in enumerate(zip(meshes, titles, strict=True)):
        ax = fig.add_subplot(1, len(meshes), i + 1, projection="3d")
        tri, shade = shaded_faces(mesh.vertices @ turn.T, mesh.faces)
        colours = np.clip(shade[:, None] * np.array([0.55, 0.7, 0.9]), 0, 1)
        ax.add_collection3d(Poly3DCollection(tri, facecolors=colours, linewidths=0))
        for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
            setter(c - half, c + half)
        ax.set_box_aspect((1, 1, 1), zoom=1.15)
        ax.view_init(elev=args.elev, azim=args.azim)
        ax.set_axis_off()
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
