"""The HDF5 dataset: generation (``python -m nbv.dataset``), layout, and reading.

``nbv.dataset.open(path_or_dir)`` opens one shard file or every shard of a folder as one dataset.
"""

from nbv.dataset.reader import Dataset, DatasetError, open_dataset
from nbv.dataset.reader import open_dataset as open  # noqa: A001 - the documented entry point

__all__ = ["Dataset", "DatasetError", "open", "open_dataset"]
