"""Diffraction: how much farther the wave travels to reach a shadowed face.

A face that solid hides from a charge (the back of a wall, the far side of a
column) is reached by the wave only once it has wrapped round the obstacle, over
its top or round its ends: later than the straight line says, and weaker for the
longer way (UFC 3-340-02 §2-15.4, the rear wall: its load starts when the front has
crossed the structure and rises over the time the wave takes to fill in behind
it). Loading it at the straight-line arrival, as before, pushed the back of a wall
as early as its front, so a wall under a long wave (1000 kg TNT at 60 m) netted
only the front's reflected excess and was barely moved.

Per wave and charge, :func:`detour_field` finds the shortest path through air
from the charge to every cell of a padded, possibly coarser copy of the shielding
grid: the cells the charge sees in a straight line are that far, and Dijkstra over
the 26-neighbour lattice (steps h, h sqrt 2, h sqrt 3) carries the distance on into
the shadows (where a path round an edge is mostly along the axes, the lattice's
steps measure it closely; a leg across a diagonal is up to 8 % long). The *detour*
of a cell is that path's length less the straight line's. A shadowed
face is loaded as if it lay its detour farther from the charge
(:func:`blastvox.simulate.forces.blast_impulses`): the wave's arrival, peak and
impulse there.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from blastvox.jit import helper, kernel

#: Most cells of the detour grid: a finer shielding grid is pooled (a cell is solid if
#: any of the cells it pools is) until it fits.
DETOUR_CELLS = 1 << 18
#: Air cells added round the shielding grid on every side: room for the path over a
#: wall's top and round its ends.
MARGIN = 2
_SQRT2, _SQRT3 = math.sqrt(2.0), math.sqrt(3.0)


class Detour(NamedTuple):
    """The detour grid of one wave: origin (3,) m, the corner of cell (0, 0, 0); cell m,
    its edge; dims (3,) int64; extra (C, X*Y*Z) m, each charge's detour to each cell
    (inf where its wave does not reach through air; 0 in the open); most (C,) m, the
    largest finite one; voxel (N, C) m: the largest round each voxel, worked out when
    first asked (:func:`voxel_detour`; -1: not yet)."""

    origin: np.ndarray
    cell: float
    dims: np.ndarray
    extra: np.ndarray
    most: np.ndarray
    voxel: np.ndarray


def detour_field(grid, charge_pos: np.ndarray, ground: tuple | None = None) -> Detour:
    """The :class:`Detour` of the charges at ``charge_pos`` (C, 3) m round the solid of the
    shielding ``grid`` (:class:`~blastvox.simulate.shielding.Occupancy`) as it stands;
    ``ground`` (up (3,), height m): the cells whose centres lie below it are solid too
    (the wave does not pass under a wall standing on the ground)."""
    dims = np.asarray(grid.dims, dtype=np.int64)
    pool = 1
    while int(np.prod(-(-dims // pool) + 2 * MARGIN)) > DETOUR_CELLS:
        pool += 1
    solid = _pooled_solid(grid.count, dims, pool, MARGIN)
    cell = float(grid.cell[0]) * pool
    origin = np.asarray(grid.origin, dtype=np.float64) - MARGIN * cell
    if ground is not None:
        up, height = np.asarray(ground[0], dtype=np.float64), float(ground[1])
        axes = [origin[a] + (np.arange(solid.shape[a]) + 0.5) * cell for a in range(3)]
        along = (axes[0][:, None, None] * up[0] + axes[1][None, :, None] * up[1]
                 + axes[2][None, None, :] * up[2])
        solid |= along < height
    shape = np.array(solid.shape, dtype=np.int64)
    flat = solid.ravel()
    extra = np.empty((len(charge_pos), flat.size))
    most = np.zeros(len(charge_pos))
    for c in range(len(charge_pos)):
        extra[c] = _detours(flat, shape, origin, cell, np.asarray(charge_pos[c], np.float64))
        finite = extra[c][np.isfinite(extra[c])]
        most[c] = float(finite.max()) if finite.size else 0.0
    return Detour(origin, cell, shape, extra, most,
                  np.full((len(grid.member), len(charge_pos)), -1.0))


def _pooled_solid(count: np.ndarray, dims: np.ndarray, pool: int, margin: int) -> np.ndarray:
    """(X', Y', Z') bool: the grid's occupied cells pooled ``pool`` to a side (any
    occupied: solid), with ``margin`` air cells round it."""
    nx, ny, nz = (int(d) for d in dims)
    occupied = (count.reshape(nx, ny, nz) != 0)
    px, py, pz = (-(-d // pool) for d in (nx, ny, nz))
    padded = np.zeros((px * pool, py * pool, pz * pool), dtype=bool)
    padded[:nx, :ny, :nz] = occupied
    pooled = padded.reshape(px, pool, py, pool, pz, pool).any(axis=(1, 3, 5))
    out = np.zeros((px + 2 * margin, py + 2 * margin, pz + 2 * margin), dtype=bool)
    out[margin:margin + px, margin:margin + py, margin:margin + pz] = pooled
    return out


@helper
def _segment_clear(solid, dims, origin, cell, px, py, pz, qx, qy, qz) -> bool:
    """Does the segment from p to q (m) cross no solid cell (sampled every quarter cell)?"""
    length = math.sqrt((qx - px) ** 2 + (qy - py) ** 2 + (qz - pz) ** 2)
    steps = int(length / (0.25 * cell)) + 1
    for s in range(steps + 1):
        t = s / steps
        i = int(math.floor((px + t * (qx - px) - origin[0]) / cell))
        j = int(math.floor((py + t * (qy - py) - origin[1]) / cell))
        k = int(math.floor((pz + t * (qz - pz) - origin[2]) / cell))
        if 0 <= i < dims[0] and 0 <= j < dims[1] and 0 <= k < dims[2]:
            if solid[(i * dims[1] + j) * dims[2] + k]:
                return False
    return True


@kernel
def _detours(solid, dims, origin, cell, charge):
    """(X*Y*Z,) the detour (m) of every cell for one charge (see the module docstring)."""
    n = solid.shape[0]
    dist = np.full(n, np.inf)
    heap = np.empty(n, dtype=np.int64)  # cells, a binary min-heap on dist
    place = np.full(n, -1, dtype=np.int64)  # each cell's index in heap, -1 if not in it
    size = 0
    nx, ny, nz = dims[0], dims[1], dims[2]
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                q = (i * ny + j) * nz + k
                if solid[q]:
                    continue
                cx, cy, cz = _centre(origin, cell, i, j, k)
                if _segment_clear(solid, dims, origin, cell, cx, cy, cz, charge[0],
                                  charge[1], charge[2]):
                    size = _lower(heap, place, dist, size, q, math.sqrt(
                        (cx - charge[0]) ** 2 + (cy - charge[1]) ** 2 + (cz - charge[2]) ** 2))
    while size > 0:
        q = heap[0]
        size = _pop(heap, place, dist, size)
        d = dist[q]
        i, rest = q // (ny * nz), q % (ny * nz)
        j, k = rest // nz, rest % nz
        for di in range(-1, 2):
            for dj in range(-1, 2):
                for dk in range(-1, 2):
                    steps = abs(di) + abs(dj) + abs(dk)
                    a, b, c = i + di, j + dj, k + dk
                    if steps == 0 or not (0 <= a < nx and 0 <= b < ny and 0 <= c < nz):
                        continue
                    r = (a * ny + b) * nz + c
                    if solid[r]:
                        continue
                    length = cell * (1.0 if steps == 1 else (_SQRT2 if steps == 2 else _SQRT3))
                    if d + length < dist[r]:
                        size = _lower(heap, place, dist, size, r, d + length)
    out = np.full(n, np.inf)
    for q in range(n):
        if math.isfinite(dist[q]):
            i, rest = q // (ny * nz), q % (ny * nz)
            j, k = rest // nz, rest % nz
            cx, cy, cz = _centre(origin, cell, i, j, k)
            out[q] = max(0.0, dist[q] - math.sqrt((cx - charge[0]) ** 2 + (cy - charge[1]) ** 2
                                                  + (cz - charge[2]) ** 2))
    return out


@helper
def _centre(origin, cell, i, j, k):
    """The centre (m) of cell (i, j, k)."""
    return (origin[0] + (i + 0.5) * cell, origin[1] + (j + 0.5) * cell,
            origin[2] + (k + 0.5) * cell)


@helper
def _lower(heap, place, dist, size, q, value) -> int:
    """Set dist[q] to ``value`` (smaller) and sift q up the heap (added if it is not in
    it); the heap's new size. Ties keep the order they came in: the field does not
    depend on the heap's layout."""
    dist[q] = value
    pos = place[q]
    if pos < 0:
        pos = size
        size += 1
    while pos > 0:
        parent = (pos - 1) // 2
        other = heap[parent]
        if _before(dist, other, q):
            break
        heap[pos] = other
        place[other] = pos
        pos = parent
    heap[pos] = q
    place[q] = pos
    return size


@helper
def _pop(heap, place, dist, size) -> int:
    """Take the heap's first cell off it; the new size."""
    place[heap[0]] = -2  # settled: never pushed again (its distance is final)
    size -= 1
    if size == 0:
        return 0
    q = heap[size]
    pos = 0
    while True:
        left, right, best = 2 * pos + 1, 2 * pos + 2, q
        at = -1
        if left < size and _before(dist, heap[left], best):
            best, at = heap[left], left
        if right < size and _before(dist, heap[right], best):
            best, at = heap[right], right
        if at < 0:
            break
        heap[pos] = best
        place[best] = pos
        pos = at
    heap[pos] = q
    place[q] = pos
    return size


@helper
def _before(dist, a, b) -> bool:
    """Does cell a come off the heap before cell b (nearer, or as near and lower)?"""
    return dist[a] < dist[b] or (dist[a] == dist[b] and a < b)


@helper
def _cell_at(detour, x, y, z):
    """The (i, j, k) of the detour grid's cell holding the point (x, y, z) m (may lie
    outside the grid)."""
    return (int(math.floor((x - detour.origin[0]) / detour.cell)),
            int(math.floor((y - detour.origin[1]) / detour.cell)),
            int(math.floor((z - detour.origin[2]) / detour.cell)))


@helper
def detour_at(detour, c, x, y, z) -> float:
    """The detour (m) of charge c's wave at the point (x, y, z) m: 0 outside the grid
    (the open) or where the wave reaches no air there (a face pressed against solid)."""
    i, j, k = _cell_at(detour, x, y, z)
    dims = detour.dims
    if not (0 <= i < dims[0] and 0 <= j < dims[1] and 0 <= k < dims[2]):
        return 0.0
    extra = detour.extra[c, (i * dims[1] + j) * dims[2] + k]
    return extra if math.isfinite(extra) else 0.0


#: Cells each way round a voxel's centre that :func:`voxel_detour` looks at: its faces'
#: air is within a cell and a half of it.
_AROUND = 2


@helper
def voxel_detour(detour, c, v, x, y, z) -> float:
    """The largest detour (m) of charge c's wave to the air round voxel v (centre
    (x, y, z) m as the wave arrived): the most any face of it can wait for the wave to
    come round. Kept in detour.voxel."""
    known = detour.voxel[v, c]
    if known >= 0.0:
        return known
    dims = detour.dims
    i0, j0, k0 = _cell_at(detour, x, y, z)
    most = 0.0
    for i in range(max(i0 - _AROUND, 0), min(i0 + _AROUND + 1, dims[0])):
        for j in range(max(j0 - _AROUND, 0), min(j0 + _AROUND + 1, dims[1])):
            for k in range(max(k0 - _AROUND, 0), min(k0 + _AROUND + 1, dims[2])):
                extra = detour.extra[c, (i * dims[1] + j) * dims[2] + k]
                if math.isfinite(extra) and extra > most:
                    most = extra
    detour.voxel[v, c] = most
    return most
