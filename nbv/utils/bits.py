"""Bit counting on packed bit arrays (numpy 1.26 has no ``bitwise_count``)."""

from __future__ import annotations

import numpy as np

#: Set bits of every byte value.
_BYTE_COUNTS = np.array([bin(i).count("1") for i in range(256)], dtype=np.uint8)
_BYTE_COUNTS.setflags(write=False)

# Masks of the SWAR popcount of 64-bit words.
_M1 = np.uint64(0x5555555555555555)
_M2 = np.uint64(0x3333333333333333)
_M4 = np.uint64(0x0F0F0F0F0F0F0F0F)
_H01 = np.uint64(0x0101010101010101)
_U1, _U2, _U4, _U56 = (np.uint64(k) for k in (1, 2, 4, 56))


def popcount(words: np.ndarray) -> np.ndarray:
    """Set bits of every element of a uint8 or uint64 array: same shape, uint8 or uint64.

    Bytes go through a 256-entry table; 64-bit words through a branch-free SWAR count, which is
    several times faster than the table on the same bytes.
    """
    words = np.asarray(words)
    if words.dtype == np.uint8:
        return _BYTE_COUNTS[words]
    if words.dtype != np.uint64:
        raise TypeError(f"popcount takes uint8 or uint64 arrays, got {words.dtype}")
    a = np.right_shift(words, _U1)
    a &= _M1
    np.subtract(words, a, out=a)  # 2-bit counts
    b = np.right_shift(a, _U2)
    b &= _M2
    a &= _M2
    a += b  # 4-bit counts
    np.right_shift(a, _U4, out=b)
    a += b
    a &= _M4  # byte counts
    a *= _H01
    a >>= _U56  # the sum of the bytes lands in the top byte
    return a


def popcount_rows(rows: np.ndarray) -> np.ndarray:
    """Set bits of each row of a ``(V, W)`` uint8 or uint64 array: ``(V,)`` int64."""
    return popcount(rows).sum(axis=1, dtype=np.int64)
