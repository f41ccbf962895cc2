"""Meshes and where they come from.

* :mod:`~nbv.assets.meshes`: loading, validation, normalisation, surface sampling.
* :mod:`~nbv.assets.catalogues`: ShapeNet, Stanford, BOP (Linemod, HomebrewDB), any folder.
* :mod:`~nbv.assets.categories`: the one table of the 16 PC-NBV categories.
* :mod:`~nbv.assets.synthetic`: procedural shapes imitating those categories, and their preview.
"""
