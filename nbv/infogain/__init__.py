"""Volumetric information gain (``ig``, ``ig_learned`` and their variants): score a candidate view
by what an occupancy map says it would reveal.

* :mod:`~nbv.infogain.settings`: :class:`~nbv.infogain.settings.InfoGainSettings` (``infogain:`` in
  the configs).
* :mod:`~nbv.infogain.occupancy`: the occupancy map, updated as OctoMap updates its octree.
* :mod:`~nbv.infogain.raytrace`: voxel traversal of rays through the map's grid.
* :mod:`~nbv.infogain.gain`: a candidate view's gain, summed over its rays.
* :mod:`~nbv.infogain.view_features`, :mod:`~nbv.infogain.gain_scorer`: what a candidate would
  see as a few numbers, and ``ig_learned``'s small perceptron over them.

Third-party imports: numba, numpy, scipy.
"""
