"""The contact broad phase: integer cell keys and a linear-time hash table of buckets
(counting sort; no comparison sort, whose kernel would cost seconds of compilation),
the hash of resting bodies' voxels, each body's rest grid, and which voxels of
moving bodies may touch something this step."""

from __future__ import annotations

import math

import numpy as np

from blastvox.geometry.transforms_nb import to_rest
from blastvox.jit import helper, kernel
from blastvox.simulate.integrate import moving


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


@kernel
def static_hash(geometry, offsets, members, bodies, cell):
    """Spatial hash of the boundary voxels of bodies that do not move (fixed or asleep).

    Returns (voxels (S,), positions (S, 3), keys (S,), start): the voxels, their
    world centres and cell keys in bucket order, and the :func:`hash_buckets`
    offsets, so bucket s is the range start[s]:start[s+1] of the three arrays.
    Rebuilt only when the set of resting bodies changes.
    """
    voxel_centroid = geometry.centroid
    body_com, body_pos, body_rot = bodies.com, bodies.pos, bodies.rot
    body_live, body_dust, body_fixed = bodies.live, bodies.dust, bodies.fixed
    body_asleep, n_bodies = bodies.asleep, bodies.count[0]
    count = 0
    for b in range(n_bodies):
        if body_live[b] and not body_dust[b] and (body_fixed[b] or body_asleep[b]):
            count += offsets[b + 1] - offsets[b]
    vox = np.empty(count, dtype=np.int64)
    pos = np.empty((count, 3))
    keys = np.empty(count, dtype=np.int64)
    n = np.int64(0)  # not a literal 0: the callee would compile twice
    for b in range(n_bodies):
        if not (body_live[b] and not body_dust[b] and (body_fixed[b] or body_asleep[b])):
            continue
        for k in range(offsets[b], offsets[b + 1]):
            _place(members[k], b, voxel_centroid, body_com, body_pos, body_rot, pos, n)
            vox[n] = members[k]
            keys[n] = cell_key(cell_of(pos[n, 0], cell), cell_of(pos[n, 1], cell),
                           cell_of(pos[n, 2], cell))
            n += 1
    start, entries = hash_buckets(keys)
    return vox[entries], pos[entries], keys[entries], start


@helper
def _place(v, b, voxel_centroid, body_com, body_pos, body_rot, pos, n) -> None:
    rot = body_rot[b]
    x = voxel_centroid[v, 0] - body_com[b, 0]
    y = voxel_centroid[v, 1] - body_com[b, 1]
    z = voxel_centroid[v, 2] - body_com[b, 2]
    for a in range(3):
        pos[n, a] = body_pos[b, a] + rot[a, 0] * x + rot[a, 1] * y + rot[a, 2] * z


# A moving body with at most this many boundary voxels is hashed whole every step;
# a bigger one only where it is inside the bounding sphere of a body it may touch.
SMALL_BODY = 64
_FIELD = 16384  # 14 bits per rest-cell coordinate in a rest-grid key


@helper
def _rest_key(body, i, j, k) -> int:
    """Key of rest cell (i, j, k) of a body; coordinates wrap at 2^14 (a wrapped cell
    only adds candidates, which the distance test then rejects)."""
    return ((body * _FIELD + (i & (_FIELD - 1))) * _FIELD + (j & (_FIELD - 1))) * _FIELD \
        + (k & (_FIELD - 1))


@kernel
def rest_grid(voxel_centroid, voxel_body, members, cell):
    """Boundary voxels hashed by (body, cell of their rest centroid).

    Rest positions never change, so this is rebuilt only when the boundary does.
    Returns (slots (M,), keys (M,), start): boundary slots and their keys in
    bucket order, and the :func:`hash_buckets` offsets.
    """
    keys = np.empty(members.shape[0], dtype=np.int64)
    for k in range(members.shape[0]):
        v = members[k]
        keys[k] = _rest_key(voxel_body[v], cell_of(voxel_centroid[v, 0], cell),
                            cell_of(voxel_centroid[v, 1], cell),
                            cell_of(voxel_centroid[v, 2], cell))
    start, entries = hash_buckets(keys)
    return entries, keys[entries], start


@helper
def _mark_near_rest(b, o, reach, cell, voxel_centroid, members, bodies, rest, world,
                    near) -> int:
    """Mark b's boundary voxels within ``reach`` (m) of body o's centre, found through
    b's rest grid ``rest`` (:func:`rest_grid`): o's centre is taken into b's rest frame.
    Returns how many."""
    body_com, body_pos, body_rot = bodies.com, bodies.pos, bodies.rot
    rest_slot, rest_keys, rest_start = rest
    cx, cy, cz = to_rest(body_rot[b], body_pos[b], body_com[b], body_pos[o, 0],
                         body_pos[o, 1], body_pos[o, 2])
    count = 0
    for i in range(cell_of(cx - reach, cell), cell_of(cx + reach, cell) + 1):
        for j in range(cell_of(cy - reach, cell), cell_of(cy + reach, cell) + 1):
            for k in range(cell_of(cz - reach, cell), cell_of(cz + reach, cell) + 1):
                key = _rest_key(b, i, j, k)
                lo, hi = bucket(key, rest_start)
                for s in range(lo, hi):
                    if rest_keys[s] != key:
                        continue
                    slot = rest_slot[s]
                    if near[slot]:
                        continue
                    v = members[slot]
                    if ((voxel_centroid[v, 0] - cx) ** 2 + (voxel_centroid[v, 1] - cy) ** 2
                            + (voxel_centroid[v, 2] - cz) ** 2) < reach * reach:
                        near[slot] = True
                        _place(v, b, voxel_centroid, body_com, body_pos, body_rot, world, slot)
                        count += 1
    return count


@helper
def near_voxels(voxel_centroid, offsets, members, bodies, cell, rest, world, near):
    """Mark (in ``near``, by boundary slot) the voxels of moving bodies that may touch
    another body this step, with their world centres in ``world``; returns how many.

    Small bodies (<= SMALL_BODY boundary voxels) take part whole: the voxel hash
    is their broad phase. A bigger moving body takes part where it is within
    ``cell`` of the bounding sphere of a live body whose sphere its own meets:
    a scan of its voxels against a big neighbour, its rest grid (:func:`rest_grid`)
    around a small one, so a big block among thousands of chips stays cheap.
    """
    body_radius, body_com, body_pos, body_rot = bodies.radius, bodies.com, bodies.pos, bodies.rot
    body_fixed, body_live, body_dust = bodies.fixed, bodies.live, bodies.dust
    body_asleep, n_bodies = bodies.asleep, bodies.count[0]
    count = 0
    for b in range(n_bodies):
        if not moving(b, body_live, body_fixed, body_dust, body_asleep):
            continue
        first, last = offsets[b], offsets[b + 1]
        if last - first <= SMALL_BODY:
            for k in range(first, last):
                _place(members[k], b, voxel_centroid, body_com, body_pos, body_rot, world, k)
                near[k] = True
            count += last - first
            continue
        placed = False
        for o in range(n_bodies):
            if o == b or not body_live[o] or body_dust[o]:
                continue
            d2 = ((body_pos[b, 0] - body_pos[o, 0]) ** 2 + (body_pos[b, 1] - body_pos[o, 1]) ** 2
                  + (body_pos[b, 2] - body_pos[o, 2]) ** 2)
            if d2 >= (body_radius[b] + body_radius[o]) ** 2:
                continue
            reach = body_radius[o] + cell
            cells = (2.0 * reach / cell + 2.0) ** 3
            if cells < last - first:
                count += _mark_near_rest(b, o, reach, cell, voxel_centroid, members, bodies,
                                         rest, world, near)
                continue
            if not placed:
                for k in range(first, last):
                    _place(members[k], b, voxel_centroid, body_com, body_pos, body_rot, world, k)
                placed = True
            for k in range(first, last):
                if not near[k] and ((world[k, 0] - body_pos[o, 0]) ** 2
                                    + (world[k, 1] - body_pos[o, 1]) ** 2
                                    + (world[k, 2] - body_pos[o, 2]) ** 2) < reach * reach:
                    near[k] = True
                    count += 1
    return count
