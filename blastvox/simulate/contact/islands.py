"""The contact solve's islands: moving bodies joined by contacts between them, which
the solver solves each on its own (:func:`islands`), and how they are dealt to
threads."""

from __future__ import annotations

import numpy as np

from blastvox.jit import helper
from blastvox.simulate.contact.partition import SPLIT_ROWS
from blastvox.simulate.topology import root_of


@helper
def islands(ends, n, order, threads):
    """The solve's islands: bodies joined by rows between two moving bodies (union-find),
    each island's rows in ``order`` and its bodies, and the islands dealt to ``threads``
    bins, largest first to the emptiest (which bin solves an island changes no byte),
    but those of at least SPLIT_ROWS rows to one more bin, the last: each of those is
    cut in parts that every thread sweeps (:mod:`~blastvox.simulate.contact.partition`).
    Returns (row_start, rows, body_start, bodies, bin_start, bin_islands): CSR arrays,
    island k's rows rows[row_start[k]:row_start[k + 1]] and so on; rows of no moving
    body are in none."""
    count = ends.shape[0]
    parent = np.arange(n)
    for r in range(count):
        ea, eb = ends[r, 0], ends[r, 1]
        if ea >= 0 and eb >= 0:
            ra, rb = root_of(parent, ea), root_of(parent, eb)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    island = np.full(n, -1, dtype=np.int64)
    k = 0
    for e in range(n):
        root = root_of(parent, e)
        if island[root] < 0:
            island[root] = k
            k += 1
        island[e] = island[root]
    body_start = np.zeros(k + 1, dtype=np.int64)
    for e in range(n):
        body_start[island[e] + 1] += 1
    row_start = np.zeros(k + 1, dtype=np.int64)
    for q in range(count):
        e = ends[order[q], 0] if ends[order[q], 0] >= 0 else ends[order[q], 1]
        if e >= 0:
            row_start[island[e] + 1] += 1
    for j in range(k):
        body_start[j + 1] += body_start[j]
        row_start[j + 1] += row_start[j]
    members = _grouped(island[:n], body_start)
    island_rows = np.empty(row_start[k], dtype=np.int64)
    fill = row_start[:-1].copy()
    for q in range(count):
        r = order[q]
        e = ends[r, 0] if ends[r, 0] >= 0 else ends[r, 1]
        if e >= 0:
            island_rows[fill[island[e]]] = r
            fill[island[e]] += 1
    load = np.zeros(threads, dtype=np.int64)
    deal = np.empty(k, dtype=np.int64)
    # the sizes as float64 (exact): numba then compiles np.argsort's merge sort once, for
    # partition's float64 keys, not a second copy for int64 ones (1.3 s of a first run)
    by_size = np.argsort(-(row_start[1:] - row_start[:-1]).astype(np.float64),
                         kind="mergesort")
    for j in by_size:
        size = row_start[j + 1] - row_start[j]
        if size >= SPLIT_ROWS:  # cut in parts, solved on every thread after the bins
            deal[j] = threads
            continue
        target = np.argmin(load)
        deal[j] = target
        load[target] += size + 1
    bin_start = np.zeros(threads + 2, dtype=np.int64)
    for j in range(k):
        bin_start[deal[j] + 1] += 1
    for t in range(threads + 1):
        bin_start[t + 1] += bin_start[t]
    bin_islands = _grouped(deal, bin_start)
    return row_start, island_rows, body_start, members, bin_start, bin_islands


@helper
def _grouped(keys, start):
    """0 .. len(keys) - 1 grouped by key (keys (m,) int64, start: each key's first slot,
    CSR), in order within a group."""
    out = np.empty(len(keys), dtype=np.int64)
    fill = start[:-1].copy()
    for i in range(len(keys)):
        out[fill[keys[i]]] = i
        fill[keys[i]] += 1
    return out
