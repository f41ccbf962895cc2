"""Convex-hull set cover: next-best-view planning on the hull of a partial cloud.

* :mod:`~nbv.planning.settings`: :class:`~nbv.planning.settings.PlannerSettings`, shared by the
  planner, the policies and the evaluation config.
* :mod:`~nbv.planning.hull_sampling`: the hull and points drawn on it.
* :mod:`~nbv.planning.visibility`, :mod:`~nbv.planning.dilation`: which hull points a view sees,
  analytically, and their ``eps``-dilation.
* :mod:`~nbv.planning.view_sets`: the view simulation (analytic or ray cast).
* :mod:`~nbv.planning.set_cover`: greedy maximum coverage on packed bit sets.
* :mod:`~nbv.planning.planner`: the whole plan (the paper's Algorithms 2 and 3).
"""
