"""The networks that pick the next best view, and their checkpoints (torch's home; the
policies, the evaluator and the benchmark call torch too).

Modules, each importing only the ones above it:

- :mod:`nbv.models.threads`: :func:`configure_openmp`, torch's OpenMP threads set to sleep when
  idle (no torch import; entry points call it before torch loads).
- :mod:`nbv.models.precision`: :data:`PRECISIONS`, :func:`resolve_precision`, :func:`autocast`
  (bfloat16 where the hardware runs it), :func:`flush_denormals`.
- :mod:`nbv.models.neighbours`: k-nearest-neighbour search in feature space
  (:func:`knn_indices`), a fast CPU top-k (:func:`smallest_indices`), :func:`gather_neighbours`.
- :mod:`nbv.models.config`: :class:`PCNBVConfig`, the sizes of a network (no torch).
- :mod:`nbv.models.layers`: 1x1 convs, :func:`max_over`, :func:`max_over_neighbours`,
  :class:`DenseEdgeConv`, :class:`FeatureExtractor`, :class:`SelfAttention`.
- :mod:`nbv.models.pcnbv`: :class:`PCNBV`, the PC-NBV network (also PCNBV-sph), and
  :func:`count_parameters`.
- :mod:`nbv.models.inference`: :func:`for_inference` (batch norm folded; in float32 the
  rewritten :class:`InferencePCNBV`, 23 % fewer FLOPs; in bfloat16 bfloat16 weights) and
  :func:`masked_argmax`, the best unvisited view.
- :mod:`nbv.models.networks`: :data:`NETWORKS`, the one declaration of the networks trained
  (sizes, module, trainer), and :func:`fresh_network`.
- :mod:`nbv.models.checkpoints`: :func:`save_checkpoint`, :func:`load_checkpoint`,
  :class:`CheckpointError`.

Nothing is re-exported here: import from the module itself, so that importing the package
costs nothing and code that avoids torch can still name it.

The other modules:

* :mod:`~nbv.models.completion`: A point-cloud completion network: the captured cloud in, points on
  the whole surface out.
* :mod:`~nbv.models.completion_inference`: The completion network's checkpoints, and completing a
  captured cloud with one.
* :mod:`~nbv.models.view_conditioned`: A viewspace-conditioned next-best-view network (beyond the
  paper), and its checkpoints.

Third-party imports: numpy, scipy, torch.
"""
