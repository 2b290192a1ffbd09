"""Chunks: the compiled graph kernels of :mod:`blastvox.voxelize.chunks`.

A weighted graph Voronoi over the voxels: seeds grow along links at their own
speeds (multiplicatively weighted "crystal growth"), a voxel joins the seed that
reaches it first, and it is claimed only from a neighbour already in that seed's
cell, so every cell is connected through links. One multi-source Dijkstra
(4-ary heap, lazy deletion) does it in O(L log L); ties go to the lower voxel
index, so the result depends on nothing but the inputs.
"""

from __future__ import annotations

import numpy as np

from blastvox.jit import kernel


@kernel
def link_graph(n, a, b, length):
    """Compressed adjacency of ``n`` nodes joined by undirected links (a[i], b[i]).

    a, b: (E,) int64 node indices; length: (E,) float64 link lengths, m.
    Returns indptr (n + 1,) int64, neighbours (2E,) int64 and lengths (2E,)
    float64: node v's links are neighbours[indptr[v]:indptr[v + 1]], in link order
    (a counting sort, O(n + E)).
    """
    count = np.zeros(n + 1, dtype=np.int64)
    for e in range(a.shape[0]):
        count[a[e] + 1] += 1
        count[b[e] + 1] += 1
    for v in range(n):
        count[v + 1] += count[v]
    indptr = count.copy()
    fill = count[:n].copy()
    neighbours = np.empty(2 * a.shape[0], dtype=np.int64)
    lengths = np.empty(2 * a.shape[0], dtype=np.float64)
    for e in range(a.shape[0]):
        i, j = a[e], b[e]
        neighbours[fill[i]] = j
        lengths[fill[i]] = length[e]
        fill[i] += 1
        neighbours[fill[j]] = i
        lengths[fill[j]] = length[e]
        fill[j] += 1
    return indptr, neighbours, lengths


@kernel
def grow(indptr, neighbours, lengths, seeds, speed):
    """Multiplicatively weighted graph Voronoi cells by crystal growth.

    indptr, neighbours, lengths: the graph (:func:`link_graph`); seeds (K,) int64
    distinct nodes (< 2^31); speed (K,) float64 > 0, relative growth speed of each
    seed. A node's arrival time from seed k is the shortest path (m) from a node of
    k's cell, over k's speed; it joins the seed that arrives first (on a tie, the
    lower node's entry is taken first).
    Returns label (n,) int64: the seed index of each node, -1 where no seed reaches.

    The queue is a 4-ary heap of (arrival time, node << 32 | seed), written out
    inline (as calls, the sifts ran at half the speed): shallower than a binary
    heap, and a node's children share a cache line.
    """
    n = indptr.shape[0] - 1
    label = np.full(n, -1, dtype=np.int64)
    best = np.full(n, np.inf)
    cap = seeds.shape[0] + neighbours.shape[0] + 1
    key = np.empty(cap, dtype=np.float64)  # arrival: path length (m) / speed
    item = np.empty(cap, dtype=np.int64)   # node << 32 | seed
    size = 0
    for k in range(seeds.shape[0]):  # the seeds, at time 0, in seed order
        best[seeds[k]] = 0.0
        key[size], item[size] = 0.0, (seeds[k] << 32) | k
        size += 1
    for start in range(size - 1, -1, -1):  # heapify: sift each entry down
        i, t, p = start, key[start], item[start]
        while True:
            child = 4 * i + 1
            if child >= size:
                break
            for c in range(child + 1, min(child + 4, size)):
                if key[c] < key[child] or (key[c] == key[child] and item[c] < item[child]):
                    child = c
            if t < key[child] or (t == key[child] and p < item[child]):
                break
            key[i], item[i] = key[child], item[child]
            i = child
        key[i], item[i] = t, p
    while size > 0:
        t, p = key[0], item[0]
        size -= 1  # pop: sift the last entry down from the top
        last_t, last_p = key[size], item[size]
        i = 0
        while True:
            child = 4 * i + 1
            if child >= size:
                break
            for c in range(child + 1, min(child + 4, size)):
                if key[c] < key[child] or (key[c] == key[child] and item[c] < item[child]):
                    child = c
            if last_t < key[child] or (last_t == key[child] and last_p < item[child]):
                break
            key[i], item[i] = key[child], item[child]
            i = child
        key[i], item[i] = last_t, last_p
        v, k = p >> 32, p & 0xFFFFFFFF
        if label[v] >= 0:
            continue  # reached earlier from another cell
        label[v] = k
        slowness = 1.0 / speed[k]
        for j in range(indptr[v], indptr[v + 1]):
            w = neighbours[j]
            if label[w] >= 0:
                continue
            arrival = t + lengths[j] * slowness
            if arrival < best[w]:
                best[w] = arrival
                i, q = size, (w << 32) | k  # push: sift up from the bottom
                while i > 0:
                    parent = (i - 1) >> 2
                    if key[parent] < arrival or (key[parent] == arrival and item[parent] < q):
                        break
                    key[i], item[i] = key[parent], item[parent]
                    i = parent
                key[i], item[i] = arrival, q
                size += 1
    return label


@kernel
def recentre(label, volume, centroid, count):
    """One Lloyd step: the node of each cell nearest the cell's centroid.

    label (n,) int64 in [0, count) or -1 (ignored); volume (n,) m^3 weights;
    centroid (n, 3) m. Returns seeds (count,) int64: for each cell, its node
    closest to the cell's volume-weighted centroid (the lowest such node on a tie).
    """
    total = np.zeros(count)
    centre = np.zeros((count, 3))
    for v in range(label.shape[0]):
        k = label[v]
        if k >= 0:
            total[k] += volume[v]
            for d in range(3):
                centre[k, d] += volume[v] * centroid[v, d]
    for k in range(count):
        if total[k] > 0.0:
            for d in range(3):
                centre[k, d] /= total[k]
    seeds = np.full(count, -1, dtype=np.int64)
    nearest = np.full(count, np.inf)
    for v in range(label.shape[0]):
        k = label[v]
        if k >= 0:
            dist = 0.0
            for d in range(3):
                dist += (centroid[v, d] - centre[k, d]) ** 2
            if dist < nearest[k]:
                nearest[k] = dist
                seeds[k] = v
    return seeds
