"""Meshes and where they come from.

* :mod:`~nbv.assets.meshes`: loading, validation, normalisation, surface sampling.
* :mod:`~nbv.assets.catalogues`: ShapeNet, Stanford, BOP (Linemod, HomebrewDB), any folder.
* :mod:`~nbv.assets.mesh_sources`: the one declaration of the mesh sources: name, licence,
  catalogue, installed copy, splits, the evaluator's dataset name.
* :mod:`~nbv.assets.categories`: the one table of the 16 PC-NBV categories.
* :mod:`~nbv.assets.weights`: the network weights and the learned score the package ships.
* :mod:`~nbv.assets.synthetic`: procedural shapes imitating those categories, and their preview.

The other modules:

* :mod:`~nbv.assets.ply`: PLY files whose faces are triangle strips (Stanford's scans: ``element
  tristrips``).
* :mod:`~nbv.assets.real_objects`: Real object meshes that install through the package managers: YCB
  and CGAL's scanned models.

Third-party imports: numpy, tqdm, trimesh.
"""
