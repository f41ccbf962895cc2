"""Every view of a model at full resolution, as the dataset's coverage bits were computed from it.

The dataset's coverage bits come from the full-resolution back-projection of each view (float64
world points); what it stores may be a subsample (``points_per_view``) in float32. PC-NBV's
scripts score the PCD files, so an export that they score as we do needs the full views, and the
values written must cover exactly the ground-truth points the bits say. :class:`FullViews` gets
them one of two ways, decided per dataset before anything is written:

* ``stored``: the dataset kept every point (``points_per_view`` 0); its float32 points are used.
* ``recast``: the dataset was ray cast (``renderer.backend=raycast``, exactly reproducible): the
  source mesh is rebuilt (a synthetic shape from its seed, category and index; a file from its
  ``source_path``), normalised, checked against the stored centre and scale, and ray cast again
  from the stored poses with the dataset's camera (and its depth-noise model, same seed).

A dataset with neither (subsampled views rendered by Blender) is refused in one line that says how
to make one. Stored half-float depth (``keep_depth``) is no way: back-projecting it moves points
by up to 2^-11 of their depth, and on 640 x 480 views of 16,384-point ground truths that changed
1,185-1,592 coverage bits a model (three synthetic models measured).

Every view is checked: the coverage of the cloud to be written, by :func:`covered_mask` with the
dataset's eps, must equal the stored bits. The float32 copy is written when it passes (nearly
always: three 640 x 480 models, 198 views, no difference); otherwise the float64 points, which the
bits were computed from. A view whose cloud does not reproduce its bits stops the export with the
model, viewspace and views named. An empty view is written as the single point :data:`EMPTY_VIEW`
(as PC-NBV's own renderer does): an empty cloud would give every ground-truth point distance 0 in
PC-NBV's nearest-neighbour kernel, i.e. full coverage; (1, 1, 1) is at least 1.23 from an object
inside the sphere of radius 0.5, so it covers nothing, as the empty view does in ours.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from nbv.dataset.reader import Dataset
from nbv.dataset.records import ModelData
from nbv.dataset.sources import SourceModel, list_models, load_normalised
from nbv.export.errors import ExportError
from nbv.geometry.camera import backproject
from nbv.geometry.raycast import raycast_depth
from nbv.geometry.scores import coverage_bits
from nbv.render.noise import DepthNoise, noisy_depth
from nbv.utils.seeding import named_rng

__all__ = ["EMPTY_VIEW", "ExportError", "FullViews", "ViewNotes"]

#: The one point an empty view is written as: far from any normalised object (radius 0.5).
EMPTY_VIEW = np.array([[1.0, 1.0, 1.0]], dtype=np.float32)


@dataclass
class ViewNotes:
    """What :meth:`FullViews.views` did for one model and viewspace.

    Attributes:
        way: ``stored`` or ``recast``.
        float64: views whose float32 copy would change a coverage bit, written in float64.
        empty: views with no point, written as :data:`EMPTY_VIEW`.
    """

    way: str = ""
    float64: list[int] = field(default_factory=list)
    empty: list[int] = field(default_factory=list)


def _config(ds: Dataset) -> dict:
    """The generation settings a dataset recorded (root attribute ``config``; {} when absent)."""
    text = ds.attrs.get("config")
    return json.loads(text) if isinstance(text, str) and text else {}


def _where(ds: Dataset) -> str:
    return str(ds.files[0].parent if len(ds.files) > 1 else ds.files[0])


class FullViews:
    """How one dataset's full-resolution views are had (see the module docstring).

    Args:
        ds: the dataset.
        threads: ray-casting threads (0 = all cores).

    Attributes:
        ways: the ways to try, in order (``stored`` first: it costs nothing).

    Raises:
        ExportError: the dataset has neither way; one line saying how to make one that has.
    """

    def __init__(self, ds: Dataset, threads: int = 0):
        self.ds, self.threads = ds, threads
        self.config = _config(ds)
        #: The depth-noise model's settings (None when off): re-casting then needs every
        #: viewspace of a model (:meth:`_recast`).
        self.noise: dict | None = self.config.get("noise")
        self.eps = float(ds.attrs["eps"])
        kept = self.config.get("points_per_view")
        backend = self.config.get("backend")
        self.ways = [w for w, ok in (("stored", kept == 0), ("recast", backend == "raycast")) if ok]
        if not self.ways:
            raise ExportError(
                f"{_where(ds)}: its views keep {kept} points each (points_per_view) and were "
                f"rendered by {backend}, so the export cannot write the full views PC-NBV's "
                "coverage needs; make the dataset with points_per_view=0, or with "
                "renderer.backend=raycast (the export re-casts those exactly)"
            )
        self._synthetic: dict[str, SourceModel] | None = None
        # The last model's re-cast views (key, viewspace -> clouds): one cast a model.
        self._cast: tuple[str, dict[str, list[np.ndarray]]] | None = None

    def views(self, model: ModelData, viewspace: str) -> tuple[list[np.ndarray], ViewNotes]:
        """Every view of ``viewspace`` as the (N_v, 3) cloud to write, float32 (float64 where
        float32 would change a coverage bit), world frame; each checked against the bits.

        Raises:
            ExportError: no way reproduces some view's coverage bits (names the views).
        """
        view = model.views[viewspace]
        failed: list[int] = []
        for way in self.ways:
            if way == "stored":
                clouds = [view.view_points(v) for v in range(len(view.poses))]
            else:
                clouds = self._recast(model, viewspace)
            written, notes, failed = self._checked(clouds, model, viewspace)
            if not failed:
                notes.way = way
                return written, notes
        raise ExportError(
            f"{_where(self.ds)}: model {model.key!r}, viewspace {viewspace}: views {failed} "
            f"({' then '.join(self.ways)}) do not cover the ground-truth points their coverage "
            "bits say; the dataset's source or its renderer changed since it was made"
        )

    def _checked(
        self, clouds: list[np.ndarray], model: ModelData, viewspace: str
    ) -> tuple[list[np.ndarray], ViewNotes, list[int]]:
        """(clouds to write, notes, views that reproduce no bits) of one way's clouds."""
        bits = model.views[viewspace].coverage
        written, notes, failed = [], ViewNotes(), []
        for v, cloud in enumerate(clouds):
            if len(cloud) == 0:
                notes.empty.append(v)
                cloud = EMPTY_VIEW
            # float32 first: the size PC-NBV's files have; float64 only when it must.
            choices = [np.asarray(cloud, dtype=np.float32)]
            if cloud.dtype == np.float64:
                choices.append(cloud)
            for choice in choices:
                if np.array_equal(coverage_bits([choice], model.gt_points, self.eps)[0], bits[v]):
                    written.append(choice)
                    if choice.dtype == np.float64:
                        notes.float64.append(v)
                    break
            else:
                failed.append(v)
        return written, notes, failed

    def _source(self, model: ModelData) -> SourceModel:
        """The record :func:`load_normalised` rebuilds the model's mesh from."""
        if model.source != "synthetic":
            return SourceModel(model.key, model.category, model.split, model.source,
                               model.source_path)  # fmt: skip
        if self._synthetic is None:
            listed = list_models("synthetic", counts=self.config.get("counts"))
            self._synthetic = {m.key: m for m in listed}
        if model.key not in self._synthetic:
            raise ExportError(
                f"{_where(self.ds)}: synthetic model {model.key!r} is not in the catalogue of "
                f"counts {self.config.get('counts')}"
            )
        return self._synthetic[model.key]

    def _recast(self, model: ModelData, viewspace: str) -> list[np.ndarray]:
        """The viewspace's full views ray cast again: (N_v, 3) float64 world points each."""
        if self._cast is None or self._cast[0] != model.key or viewspace not in self._cast[1]:
            self._cast = (model.key, self._cast_model(model, viewspace))
        return self._cast[1][viewspace]

    def _cast_model(self, model: ModelData, viewspace: str) -> dict[str, list[np.ndarray]]:
        """viewspace -> its views ray cast again, for ``viewspace`` (every viewspace when the
        dataset has a noise model)."""
        mesh, center, scale = load_normalised(self._source(model), model.seed)
        if not (np.array_equal(center, model.center) and scale == model.scale):
            raise ExportError(
                f"{_where(self.ds)}: model {model.key!r}: its source {model.source_path} "
                f"normalises with centre {center.tolist()} and scale {scale!r}, the dataset "
                f"recorded {np.asarray(model.center).tolist()} and {model.scale!r}: the mesh "
                "changed since the dataset was made"
            )
        # With noise the generator drew it over every viewspace's views in its order (the
        # recorded config lists the viewspaces sorted, as the default order is): cast them all.
        # (The caller reads every viewspace of the model then.)
        names = list(self.config.get("viewspaces", {})) if self.noise else [viewspace]
        poses = np.concatenate([model.views[n].poses for n in names])
        camera = self.ds.intrinsics
        depth = raycast_depth(mesh.vertices, mesh.faces, poses, camera, threads=self.threads)
        if self.noise:
            rng = named_rng(int(self.ds.attrs["seed"]), "depth-noise", model.key)
            depth = noisy_depth(depth, camera, DepthNoise(**self.noise), rng)
        clouds = [backproject(depth[i], camera, poses[i]) for i in range(len(poses))]
        out, first = {}, 0
        for n in names:
            count = len(model.views[n].poses)
            out[n], first = clouds[first : first + count], first + count
        return out
