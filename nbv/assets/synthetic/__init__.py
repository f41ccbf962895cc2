"""Procedural stand-ins for ShapeNet: 16 categories of meshes assembled from primitives.

Nobody can download ShapeNet here, so the default dataset is made on the fly. Each category
imitates one of PC-NBV's 8 training or 8 unseen ShapeNet categories (names:
:mod:`nbv.assets.categories`). A model is a concatenation of trimesh primitives (boxes, cylinders,
frusta, cones, ellipsoids, capsules, tori, annuli and "hexahedra": boxes whose 8 corners are moved,
used for swept wings, hulls and slanted cabins), with randomised proportions and optional or
variable parts, so that shapes within a category differ and categories differ in their structure
(legs, gaps, shelves, wheels, wings). Overlapping parts are simply concatenated: no booleans, so
surfaces hidden inside other parts exist, as in ShapeNet.

Frame (ShapeNet's OBJ frame): Y is up, the object's front faces +z (cars, airplanes, vessels,
buses, motorbikes, skateboards and pistols are long along z and point to +z; chairs, sofas, beds,
cabinets and bookshelves face +z; guitars stand upright, neck along +y, strings facing +z). Like
ShapeNetCore v2's ``model_normalized.obj`` every model is centred on its bounding-box centre and
scaled so that the bounding-box diagonal is 1, so it fits in a sphere of radius 0.5.

* :func:`make_model` builds one model of a category from a ``numpy.random.Generator``.
* :func:`catalogue` lists the models of the default dataset (:data:`DEFAULT_COUNTS`);
  :func:`build` makes one of them from a seed, independently of every other model.
* :func:`preview` draws a contact sheet (``python -m nbv.preview preview=out.png``).

Modules, imports going one way (each imports only the ones above it):

* :mod:`~nbv.assets.synthetic.primitives`: the mesh primitives and their mirroring;
* the builders by family: :mod:`~nbv.assets.synthetic.craft` (airplane, vessel),
  :mod:`~nbv.assets.synthetic.vehicles` (car, bus, motorbike, skateboard),
  :mod:`~nbv.assets.synthetic.seating` (chair, sofa, bench),
  :mod:`~nbv.assets.synthetic.furniture` (table, cabinet, bed, bookshelf),
  :mod:`~nbv.assets.synthetic.objects` (lamp, guitar, pistol);
* :mod:`~nbv.assets.synthetic.catalogue`: the category -> builder table, :func:`make_model`, the
  catalogue, the per-model generators and :func:`build`;
* :mod:`~nbv.assets.synthetic.preview`: the contact sheet.
"""

from nbv.assets.synthetic.catalogue import (
    DEFAULT_COUNTS,
    SPLITS,
    SyntheticEntry,
    build,
    catalogue,
    make_model,
    model_rng,
)
from nbv.assets.synthetic.preview import preview, render_tile

__all__ = [
    "DEFAULT_COUNTS",
    "SPLITS",
    "SyntheticEntry",
    "build",
    "catalogue",
    "make_model",
    "model_rng",
    "preview",
    "render_tile",
]
