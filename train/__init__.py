"""Training of the learners.

* ``python -m train``: PCNBV and PCNBV-sph on coverage or VIG targets, one cross-validation fold
  a run (``python -m train fold=3 score=vig model=pcnbv_sph``); ``python -m train.summary``
  gathers the folds.
* ``python -m train.conditioned``: the viewspace-conditioned networks (``vcnbv``, ``vcnbv_map``).
* ``python -m train.scorer``: ``ig_learned``'s score of candidate views.

The other modules:

* :mod:`~train.augment`: Exact symmetry augmentation of training batches
  (:mod:`nbv.geometry.symmetry`).
* :mod:`~train.ranking_baselines`: What a network's ranking has to beat: two baselines scored on
  the same validation samples.
* :mod:`~train.completion`: Training of the completion network (:mod:`nbv.models.completion`).
* :mod:`~train.completion_data`: The completion network's data: partial views and true surfaces of
  the training categories.
* :mod:`~train.conditioned_config`: The settings of ``python -m train.conditioned``:
  :class:`ConditionedSettings`, the one declaration of ``conf/train_conditioned.yaml``'s keys (the
  hydra schema ``train_conditioned_schema`` is derived from it), and the command's :data:`ENTRY`.
* :mod:`~train.config`: The settings of ``python -m train``: :class:`TrainSettings`, the one
  declaration of ``conf/train.yaml``'s keys (the hydra schema ``train_schema`` is derived from it by
  :mod:`nbv.config.settings`.
* :mod:`~train.fitcheck`: The fitting check: can the network learn to rank the views of a few models
  it is trained on?.
* :mod:`~train.folds`: A fold of the cross-validation: its training and validation samples
  (:func:`split_samples`) and its models (:func:`fold_keys`): those whose episodes choose the
  checkpoint and the held-out category's.
* :mod:`~train.heldout`: The held-out category, scored once, with the chosen checkpoint only.
* :mod:`~train.loop`: One training run: leave-one-category-out, checkpoints, metrics, resumption.
* :mod:`~train.losses`: Training losses of the per-view gain networks.
* :mod:`~train.metrics`: Training metrics: rank correlation and best-view agreement of predicted and
  true gains, overall and by trajectory stage.
* :mod:`~train.run_log`: What every trainer records beside its weights: the epochs' rows of its CSV
  files, and the identity of the dataset it read.
* :mod:`~train.resume`: Resuming a run only with the settings, dataset and samples it started with.
* :mod:`~train.subsets`: The training models a trainer uses when told to use fewer (``max_models``):
  a learning curve's training sets, nested and balanced over the categories.

Third-party imports: h5py, hydra, matplotlib, numpy, torch, tqdm.
"""
