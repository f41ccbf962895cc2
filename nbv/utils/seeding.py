"""Generators derived from names: the same draws in every process, run and machine.

A seed and a sequence of names (strings, hashed with CRC-32, or non-negative integers) give one
:class:`numpy.random.SeedSequence`. Python's ``hash`` of a string changes between processes, so it
is never used.
"""

from __future__ import annotations

import zlib

import numpy as np


def seed_words(seed: int, *names: str | int) -> list[int]:
    """``[seed, word(name) ...]``: a string's word is its CRC-32 of UTF-8, an integer is itself."""
    return [int(seed)] + [
        zlib.crc32(n.encode("utf-8")) if isinstance(n, str) else int(n) for n in names
    ]


def seed_sequence(seed: int, *names: str | int) -> np.random.SeedSequence:
    """The seed sequence of ``names`` under ``seed`` (see :func:`seed_words`)."""
    return np.random.SeedSequence(seed_words(seed, *names))


def named_rng(seed: int, *names: str | int) -> np.random.Generator:
    """A generator seeded by ``seed`` and ``names`` (see :func:`seed_words`)."""
    return np.random.default_rng(seed_sequence(seed, *names))
