"""Geometry, the bottom layer above the helpers (third-party imports: the last line).

* :mod:`~nbv.geometry.camera`: the pinhole camera, poses looking at the origin, projection and
  back-projection.
* :mod:`~nbv.geometry.viewspace`: the original and permuted 33-view viewspaces, viewspace files.
* :mod:`~nbv.geometry.sph`: spherical-harmonics signatures of clouds.
* :mod:`~nbv.geometry.clouds`: checked ``(N, 3)`` clouds, farthest point sampling.
* :mod:`~nbv.geometry.hull`: convex-hull volume and vertices of clouds of any rank.
* :mod:`~nbv.geometry.scores`: coverage (PC-NBV's test, squared distance < eps**2 in float64,
  eps = sqrt(5e-5)) and VIG of view states (PC-NBV's targets).

The other modules:

* :mod:`~nbv.geometry.fusion`: Depth images fused into a triangle mesh: truncated signed distance
  (TSDF) integration.
* :mod:`~nbv.geometry.point_visibility`: Which points of a cloud each camera sees: a z-buffer of the
  points themselves.
* :mod:`~nbv.geometry.raycast`: Depth images of a triangle mesh by ray casting: Open3D's Embree
  scene, one ray per pixel centre.
* :mod:`~nbv.geometry.reconstruction_metrics`: The field's reconstruction and path metrics of a
  set of views: Chamfer distance, F-score, views to reach a coverage, great-circle camera paths
  and the shortest path through views.
* :mod:`~nbv.geometry.symmetry`: Exact symmetries of a viewspace, and what they do to a training
  sample.
* :mod:`~nbv.geometry.union`: Convex-hull volumes of unions of a model's views, grown one view at a
  time and memoised.
* :mod:`~nbv.geometry.viewspace_generators`: Viewspaces for real rigs: generated directions, an up
  axis, and one spec that names them all.

Third-party imports: fpsample, numba, numpy, open3d, scipy, trimesh.
"""
