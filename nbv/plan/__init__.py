"""``python -m nbv.plan``: plan views for a user's own object, from a mesh (a simulated episode)
or from real captures, and write the plan, its picture and its 3D page.

The planner a robot keeps warm is the library's, :class:`nbv.scan.planner.Planner`; it is also
importable from here (``from nbv.plan import Planner``), as it was before ``nbv.scan`` existed.

The other modules:

* :mod:`~nbv.plan.config`: The settings of ``python -m nbv.plan``: :class:`PlanSettings`, the one
  declaration of ``conf/plan.yaml``'s keys (the hydra schema ``plan_schema`` is derived from it by
  :mod:`nbv.config.settings`).
* :mod:`~nbv.plan.example`: ``python -m nbv.plan.example out=OUT.obj [category=chair] [seed=0]``: a
  synthetic model as a mesh file, the object of the worked example of planning for your own object.
* :mod:`~nbv.plan.mesh`: A whole episode on simulated captures of a mesh (``python -m nbv.plan
  mesh=...``).
* :mod:`~nbv.plan.output`: What a plan writes into its run folder: ``plan.json``, ``cloud.ply``,
  ``plan.png`` and ``plan.html``, each whole or not at all.
* :mod:`~nbv.plan.page`: The planner's interactive 3D page: one self-contained HTML file that opens
  from disk.
* :mod:`~nbv.plan.picture`: ``plan.png``: the captured cloud, its convex hull and the cameras, drawn
  with matplotlib.

Third-party imports: matplotlib, numpy, open3d, plotly, trimesh.
"""

__all__ = ["NextView", "Planner"]


def __getattr__(name: str):
    # Imported on first use: the planner pulls in the policies (and torch), which the command's
    # config checks and `python -m nbv.plan.example` do not need.
    if name in __all__:
        from nbv.scan import planner

        return getattr(planner, name)
    raise AttributeError(f"module 'nbv.plan' has no attribute {name!r}")
