"""Helpers every layer may use (the standard library, numpy and scipy).

* :mod:`~nbv.utils.atomic`: crash-safe writes (temporary file, fsync, rename) and durable logs.
* :mod:`~nbv.utils.artefacts`: reading the toolkit's own files, every fault refused in one line.
* :mod:`~nbv.utils.lock`: one writer at a time per output (``flock``, freed when its holder dies).
* :mod:`~nbv.utils.seeding`: generators derived from a seed and names (CRC-32).
* :mod:`~nbv.utils.bits`: popcount of packed bit arrays.
* :mod:`~nbv.utils.selection`: the best unvisited view (masked argmax).
* :mod:`~nbv.utils.declared`: a name looked up in a table of declarations (methods, networks,
  mesh sources), refused with the declared names.

The other modules:

* :mod:`~nbv.utils.fields`: Settings fields that carry their allowed range: :func:`setting` and
  :func:`check_ranges`.
* :mod:`~nbv.utils.markdown`: Markdown tables for the reports.
* :mod:`~nbv.utils.ranking`: How well predicted view scores rank the true gains: Spearman's rank
  correlation over the unvisited views of each sample, and how often the predicted best view is the
  true best one.
* :mod:`~nbv.utils.settings_values`: Settings objects as plain values and back, without hydra: what
  a library API (the robot's :class:`nbv.scan.planner.Planner`) needs to take keyword overrides and
  to save and restore its settings as JSON.
* :mod:`~nbv.utils.stats`: Means with bootstrap confidence intervals, for paired differences over
  episodes.

Third-party imports: numpy, scipy.
"""
