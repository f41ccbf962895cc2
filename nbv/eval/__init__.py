"""The evaluator: every view-selection method side by side (``python -m nbv.eval``).

Modules: :mod:`~nbv.eval.config` (settings and their validation), :mod:`~nbv.eval.prepare`
(a mesh folder through the dataset pipeline, cached), :mod:`~nbv.eval.protocol` (method names
to policies, seeds, one episode's record), :mod:`~nbv.eval.disturb` (the disturbance checks),
:mod:`~nbv.eval.timing` (the timing table beside the paper's), :mod:`~nbv.eval.evaluate` (the
loop), :mod:`~nbv.eval.report` (results.json, summary.csv, report.md) and :mod:`~nbv.eval.plots`.
"""
