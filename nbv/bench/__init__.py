"""``python -m nbv.bench`` (``make bench``): the fast paths against fair references.

* :mod:`~nbv.bench.config`: the settings of ``conf/bench.yaml``; ``__main__`` runs them.
* :mod:`~nbv.bench.suite`: the rows and the table.
* :mod:`~nbv.bench.network`: a 9-view PCNBV inference episode.
* :mod:`~nbv.bench.render`: Blender against ray casting.
* :mod:`~nbv.bench.timing`: the best-of-n wall clock.
"""
