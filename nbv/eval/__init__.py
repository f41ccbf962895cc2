"""The evaluator: every view-selection method side by side (``python -m nbv.eval``).

Modules: :mod:`~nbv.eval.config` (settings and their validation), :mod:`~nbv.eval.prepare`
(a mesh folder through the dataset pipeline, cached), :mod:`~nbv.eval.protocol` (seeds and
one episode's record), :mod:`~nbv.eval.disturb` (the disturbance checks),
:mod:`~nbv.eval.timing` (the timing table beside the paper's), :mod:`~nbv.eval.evaluate` (the
loop), :mod:`~nbv.eval.report` (results.json, summary.csv, report.md) and :mod:`~nbv.eval.plots`.

The other modules:

* :mod:`~nbv.eval.claims`: The paper's claims checked against the measured numbers, each by a paired
  interval (claim 5, the completed hull, is the one the paper names as a contribution without
  measuring it).
* :mod:`~nbv.eval.completion_quality`: How well a completion network completes captured clouds:
  CD-L1 and F-score against the ground truth, next to the partial cloud itself and its best mirror
  completion.
* :mod:`~nbv.eval.config_checks`: The checks the evaluator's settings share
  (:mod:`nbv.eval.config`): a list of names, a viewspace, a nested group's ranges, each refusal one
  :class:`~nbv.utils.fields.ConfigError` naming the key path.
* :mod:`~nbv.eval.curve`: ``python -m nbv.eval.curve runs=[<run folder>,...] [out=outputs/curve]``:
  the learning curve of a learner over the number of training models.
* :mod:`~nbv.eval.episode_log`: The evaluation's episode log: finished models survive a crash or a
  kill, a rerun skips them.
* :mod:`~nbv.eval.inputs`: What an evaluation runs on: the datasets opened (and ``mesh_dir``
  prepared) and checked against the viewspaces and start views (:func:`open_datasets`,
  :class:`DatasetInfo`), the models that chose a network's checkpoint left out
  (:func:`exclude_selection`), the networks loaded (:func:`load_networks`,
  :func:`with_shipped_weights`) and the methods' context on a dataset (:func:`dataset_context`).
* :mod:`~nbv.eval.metric_tables`: The report's tables of the field's metrics
  (:mod:`nbv.eval.metrics`), the seconds per decision of each stage, and spread's ties.
* :mod:`~nbv.eval.metrics`: The field's metrics of an episode, beside coverage AUC and VIG
  (``EpisodeRecord.metrics``).
* :mod:`~nbv.eval.ranking`: ``python -m nbv.eval.ranking [methods=[...]] [out=outputs/ranking]
  [key=value]``: how well each method's view scores rank the true coverage gains, on the
  evaluation's models.
* :mod:`~nbv.eval.results_files`: The numbers of an evaluation as files: ``results.json`` and
  ``summary.csv``.
* :mod:`~nbv.eval.statistics`: the evaluator's statistics: means over episodes and paired
  differences, free of Markdown.
* :mod:`~nbv.eval.tables`: the Markdown tables of the report, from those statistics.

Third-party imports: matplotlib, numpy, omegaconf, scipy, threadpoolctl, torch, tqdm.
"""
