"""Depth rendering of meshes.

* :mod:`~nbv.render.job`: a render job and the error of a failed one.
* :mod:`~nbv.render.raycast`: Open3D ray casting in this process.
* :mod:`~nbv.render.blender`: the Blender driver (``blender_scripts/render_depth.py`` in a
  subprocess; nothing here imports ``bpy``).
* :mod:`~nbv.render.preflight`: a Blender binary checked once on a tiny scene before a batch.
* :mod:`~nbv.render.backends`: :func:`~nbv.render.backends.render`, a stream of jobs on either.

The other modules:

* :mod:`~nbv.render.noise`: A depth-sensor noise model applied to rendered depth images
  (``renderer.noise``).
* :mod:`~nbv.render.scene`: A table-top scene as a depth camera on a robot sees it, rendered with
  the project's ray caster.

Third-party imports: numpy, trimesh.
"""
