"""Planning views from a partial cloud, by two families of methods.

Convex-hull set cover (the paper's planner):

* :mod:`~nbv.planning.settings`: :class:`~nbv.planning.settings.PlannerSettings`, shared by the
  planner, the policies and the evaluation config, and the volumetric settings.
* :mod:`~nbv.planning.hull_sampling`: the hull and points drawn on it.
* :mod:`~nbv.planning.visibility`, :mod:`~nbv.planning.dilation`: which hull points a view sees,
  analytically, and their ``eps``-dilation.
* :mod:`~nbv.planning.view_sets`: the view simulation (analytic or ray cast).
* :mod:`~nbv.planning.set_cover`: greedy maximum coverage on packed bit sets.
* :mod:`~nbv.planning.planner`: the whole plan (the paper's Algorithms 2 and 3).

Volumetric information gain (``ig``, ``ig_learned`` and their variants):

* :mod:`~nbv.planning.occupancy`: the occupancy map, updated as OctoMap updates its octree.
* :mod:`~nbv.planning.raytrace`: voxel traversal of rays through the map's grid.
* :mod:`~nbv.planning.information_gain`: a candidate view's gain, summed over its rays.
* :mod:`~nbv.planning.view_features`, :mod:`~nbv.planning.gain_scorer`: what a candidate would
  see as a few numbers, and ``ig_learned``'s small perceptron over them.
"""
