"""``python -m nbv.bench`` (``make bench``): the fast paths against fair references.

* :mod:`~nbv.bench.config`: the settings of ``conf/bench.yaml``; ``__main__`` runs them.
* :mod:`~nbv.bench.suite`: the rows and the table.
* :mod:`~nbv.bench.network`: a 9-view PCNBV inference episode.
* :mod:`~nbv.bench.render`: Blender against ray casting.
* :mod:`~nbv.bench.timing`: the best-of-n wall clock.

The other modules:

* :mod:`~nbv.bench.completion`: Benchmark rows of the completion network and the planners that use
  it (``make bench``).
* :mod:`~nbv.bench.floor`: The FLOP floor of a network episode on this machine: the float32 FLOPs of
  a PCNBV forward pass, counted from its layer shapes (as written, and in the rewritten evaluation
  form that the evaluator runs), over the CPU's peak float32 FLOP/s.
* :mod:`~nbv.bench.plan`: Benchmark rows of ``python -m nbv.plan``'s next-view decision from one
  50k-point capture.
* :mod:`~nbv.bench.training`: Time a training step of PCNBV and PCNBV-sph beside its FLOP floor
  (rows of ``make bench``).
* :mod:`~nbv.bench.infogain`: Plain numpy references of the volumetric planners, and their
  benchmark rows.
* :mod:`~nbv.bench.warm`: Benchmark rows of the warm planner (:class:`nbv.scan.planner.Planner`) in
  a robot's loop.

Third-party imports: numpy, scipy, threadpoolctl, torch, trimesh.
"""
