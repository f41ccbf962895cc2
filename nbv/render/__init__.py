"""Depth rendering of meshes.

* :mod:`~nbv.render.job`: a render job and the error of a failed one.
* :mod:`~nbv.render.raycast`: Open3D ray casting in this process.
* :mod:`~nbv.render.blender`: the Blender driver (``blender_scripts/render_depth.py`` in a
  subprocess; nothing here imports ``bpy``).
* :mod:`~nbv.render.preflight`: a Blender binary checked once on a tiny scene before a batch.
* :mod:`~nbv.render.backends`: :func:`~nbv.render.backends.render`, a stream of jobs on either.
"""
