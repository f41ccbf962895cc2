"""The HDF5 dataset: generation (``python -m nbv.dataset``), layout, and reading.

``nbv.dataset.open(path_or_dir)`` opens one shard file or every shard of a folder as one dataset;
``nbv.dataset.open(path, eps=...)`` also refuses a dataset made with another coverage ``eps``.
The reader (and h5py) is imported on first use, so that algorithms taking the in-memory records
(:mod:`nbv.dataset.records`) never load the storage code.
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
