"""``python -m nbv.plan``: plan views for a user's own object, from a mesh (a simulated episode)
or from real captures, and write the plan, its picture and its 3D page.

The planner a robot keeps warm is the library's: ``from nbv.scan import Planner``
(:class:`nbv.scan.planner.Planner`), its one home.

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
