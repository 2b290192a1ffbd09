"""Broad phase of fragment contacts: the pairs of voxel boxes that may touch this step.

The boundary voxels of moving bodies that may touch something
(:func:`~blastvox.simulate.contact.pairs.near_voxels`) go into a spatial hash
each step (:func:`~blastvox.simulate.contact.pairs.hash_buckets`); voxels of
bodies at rest (fixed or asleep) come from the static hash
(:func:`~blastvox.simulate.contact.pairs.static_hash`), so a big standing
structure costs nothing per step. Each moving voxel looks in the 27 cells
around its own: against moving voxels each pair once, against resting ones
all. A pair is a candidate when the boxes' bounding spheres may touch within
the step (:func:`_lookahead`).

The search runs on every core (:func:`_search`): the moving voxels are dealt
in fixed chunks of :data:`CHUNK` (not one per thread), each chunk writes its
candidates into its own slots in voxel order, and the chunks are joined in
order, so the candidates are in the same order for any thread count (and the
same as one serial loop over the voxels would give).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from blastvox.jit import helper, kernel, parallel_kernel
from blastvox.simulate.contact.pairs import bucket, cell_key, cell_of, hash_buckets, near_voxels
from blastvox.simulate.integrate import angular_velocity

#: Moving voxels a chunk of the parallel search takes (fixed: the order of the
#: candidates does not depend on the thread count).
CHUNK = 32
#: Candidate slots a chunk starts with, per voxel; a chunk that finds more than its
#: slots is searched again with room for the most any chunk found.
SLOTS_PER_VOXEL = 12


def candidates(geometry, voxels, bodies, params, boundary, static, rest,
               memory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs of voxel boxes of different bodies whose bounding spheres may touch
    within the step, in hash order: pairs (C, 4) int64 (body, voxel of a, then of b),
    centres (C, 2, 3) m, ahead (C,) m (the lookahead).

    boundary: (offsets, members) each body's boundary voxels; params:
    :class:`~blastvox.simulate.contact.fragments.CollideParams` (cell, reach, dt);
    static: :func:`~blastvox.simulate.contact.pairs.static_hash`; rest:
    :func:`~blastvox.simulate.contact.pairs.rest_grid`; memory: the contact memory
    (its radius (N,) m, the boxes' half diagonals)."""
    world, slot, ijk, keys, motion, start, entries = _hashed(
        geometry.centroid, voxels.body, boundary, bodies, params.cell, rest, memory.radius)
    n = len(slot)
    if n == 0:
        return np.empty((0, 4), dtype=np.int64), np.empty((0, 2, 3)), np.empty(0)
    chunks = -(-n // CHUNK)
    slots = SLOTS_PER_VOXEL * CHUNK
    while True:
        pairs = np.empty((chunks * slots, 4), dtype=np.int64)
        centres = np.empty((chunks * slots, 2, 3))
        ahead = np.empty(chunks * slots)
        found = np.zeros(chunks, dtype=np.int64)
        _search((boundary[1], voxels.body, voxels.alive, memory.radius),
                (world, slot, ijk, keys, motion, start, entries), static,
                (params.reach, params.dt, slots), (pairs, centres, ahead), found)
        most = int(found.max())
        if most <= slots:
            break
        slots = most
    keep = (np.arange(slots)[None, :] < found[:, None]).ravel()
    return pairs[keep], centres[keep], ahead[keep]


@kernel
def _hashed(voxel_centroid, voxel_body, boundary, bodies, cell, rest, radius):
    """The moving voxels that may touch something this step, hashed: world (K, 3) m
    centres by boundary slot; slot (n,) their boundary slots; ijk (n, 3) cells; keys
    (n,) cell keys; motion (n, 4) (:func:`_motion`); start, entries: the hash
    (:func:`~blastvox.simulate.contact.pairs.hash_buckets`)."""
    offsets, members = boundary
    world = np.empty((members.shape[0], 3))
    near = np.zeros(members.shape[0], dtype=np.bool_)
    count = near_voxels(voxel_centroid, offsets, members, bodies, cell, rest, world, near)
    slot = np.empty(count, dtype=np.int64)
    ijk = np.empty((count, 3), dtype=np.int64)
    keys = np.empty(count, dtype=np.int64)
    motion = np.empty((count, 4))
    n = 0
    for k in range(members.shape[0]):
        if near[k]:
            slot[n] = k
            for a in range(3):
                ijk[n, a] = cell_of(world[k, a], cell)
            keys[n] = cell_key(ijk[n, 0], ijk[n, 1], ijk[n, 2])
            _motion(members[k], voxel_body[members[k]], world[k], bodies, radius, motion[n])
            n += 1
    start, entries = hash_buckets(keys)
    return world, slot, ijk, keys, motion, start, entries


@parallel_kernel
def _search(voxel_fields, moving, static, scalars, out, found) -> None:
    """Each chunk of :data:`CHUNK` moving voxels (``moving``: :func:`_hashed`'s) writes
    its candidates to its own ``slots`` rows of pairs, centres and ahead (as
    :func:`candidates` returns them) and how many it found to found (chunks,) (those
    past its slots counted, not written). voxel_fields: (boundary members, voxel body,
    voxel alive, box half diagonals); static: the static hash; scalars: (reach m, dt s,
    slots); out: (pairs, centres, ahead). (found is an argument of its own: numba 0.68
    silently dropped a parallel loop's ``found[k] = count`` when found came unpacked
    from a tuple argument, while the same loop's writes to the tuple's other arrays
    stayed.)"""
    members, voxel_body, voxel_alive, radius = voxel_fields
    world, slot, ijk, keys, motion, start, entries = moving
    static_vox, static_pos, static_keys, static_start = static
    reach, dt, slots = scalars
    pairs, centres, ahead = out
    n = slot.shape[0]
    for k in nb.prange(found.shape[0]):
        still = np.zeros(4)
        base, count = k * slots, 0
        for i in range(k * CHUNK, min(n, (k + 1) * CHUNK)):
            vi = members[slot[i]]
            bi = voxel_body[vi]
            if not voxel_alive[vi]:
                continue
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    for dz in range(-1, 2):
                        key = cell_key(ijk[i, 0] + dx, ijk[i, 1] + dy, ijk[i, 2] + dz)
                        # moving against moving, each pair once: from the cell of either,
                        # the other in one of the 13 cells that follow it, or in the same
                        # cell, the lower voxel first
                        forward = (dx, dy, dz) > (0, 0, 0)
                        lo, hi = bucket(key, start)
                        for jj in range(lo if forward or (dx, dy, dz) == (0, 0, 0) else hi, hi):
                            j = entries[jj]
                            if keys[j] != key:
                                continue
                            vj = members[slot[j]]
                            bj = voxel_body[vj]
                            if (not forward and vj <= vi) or bj == bi or not voxel_alive[vj]:
                                continue
                            gap = _lookahead(motion[i], motion[j], reach, dt)
                            if _touching(world[slot[i]], world[slot[j]],
                                         radius[vi] + radius[vj] + gap):
                                if count < slots:
                                    _candidate(base + count, bi, vi, bj, vj, world[slot[i]],
                                               world[slot[j]], gap, pairs, centres, ahead)
                                count += 1
                        if static_vox.shape[0] == 0:  # moving against resting
                            continue
                        lo, hi = bucket(key, static_start)
                        for jj in range(lo, hi):
                            if static_keys[jj] != key:
                                continue
                            vj = static_vox[jj]
                            bj = voxel_body[vj]
                            if bj == bi or not voxel_alive[vj]:
                                continue
                            gap = _lookahead(motion[i], still, reach, dt)
                            if _touching(world[slot[i]], static_pos[jj],
                                         radius[vi] + radius[vj] + gap):
                                if count < slots:
                                    _candidate(base + count, bi, vi, bj, vj, world[slot[i]],
                                               static_pos[jj], gap, pairs, centres, ahead)
                                count += 1
        found[k] = count


@helper
def _candidate(c, bi, vi, bj, vj, ci, cj, ahead, pairs, centres, ahead_of) -> None:
    """Write candidate c: bodies and voxels, centres ci, cj (3,) m, lookahead (m)."""
    pairs[c, 0], pairs[c, 1], pairs[c, 2], pairs[c, 3] = bi, vi, bj, vj
    for a in range(3):
        centres[c, 0, a] = ci[a]
        centres[c, 1, a] = cj[a]
    ahead_of[c] = ahead


@helper
def _touching(ci, cj, reach) -> bool:
    """Are ci and cj (3,) closer than ``reach`` (m)?"""
    d2 = (cj[0] - ci[0]) ** 2 + (cj[1] - ci[1]) ** 2 + (cj[2] - ci[2]) ** 2
    return d2 < reach * reach


@helper
def _motion(v, b, centre, bodies, radius, out) -> None:
    """out (4,): the velocity (m/s) of moving body b, and its spin (rad/s) times the
    reach of voxel v's box (centre (3,) m, half diagonal radius[v]) from b's centre."""
    m = bodies.mass[b]
    for a in range(3):
        out[a] = bodies.lin[b, a] / m
    w = angular_velocity(bodies.rot[b], bodies.inv_inertia[b], bodies.ang[b])
    arm = math.sqrt((centre[0] - bodies.pos[b, 0]) ** 2 + (centre[1] - bodies.pos[b, 1]) ** 2
                    + (centre[2] - bodies.pos[b, 2]) ** 2) + radius[v]
    out[3] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * arm


@helper
def _lookahead(a, b, reach, dt) -> float:
    """How close (m) two boxes whose :func:`_motion` are a and b (4,) may come within a
    step of dt s: their relative speed bound times dt, at most ``reach`` (m)."""
    speed = math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)
    return min(reach, (speed + a[3] + b[3]) * dt)
