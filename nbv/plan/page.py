"""The planner's interactive 3D page: one self-contained HTML file that opens from disk.

The page shows the captured cloud, the convex hull, every candidate camera as a small frustum,
the views already visited, and the chosen views numbered in their order and joined by a path.
plotly.js is embedded in the file (``include_plotlyjs=True``), so the page loads nothing from the
network; it needs a browser with WebGL.

Frames and units: everything is in the world frame of the plan, in its length unit. Camera poses
are camera-to-world 4x4 matrices with OpenCV axes (+x right, +y down, +z forward along the
optical axis), as in :mod:`nbv.geometry.camera`.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import plotly.graph_objects as go

from nbv.utils.atomic import write_text

log = logging.getLogger(__name__)

#: At most this many cloud points go into the page (about 0.3 MB of base64 at float32); the
#: embedded plotly.js is about 4.8 MB, so the page stays well under 10 MB.
MAX_PAGE_POINTS = 20_000

# Fixed colours, so a screenshot can be checked for what was drawn (tests/test_plan_page.py).
POINT_COLOUR = "#1f77b4"
SURROUNDINGS_COLOUR = "#b0b0b0"  # the table, walls and clutter: there, but not the object
HULL_COLOUR = "#2ca02c"
CANDIDATE_COLOUR = "#9a9a9a"
VISITED_COLOUR = "#9467bd"
CHOSEN_COLOUR = "#ff7f0e"
BACKGROUND_COLOUR = "#ffffff"

#: The world axes the page can keep up on screen ("-y": the world's -y points up).
UP_AXES = {
    f"{sign}{axis}": tuple(float(s) if i == k else 0.0 for i in range(3))
    for k, axis in enumerate("xyz")
    for sign, s in (("", 1), ("-", -1))
}

#: Run once plotly has drawn the figure: the page's <html> element gets ``data-plot-ready-ms``,
#: the milliseconds since navigation start (how tests/test_plan_page.py measures rendering).
_READY_SCRIPT = "document.documentElement.dataset.plotReadyMs = performance.now().toFixed(0);"

#: Frustum depth as a fraction of the scene's bounding-box diagonal.
_FRUSTUM_FRACTION = 0.05
#: Half width and half height of a frustum's far rectangle per unit of depth (a 4:3 image at a
#: field of view of about 67 degrees, PC-NBV's camera; only the look matters).
_FRUSTUM_HALF_W = 0.67
_FRUSTUM_HALF_H = 0.5


def subsample_evenly(points: np.ndarray, cap: int) -> np.ndarray:
    """At most ``cap`` rows of ``points``, evenly spaced in index order (deterministic, no RNG).

    Args:
        points: (N, 3) array.
        cap: maximum number of rows kept, >= 1.

    Returns:
        ``points`` itself when N <= cap, else (cap, 3) rows at indices ``round(linspace(0, N-1))``.
        Clouds stored view after view keep a share of every view.
    """
    n = len(points)
    if n <= cap:
        return points
    return points[np.round(np.linspace(0, n - 1, cap)).astype(np.int64)]


def frustum_segments(poses: np.ndarray, depth: float) -> np.ndarray:
    """Polyline vertices of camera frustums, separated by NaN rows (plotly breaks lines there).

    Args:
        poses: (V, 4, 4) camera-to-world, OpenCV axes; the frustum opens along each camera's +z.
        depth: distance from the camera centre to the far rectangle, world units.

    Returns:
        (V * 12, 3) float64: per camera the closed far rectangle (5 vertices), then the two
        diagonals through the apex (apex-corner-... drawn as corner0-apex-corner2 and
        corner1-apex-corner3, 6 vertices), then one NaN separator row.
    """
    w, h = _FRUSTUM_HALF_W * depth, _FRUSTUM_HALF_H * depth
    corners_cam = np.array([[-w, -h, depth], [w, -h, depth], [w, h, depth], [-w, h, depth]])
    rotations, centres = poses[:, :3, :3], poses[:, :3, 3]
    corners = np.einsum("vij,cj->vci", rotations, corners_cam) + centres[:, None, :]  # (V, 4, 3)
    apex = centres[:, None, :]
    nan = np.full((len(poses), 1, 3), np.nan)
    rectangle = corners[:, [0, 1, 2, 3, 0]]
    through_apex = np.concatenate(
        [corners[:, [0]], apex, corners[:, [2]], corners[:, [1]], apex, corners[:, [3]]], axis=1
    )
    return np.concatenate([rectangle, through_apex, nan], axis=1).reshape(-1, 3)


def _check_indices(name: str, indices: Sequence[int], n_views: int) -> np.ndarray:
    """``indices`` as (n,) int64, or one ValueError naming ``name``, the bad value and the range."""
    array = np.asarray(list(indices), dtype=np.int64).reshape(-1)
    bad = array[(array < 0) | (array >= n_views)]
    if len(bad):
        raise ValueError(
            f"{name}: view index {int(bad[0])} is out of range; allowed 0..{n_views - 1} "
            f"(there are {n_views} candidates)"
        )
    return array


def _check_array(name: str, array: np.ndarray, shape: tuple[int | None, ...]) -> np.ndarray:
    """``array`` when its shape matches ``shape`` (None: any length) and it is finite."""
    array = np.asarray(array)
    mismatch = array.ndim != len(shape) or any(
        s is not None and s != a for s, a in zip(shape, array.shape, strict=True)
    )
    if mismatch:
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name}: shape {array.shape} is not {want}")
    if array.dtype.kind == "f" and not np.isfinite(array).all():
        raise ValueError(f"{name}: holds NaN or infinite values; only finite values are allowed")
    return array


def _checked_hull(hull_vertices: np.ndarray, hull_faces: np.ndarray) -> tuple:
    """``(vertices (K, 3), faces (F, 3) int)`` checked: finite, integer faces within range.

    Raises:
        ValueError: naming the argument, the bad value and what is allowed.
    """
    hull_vertices = _check_array("hull_vertices", hull_vertices, (None, 3))
    hull_faces = _check_array("hull_faces", hull_faces, (None, 3))
    if hull_faces.dtype.kind not in "iu":
        raise ValueError(f"hull_faces: dtype {hull_faces.dtype} is not an integer type")
    if len(hull_faces) and (hull_faces.min() < 0 or hull_faces.max() >= len(hull_vertices)):
        raise ValueError(
            f"hull_faces: vertex index {int(hull_faces.max())} or {int(hull_faces.min())} is out "
            f"of range; allowed 0..{len(hull_vertices) - 1}"
        )
    return hull_vertices, hull_faces


def _camera_traces(candidates: np.ndarray, centres: np.ndarray, role: np.ndarray,
                   depth: float) -> list:  # fmt: skip
    """The frustums of the candidates, the visited and the chosen views (``role`` 0, 1, 2),
    each with hover markers at the camera centres."""
    traces = []
    for code, name, colour, width in (
        (0, "candidates", CANDIDATE_COLOUR, 2),
        (1, "visited", VISITED_COLOUR, 4),
        (2, "chosen", CHOSEN_COLOUR, 5),
    ):
        ids = np.flatnonzero(role == code)
        lines = frustum_segments(candidates[ids].astype(np.float64), depth)
        traces.append(
            go.Scatter3d(
                x=lines[:, 0], y=lines[:, 1], z=lines[:, 2], mode="lines", name=name,
                line={"color": colour, "width": width}, hoverinfo="skip", legendgroup=name,
            )
        )  # fmt: skip
        # Invisible-in-legend markers at the centres carry the hover text "view <index>".
        traces.append(
            go.Scatter3d(
                x=centres[ids, 0], y=centres[ids, 1], z=centres[ids, 2], mode="markers",
                marker={"size": 3, "color": colour}, name=name, legendgroup=name,
                showlegend=False, hovertext=[f"view {v}" for v in ids], hoverinfo="text",
            )
        )  # fmt: skip
    return traces


def _cloud_and_hull(drawn: np.ndarray, hull_vertices: np.ndarray, hull_faces: np.ndarray) -> list:
    """The cloud's markers and the hull's semi-transparent mesh."""
    return [
        go.Scatter3d(
            x=drawn[:, 0], y=drawn[:, 1], z=drawn[:, 2], mode="markers", name="cloud",
            marker={"size": 2, "color": POINT_COLOUR}, hoverinfo="skip",
        ),
        go.Mesh3d(
            x=hull_vertices[:, 0], y=hull_vertices[:, 1], z=hull_vertices[:, 2],
            i=hull_faces[:, 0], j=hull_faces[:, 1], k=hull_faces[:, 2], name="hull",
            color=HULL_COLOUR, opacity=0.25, showlegend=True, hoverinfo="skip",
        ),
    ]  # fmt: skip


def _laid_out(figure: go.Figure, title: str, up: str) -> go.Figure:
    """``figure`` titled, on the page's background, with ``up`` kept up on screen."""
    x, y, z = UP_AXES[up]
    figure.update_layout(
        title={"text": title},
        paper_bgcolor=BACKGROUND_COLOUR,
        margin={"l": 0, "r": 0, "t": 40, "b": 0},
        scene={
            "aspectmode": "data",
            "camera": {"up": {"x": x, "y": y, "z": z}},
            "bgcolor": BACKGROUND_COLOUR,
        },
        legend={"itemsizing": "constant"},
    )
    return figure


def _order_trace(centres: np.ndarray, chosen_ids: np.ndarray) -> go.Scatter3d:
    """The chosen views' path, numbered 1..n at their camera centres."""
    path = centres[chosen_ids]
    return go.Scatter3d(
        x=path[:, 0], y=path[:, 1], z=path[:, 2], mode="lines+markers+text", name="order",
        line={"color": CHOSEN_COLOUR, "width": 3, "dash": "dash"},
        marker={"size": 5, "color": CHOSEN_COLOUR},
        text=[str(i + 1) for i in range(len(chosen_ids))],
        textposition="top center", textfont={"size": 16, "color": "#000000"},
        hovertext=[f"#{i + 1}: view {v}" for i, v in enumerate(chosen_ids)],
        hoverinfo="text",
    )  # fmt: skip


def build_plan_figure(
    *,
    points: np.ndarray,
    hull_vertices: np.ndarray,
    hull_faces: np.ndarray,
    candidates: np.ndarray,
    chosen: Sequence[int],
    visited: Sequence[int],
    title: str,
    up: str = "y",
    max_points: int = MAX_PAGE_POINTS,
    surroundings: np.ndarray | None = None,
) -> go.Figure:
    """The plotly figure of a plan (pure: no files, no browser).

    Args:
        points: (N, 3) captured cloud, world frame; N may be 0. At most ``max_points`` evenly
            spaced rows are drawn (:func:`subsample_evenly`).
        hull_vertices: (K, 3) convex-hull vertices, world frame.
        hull_faces: (F, 3) int triangles indexing ``hull_vertices``; drawn semi-transparent.
        candidates: (V, 4, 4) camera-to-world poses of every candidate view, OpenCV axes.
        chosen: the planned views in their order (indices into ``candidates``, no repeats); drawn
            numbered 1..n and joined by a path.
        visited: views already captured (indices into ``candidates``). A view both visited and
            chosen is drawn as chosen.
        title: the page's title.
        up: the world axis kept up on screen, one of ``UP_AXES`` ("x", "y", "z", "-x", "-y",
            "-z").
        max_points: cap on drawn cloud points.
        surroundings: (M, 3) captured points outside the object's region (a table, walls,
            clutter), drawn faint grey and left out of the frustums' scale; None or empty: none.

    Traces, in order (names are the legend entries): "cloud", "hull", "candidates",
    "visited", "chosen", "order" (the path and the numbers at the chosen camera centres), and
    "surroundings" last when there are any.

    Raises:
        ValueError: one message naming the argument, the bad value and what is allowed.
    """
    if up not in UP_AXES:
        raise ValueError(f"up: {up!r} is not one of {sorted(UP_AXES)}")
    points = _check_array("points", points, (None, 3))
    hull_vertices, hull_faces = _checked_hull(hull_vertices, hull_faces)
    candidates = _check_array("candidates", candidates, (None, 4, 4))
    n_views = len(candidates)
    if n_views == 0:
        raise ValueError("candidates: no camera poses; at least one is needed")
    chosen_ids = _check_indices("chosen", chosen, n_views)
    visited_ids = _check_indices("visited", visited, n_views)
    if len(np.unique(chosen_ids)) != len(chosen_ids):
        raise ValueError(f"chosen: repeats a view ({chosen_ids.tolist()}); each view at most once")

    drawn = subsample_evenly(points.astype(np.float32, copy=False), max_points)
    if len(drawn) < len(points):
        log.info("plan page: drawing %d of %d cloud points", len(drawn), len(points))
    centres = candidates[:, :3, 3].astype(np.float64)
    extent = np.concatenate([centres, hull_vertices.reshape(-1, 3), drawn.reshape(-1, 3)])
    diagonal = float(np.linalg.norm(extent.max(axis=0) - extent.min(axis=0)))
    depth = _FRUSTUM_FRACTION * (diagonal if diagonal > 0 else 1.0)

    role = np.zeros(n_views, dtype=np.int8)  # 0 candidate, 1 visited, 2 chosen
    role[visited_ids] = 1
    role[chosen_ids] = 2
    traces: list[go.BaseTraceType] = _cloud_and_hull(drawn, hull_vertices, hull_faces)
    traces += _camera_traces(candidates, centres, role, depth)
    rest = None
    if surroundings is not None and len(surroundings):
        rest = _check_array("surroundings", surroundings, (None, 3))
    traces.append(_order_trace(centres, chosen_ids))
    if rest is not None:
        rest = subsample_evenly(rest.astype(np.float32), max_points)
        traces.append(go.Scatter3d(
            x=rest[:, 0], y=rest[:, 1], z=rest[:, 2], mode="markers", name="surroundings",
            marker={"size": 1.5, "color": SURROUNDINGS_COLOUR, "opacity": 0.3}, hoverinfo="skip",
        ))  # fmt: skip
    return _laid_out(go.Figure(data=traces), title, up)


def write_plan_page(path: Path, **scene: Any) -> None:
    """Write the plan's self-contained interactive page to ``path`` (whole or not at all).

    ``scene``: the keyword arguments of :func:`build_plan_figure`. plotly.js is embedded, so the
    file opens from disk with no network. The page fills the browser window.

    Raises:
        ValueError: bad input, one message naming the argument; nothing is written then.
    """
    figure = build_plan_figure(**scene)
    html = figure.to_html(
        include_plotlyjs=True,
        full_html=True,
        default_width="100%",
        default_height="100vh",
        # No MathJax from a CDN (include_mathjax stays False): nothing to fetch.
        config={"displaylogo": False, "responsive": True},
        post_script=_READY_SCRIPT,
    )
    # Full window, no scroll bars: the plot's div is 100vh high and the body has no margin.
    html = html.replace("<head>", "<head><style>html,body{margin:0;overflow:hidden}</style>", 1)
    write_text(Path(path), html)
    log.info("wrote %s (%.1f MB)", path, len(html.encode("utf-8")) / 1e6)
