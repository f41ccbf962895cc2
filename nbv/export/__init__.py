"""Export evaluation runs and datasets to PC-NBV's file layout, to cross-check coverage and AUC.

The other modules:

* :mod:`~nbv.export.config`: The settings of ``python -m nbv.export``: :class:`ExportSettings`, the
  one declaration of ``conf/export.yaml``'s keys (the hydra schema ``export_schema`` is derived from
  it by :mod:`nbv.config.settings`).
* :mod:`~nbv.export.errors`: The one error of an export.
* :mod:`~nbv.export.pcnbv_format`: Writing a dataset and an evaluation's selected views in PC-NBV's
  file layout.
* :mod:`~nbv.export.sources`: What an export reads: a finished evaluation run or a dataset, checked
  before any writing.
* :mod:`~nbv.export.views`: Every view of a model at full resolution, as the dataset's coverage bits
  were computed from it.

Third-party imports: numpy, open3d, scipy, tqdm.
"""
