"""``plan.png``: the captured cloud, its convex hull and the cameras, drawn with matplotlib.

A scene with a table or clutter has points outside the object's region: those are drawn faint
grey (``surroundings``), and the axes are framed on the object's region and the candidates, so
that the picture shows the object, not the room."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv.utils.atomic import atomic_path

#: Cloud points drawn at most (an even subset): a picture, not a measurement.
MAX_POINTS = 6000


def _frame(ax, centres: np.ndarray, focus: tuple[np.ndarray, float] | None,
           order: list[int]) -> None:  # fmt: skip
    """Equal axes holding the cameras ``centres`` (drawn axes) and the ``focus`` region (world
    frame), labelled with the world axes ``order`` put on them."""
    lo, hi = centres.min(axis=0), centres.max(axis=0)
    if focus is not None:
        # Framed on the object's region and the cameras: the room around them is cut off.
        middle, radius = np.asarray(focus[0])[order], float(focus[1])
        lo, hi = np.minimum(lo, middle - radius), np.maximum(hi, middle + radius)
    mid, half = 0.5 * (lo + hi), 0.55 * float((hi - lo).max() or 1.0)
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1, 1, 1))
    names = np.array(["x", "y", "z"])[order]
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    ax.set_zlabel(names[2])


def draw_plan(
    path: Path,
    points: np.ndarray,
    hull_vertices: np.ndarray,
    hull_faces: np.ndarray,
    candidates: np.ndarray,
    visited: list[int],
    chosen: list[int],
    title: str,
    up: str = "y",
    surroundings: np.ndarray | None = None,
    focus: tuple[np.ndarray, float] | None = None,
) -> None:
    """Draw a plan to a PNG (whole or not at all).

    Args:
        path: the PNG file.
        points: (N, 3) captured cloud, world frame.
        hull_vertices, hull_faces: (K, 3) float and (F, 3) int, the hull the planner saw.
        candidates: (V, 4, 4) camera-to-world poses (OpenCV axes) of every candidate.
        visited: captured views (indices of ``candidates``), drawn purple.
        chosen: planned views in order, drawn orange and numbered from 1; the rest grey.
        title: the picture's title.
        up: the world axis drawn vertical (``x``, ``y`` or ``z``; a sign is ignored).
        surroundings: (M, 3) captured points outside the object's region, drawn faint grey;
            None: none.
        focus: ``(centre (3,), radius)`` of the object's region, world frame: the axes hold it
            and the candidates (None: the candidates only).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # A cyclic permutation of the axes (it keeps the frame right-handed) puts ``up`` on
    # matplotlib's vertical axis.
    order = {"x": [1, 2, 0], "y": [2, 0, 1], "z": [0, 1, 2]}[up.lstrip("-")]
    points, hull_vertices = np.asarray(points)[:, order], np.asarray(hull_vertices)[:, order]
    rest = np.zeros((0, 3)) if surroundings is None else np.asarray(surroundings)[:, order]
    candidates = np.asarray(candidates).copy()
    candidates[:, :3, :] = candidates[:, order, :]
    fig = plt.figure(figsize=(7, 7))
    ax = fig.add_subplot(projection="3d")
    step = max(1, len(points) // MAX_POINTS)
    p = points[::step]
    if len(rest):
        r = rest[:: max(1, len(rest) // MAX_POINTS)]
        ax.scatter(r[:, 0], r[:, 1], r[:, 2], s=0.3, c="#b0b0b0", alpha=0.5,
                   label="surroundings")  # fmt: skip
    ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=0.5, c="#1f77b4", label="cloud")
    if len(hull_faces):
        ax.plot_trisurf(*np.asarray(hull_vertices).T, triangles=hull_faces, color="#2ca02c",
                        alpha=0.15, linewidth=0)  # fmt: skip
    centres = candidates[:, :3, 3]
    axes_len = 0.15 * float(np.ptp(centres, axis=0).max() or 1.0)
    rest = np.setdiff1d(np.arange(len(candidates)), list(visited) + list(chosen))
    for group, colour, label in ((rest, "#9a9a9a", "candidates"),
                                 (np.asarray(visited, int), "#9467bd", "visited"),
                                 (np.asarray(chosen, int), "#ff7f0e", "chosen")):  # fmt: skip
        if len(group) == 0:
            continue
        c, z = centres[group], candidates[group][:, :3, 2] * axes_len
        ax.scatter(c[:, 0], c[:, 1], c[:, 2], s=25, c=colour, label=label, depthshade=False)
        ax.quiver(c[:, 0], c[:, 1], c[:, 2], z[:, 0], z[:, 1], z[:, 2], color=colour,
                  linewidth=0.8)  # fmt: skip
    for k, v in enumerate(chosen, start=1):
        ax.text(*centres[v], f" {k}", color="#d62728", fontsize=9)
    _frame(ax, centres, focus, order)
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper left", fontsize=8)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
