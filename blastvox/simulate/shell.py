"""Which links and voxels a shock front can cross this step, found through a rest grid.

Fracture tests each link midpoint and voxel centre against the shell between
the front's radius at the step's start and end. Testing all of them costs one
transform and distance per link per step while a front is inside the model,
though the shell holds a thin slice of them. Rest positions never change and
bodies are rigid, so a dense grid over the rest positions, built once, finds
the candidates: for each body the wave can touch, each charge is taken into
the body's rest frame, and only cells that meet both the body's rest sphere
and the shell are visited. Fracture then tests the flagged candidates exactly
as before, in the same order, so results do not change.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.geometry.transforms_nb import to_rest
from blastvox.jit import helper, kernel


@kernel
def dense_grid(points, cell):
    """CSR of point indices by the cell of a dense grid over their bounding box.

    points (P, 3) m; cell m. Returns origin (3,) m, dims (3,) cells, offsets
    (C + 1,) and ids (P,) int32: the points of cell (i, j, k) are
    ids[offsets[q]:offsets[q + 1]] with q = (i * dims[1] + j) * dims[2] + k.
    """
    origin = np.zeros(3)
    dims = np.ones(3, dtype=np.int64)
    n = points.shape[0]
    if n > 0:
        for a in range(3):
            lo, hi = points[0, a], points[0, a]
            for p in range(n):
                lo = min(lo, points[p, a])
                hi = max(hi, points[p, a])
            origin[a] = lo
            dims[a] = int((hi - lo) / cell) + 1
    cells = np.empty(n, dtype=np.int64)
    offsets = np.zeros(dims[0] * dims[1] * dims[2] + 1, dtype=np.int64)
    for p in range(n):
        q = 0
        for a in range(3):
            q = q * dims[a] + min(int((points[p, a] - origin[a]) / cell), dims[a] - 1)
        cells[p] = q
        offsets[q + 1] += 1
    for q in range(offsets.shape[0] - 1):
        offsets[q + 1] += offsets[q]
    fill = offsets[:-1].copy()
    ids = np.empty(n, dtype=np.int32)  # point ids: int32 as the model's voxel ids
    for p in range(n):
        ids[fill[cells[p]]] = p
        fill[cells[p]] += 1
    return origin, dims, offsets, ids


@helper
def _axis_gaps(p, lo, size):
    """Squared nearest and farthest distance (m^2) from p to [lo, lo + size] on one axis."""
    hi = lo + size
    near = max(lo - p, 0.0, p - hi)
    far = max(abs(p - lo), abs(p - hi))
    return near * near, far * far


@helper
def _box_distances(x, y, z, lo0, lo1, lo2, size):
    """Nearest and farthest distance (m) from (x, y, z) to the cube at lo of edge size."""
    n0, f0 = _axis_gaps(x, lo0, size)
    n1, f1 = _axis_gaps(y, lo1, size)
    n2, f2 = _axis_gaps(z, lo2, size)
    return math.sqrt(n0 + n1 + n2), math.sqrt(f0 + f1 + f2)


@kernel
def mark_in_shell(grid, cell, owner_voxel, voxel_body, active, bodies, front, out) -> None:
    """Flag in ``out`` (P,) the grid points of active bodies whose cell meets a shell.

    grid: (origin, dims, offsets, ids), a :func:`dense_grid` of cell ``cell`` (m);
    owner_voxel (P,): voxel whose body a point moves with. A point is flagged
    when its cell meets, in the rest frame of its body, both the body's rest
    sphere (centre of mass, radius body_radius) and the shell (front_in,
    front_out] (m) of some charge; front_out <= 0 means not detonated, front_in
    < 0 nothing passed yet. Flags are only ever set: clear ``out`` first.
    """
    origin, dims, offsets, ids = grid
    body_com, body_pos, body_rot, body_radius = bodies.com, bodies.pos, bodies.rot, bodies.radius
    charge_pos, front_in, front_out = front.position, front.inner, front.outer
    n_bodies = body_radius.shape[0]
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    for b in range(n_bodies):
        if not active[b]:
            continue
        rot = body_rot[b]
        for c in range(charge_pos.shape[0]):
            outer = front_out[c]
            if outer <= 0.0:
                continue
            inner = front_in[c]
            cx, cy, cz = to_rest(rot, body_pos[b], body_com[b], charge_pos[c, 0],
                                 charge_pos[c, 1], charge_pos[c, 2])
            empty = False
            for a in range(3):
                centre = cx if a == 0 else (cy if a == 1 else cz)
                first = max(centre - outer, body_com[b, a] - body_radius[b])
                last = min(centre + outer, body_com[b, a] + body_radius[b])
                if first > last:
                    empty = True
                    break
                lo[a] = max(0, int(math.floor((first - origin[a]) / cell)))
                hi[a] = min(dims[a] - 1, int(math.floor((last - origin[a]) / cell)))
                if lo[a] > hi[a]:
                    empty = True
                    break
            if empty:
                continue
            for i in range(lo[0], hi[0] + 1):
                for j in range(lo[1], hi[1] + 1):
                    for k in range(lo[2], hi[2] + 1):
                        near, far = _box_distances(cx, cy, cz, origin[0] + i * cell,
                                                   origin[1] + j * cell, origin[2] + k * cell,
                                                   cell)
                        # a hair of slack: a point on a cell's face may sit in either cell
                        slack = 1e-6 * cell
                        if near > outer + slack or (inner >= 0.0 and far <= inner - slack):
                            continue
                        q = (i * dims[1] + j) * dims[2] + k
                        for s in range(offsets[q], offsets[q + 1]):
                            p = ids[s]
                            if voxel_body[owner_voxel[p]] == b:
                                out[p] = True
