"""The convex-hull set cover (the paper's planner): plan the views that cover the hull of a
partial cloud.

* :mod:`~nbv.setcover.settings`: :class:`~nbv.setcover.settings.SetCoverSettings`
  (``setcover:`` in the configs), shared by the plan, the policies and the configs.
* :mod:`~nbv.setcover.hull_sampling`: the hull and points drawn on it.
* :mod:`~nbv.setcover.visibility`, :mod:`~nbv.setcover.dilation`: which hull points a view sees,
  analytically, and their ``eps``-dilation.
* :mod:`~nbv.setcover.view_sets`: the view simulation (analytic or ray cast).
* :mod:`~nbv.setcover.greedy`: greedy maximum coverage on packed bit sets.
* :mod:`~nbv.setcover.oneshot`: the whole one-shot plan (the paper's Algorithms 2 and 3).

Third-party imports: numpy, scipy.
"""
