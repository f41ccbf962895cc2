"""The HDF5 dataset: generation (``python -m nbv.dataset``), layout, and reading.

``nbv.dataset.open(path_or_dir)`` opens one shard file or every shard of a folder as one dataset;
``nbv.dataset.open(path, eps=...)`` also refuses a dataset made with another coverage ``eps``.
The reader (and h5py) is imported on first use, so that algorithms taking the in-memory records
(:mod:`nbv.dataset.records`) never load the storage code.

The other modules:

* :mod:`~nbv.dataset.config`: The settings of ``python -m nbv.dataset``: :class:`Settings`, the one
  declaration of ``conf/dataset.yaml``'s keys (the hydra schema ``dataset_schema`` is derived from
  it by :mod:`nbv.config.settings`).
* :mod:`~nbv.dataset.generator`: Dataset generation: render every model of a shard, score its views,
  write the shard file.
* :mod:`~nbv.dataset.generator_settings`: The settings of dataset generation
  (:func:`nbv.dataset.generator.generate`), nested like ``conf/dataset.yaml``:
  :class:`GeneratorSettings` with its groups :class:`Synthetic`, :class:`Renderer` and
  :class:`Noise`.
* :mod:`~nbv.dataset.reader`: Reading a dataset: all shard files of a folder seen as one.
* :mod:`~nbv.dataset.samples`: Training samples: oracle trajectories over a model's views, as
  PC-NBV's networks learn them.
* :mod:`~nbv.dataset.schema`: The HDF5 layout of a dataset shard and the functions that write it
  (the contract between stages: docs/dataset.md, "The shard file").
* :mod:`~nbv.dataset.show`: ``python -m nbv.dataset.show dataset=<file or folder> key=<model>
  [out=PNG]``: draw a model's views.
* :mod:`~nbv.dataset.sources`: Where a dataset's meshes come from: the synthetic categories or a
  catalogue of real files.
* :mod:`~nbv.dataset.views`: A viewspace's depth images as its view record: back-projected, scored,
  subsampled.

Third-party imports: h5py, matplotlib, numpy, threadpoolctl, tqdm.
"""

from __future__ import annotations

from importlib import import_module

__all__ = ["Dataset", "DatasetError", "check_eps", "open", "open_dataset"]

#: Public name -> its name in :mod:`nbv.dataset.reader`.
_READER_NAMES = {
    "Dataset": "Dataset",
    "DatasetError": "DatasetError",
    "check_eps": "check_eps",
    "open": "open_dataset",
    "open_dataset": "open_dataset",
}


def __getattr__(name: str):
    if name in _READER_NAMES:
        return getattr(import_module("nbv.dataset.reader"), _READER_NAMES[name])
    raise AttributeError(f"module 'nbv.dataset' has no attribute {name!r}")
