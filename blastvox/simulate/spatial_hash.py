"""Integer cell keys and a linear-time hash table of buckets (counting sort), for the
contact broad phase. No comparison sort: its kernel would cost seconds of compilation."""

from __future__ import annotations

import math

import numpy as np

from blastvox.jit import helper


@helper
def cell_of(x, cell) -> int:
    return int(math.floor(x / cell)) + 1048576


@helper
def cell_key(i, j, k) -> int:
    """Hash key (>= 0) of integer cell (i, j, k)."""
    return (i * 2097152 + j) * 2097152 + k


@helper
def _slot(key, mask) -> int:
    """Table slot of a cell key: fold the three 21-bit fields, then a Fibonacci mix."""
    h = (key ^ (key >> 21) ^ (key >> 42)) * -7046029254386353131  # 0x9E3779B97F4A7C15
    return (h ^ (h >> 32)) & mask  # int64 arithmetic wraps


@helper
def hash_buckets(keys):
    """Counting sort of cell ``keys`` (M,) int64 into the buckets of a hash table.

    Returns (start (T+1,), entries (M,)): bucket s of the T-slot table (T a
    power of two, at least 2 M and 16) holds the indices entries[start[s]:
    start[s+1]] into ``keys``, in increasing order. Distinct keys can share a
    bucket, so a lookup compares keys (:func:`bucket`). Linear time and no
    comparison sort, whose kernel would cost seconds of compilation.
    """
    n = keys.shape[0]
    size = 16
    while size < 2 * n:
        size *= 2
    mask = size - 1
    start = np.zeros(size + 1, dtype=np.int64)
    for i in range(n):
        start[_slot(keys[i], mask) + 1] += 1
    for s in range(size):
        start[s + 1] += start[s]
    fill = start[:-1].copy()
    entries = np.empty(n, dtype=np.int64)
    for i in range(n):
        s = _slot(keys[i], mask)
        entries[fill[s]] = i
        fill[s] += 1
    return start, entries


@helper
def bucket(key, start):
    """(lo, hi): the range of ``key``'s bucket in a :func:`hash_buckets` table."""
    s = _slot(key, start.shape[0] - 2)
    return start[s], start[s + 1]
