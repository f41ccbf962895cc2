"""Benchmark rows of the warm planner (:class:`nbv.scan.planner.Planner`) in a robot's loop.

The scene: a synthetic cabinet on a table with a wall behind it (:mod:`nbv.render.scene`), seen by
a 640 x 480 depth camera with the sensor's noise, dropout, missing pixels and 1.2 m range. The
planner takes the table scene's first view without ``object.*`` (the object is estimated), then
decides ``decisions`` times, each after the view it chose before is rendered and added.

* **cold**: the first decision of a new planner in this process (the object estimated, the
  candidates limited and traced, the policy built, the map's first view);
* **warm** (``ours``): the median of ``add_view`` of a new 640 x 480 view plus ``next_view``;
* **reference**: the same last decision by a fresh planner on the saved views
  (:meth:`~nbv.scan.planner.Planner.load`: what ``python -m nbv.plan captures=...`` does after
  reading the files, without its process start); it must choose the same view.

Rendering the views is not timed.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from nbv.geometry.camera import Intrinsics

#: The issue's target for a warm decision, seconds (2 cores, map update included).
TARGET = 0.050
#: The camera: a 640 x 480 depth sensor.
CAMERA = Intrinsics.centred(640, 480, 476.0)
#: The planner's settings: a hemisphere of 40 views 0.45 m out, above 10 degrees.
SETTINGS = {
    "viewspace": {"kind": "hemisphere", "n": 40, "up": "z", "radius": 0.45},
    "candidates": {"min_elevation": 10.0},
}
#: The sensor's range, metres.
RANGE = 1.2


def _scene():
    from nbv.assets.synthetic.catalogue import make_model

    vertices, faces = make_model("cabinet", np.random.default_rng(1))
    # ShapeNet's Y up turned to the table's Z up.
    return vertices[:, [0, 2, 1]] * np.array([1.0, -1.0, 1.0]), faces


def warm_decisions(method: str, decisions: int = 6) -> dict:
    """Time a planner of ``method`` in a loop on the table scene (module docstring).

    Returns:
        ``{"cold": s, "warm": [s, ...], "fresh": s, "views": [...], "same": bool}``: seconds of
        the first decision, of each warm one, of the fresh planner's last decision; the chosen
        viewspace indices; whether the fresh planner chose the warm one's last view.
    """
    from nbv.render.scene import SceneSettings, table_scene
    from nbv.scan.planner import Planner

    mesh = _scene()
    scene = table_scene(*mesh, CAMERA, SceneSettings(views=1), seed=0)
    n_views = decisions + 2
    planner = Planner(method=method, n_views=n_views, **SETTINGS)
    t0 = time.perf_counter()
    planner.add_view(scene.depth[0], scene.poses[0], CAMERA, max_range=RANGE)
    step = planner.next_view()
    cold = time.perf_counter() - t0
    views, warm = [step.view], []
    depths, poses = [scene.depth[0]], [scene.poses[0]]
    for k in range(decisions):
        depth = table_scene(*mesh, CAMERA, SceneSettings(), seed=k + 1,
                            poses=step.opencv[None]).depth[0]  # fmt: skip
        depths.append(depth)
        poses.append(step.opencv)
        t0 = time.perf_counter()
        planner.add_view(depth, step.opencv, CAMERA, max_range=RANGE)
        step = planner.next_view()
        warm.append(time.perf_counter() - t0)
        views.append(step.view)
    # The same last decision by a fresh planner on the saved views (placed as the warm one
    # was: its frame and support came from the first view).
    with tempfile.TemporaryDirectory() as tmp:
        fresh_planner = Planner.load(planner.save(Path(tmp) / "scan"))
        t0 = time.perf_counter()
        again = fresh_planner.next_view()
        fresh = time.perf_counter() - t0
    return {"cold": cold, "warm": warm, "fresh": fresh, "views": views,
            "same": again.view == step.view}  # fmt: skip


def warm_rows(decisions: int = 6) -> list[dict]:
    """The rows: ``ig`` and ``ig_learned`` deciding warm in a loop on 640 x 480 views."""
    rows = []
    for method in ("ig", "ig_learned"):
        run = warm_decisions(method, decisions)
        warm = float(np.median(run["warm"]))
        rows.append(dict(
            name=f"Planner {method} warm decision (add_view 640x480 + next_view)",
            ours=warm, reference=run["fresh"], ratio=run["fresh"] / warm, target=TARGET,
            note=f"median of {decisions}; cold first decision {run['cold']:.3f} s; reference: a "
                 "fresh planner's same decision" + ("" if run["same"] else " (CHOSE ANOTHER VIEW)"),
        ))  # fmt: skip
    return rows
