"""Geometry, the bottom layer above the helpers: numpy and scipy only.

* :mod:`~nbv.geometry.camera`: the pinhole camera, poses looking at the origin, projection and
  back-projection.
* :mod:`~nbv.geometry.viewspace`: the original and permuted 33-view viewspaces, viewspace files.
* :mod:`~nbv.geometry.sph`: spherical-harmonics signatures of clouds.
* :mod:`~nbv.geometry.clouds`: checked ``(N, 3)`` clouds, farthest point sampling.
* :mod:`~nbv.geometry.hull`: convex-hull volume and vertices of clouds of any rank.
* :mod:`~nbv.geometry.scores`: coverage (PC-NBV's test, squared distance < eps**2 in float64,
  eps = sqrt(5e-5)) and VIG of view states (PC-NBV's targets).
"""
