"""Training of the learners.

* ``python -m train``: PCNBV and PCNBV-sph on coverage or VIG targets, one cross-validation fold
  a run (``python -m train fold=3 score=vig model=pcnbv_sph``); ``python -m train.summary``
  gathers the folds.
* ``python -m train.conditioned``: the viewspace-conditioned networks (``vcnbv``, ``vcnbv_map``).
* ``python -m train.scorer``: ``ig_learned``'s score of candidate views.
"""
