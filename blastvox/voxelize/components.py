"""Connected components of an undirected graph given as an edge list (numba union-find).

The voxelizer splits each lattice into objects with it: nodes are voxels, edges
are links. Components are numbered in order of their lowest node index, as
``scipy.sparse.csgraph.connected_components`` numbers them (this replaced it).
"""

from __future__ import annotations

import numpy as np

from blastvox.jit import kernel


@kernel
def _root(parent, v):
    """Union-find root of v, halving the path on the way."""
    while parent[v] != v:
        parent[v] = parent[parent[v]]
        v = parent[v]
    return v


@kernel
def union_find_labels(edges, n):
    """Component label of each of ``n`` nodes joined by undirected ``edges``.

    edges: (E, 2) int64, node indices in [0, n) (unchecked: see
    :func:`component_labels`); either order, repeats and self-loops allowed.
    Returns labels (n,) int64 in [0, count), components numbered in order of
    their lowest node (node 0 is in component 0; count = labels.max() + 1).

    A larger root always hangs under a smaller one, so every root is its set's
    lowest node and one ascending pass numbers the roots and, through them,
    every other node (whose root is lower, so labelled already).
    """
    parent = np.arange(n, dtype=np.int64)
    for e in range(edges.shape[0]):
        ra = _root(parent, edges[e, 0])
        rb = _root(parent, edges[e, 1])
        if ra < rb:
            parent[rb] = ra
        elif rb < ra:
            parent[ra] = rb
    labels = np.empty(n, dtype=np.int64)
    count = 0
    for v in range(n):
        if parent[v] == v:
            labels[v] = count
            count += 1
        else:
            labels[v] = labels[_root(parent, v)]
    return labels


def component_labels(edges: np.ndarray, n: int) -> np.ndarray:
    """Checked :func:`union_find_labels`: labels (n,) int64 of n nodes, edges (E, 2).

    Raises ValueError if ``edges`` is not (E, 2) integer or holds an index outside [0, n).
    """
    edges = np.asarray(edges)
    if edges.ndim != 2 or edges.shape[1] != 2:
        raise ValueError(f"edges must be (E, 2), got shape {edges.shape}")
    if edges.size and not np.issubdtype(edges.dtype, np.integer):
        raise ValueError(f"edges must be integers, got {edges.dtype}")
    n = int(n)
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if edges.size and (edges.min() < 0 or edges.max() >= n):
        raise ValueError(f"edge node index outside [0, {n})")
    return union_find_labels(np.ascontiguousarray(edges, dtype=np.int64), n)
