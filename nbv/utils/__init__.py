"""Helpers every layer may use (standard library and numpy only).

* :mod:`~nbv.utils.atomic`: crash-safe writes (temporary file, fsync, rename) and durable logs.
* :mod:`~nbv.utils.artefacts`: reading the toolkit's own files, every fault refused in one line.
* :mod:`~nbv.utils.lock`: one writer at a time per output (``flock``, freed when its holder dies).
* :mod:`~nbv.utils.seeding`: generators derived from a seed and names (CRC-32).
* :mod:`~nbv.utils.bits`: popcount of packed bit arrays.
* :mod:`~nbv.utils.selection`: the best unvisited view (masked argmax).
"""
