"""A large island cut in parts that the solve's threads sweep side by side
(:func:`cut_island`).

Islands are solved each on its own thread, but a collapse piles most of its
pieces into one island (the building's rubble: up to 60 % of the rows), which
one thread then sweeps while the others wait. An island of at least
:data:`SPLIT_ROWS` rows is cut in :data:`PARTS` slabs side by side across the
ground, each holding about as many row ends: the rows within a part touch only
its bodies, so the parts' rows are swept at once, on as many threads; the rows
between two parts (the seam) are swept on one. The push-out sweep takes the seam
before the parts and again after them, so the parts start from the seam's
impulses of this sweep and the seam ends on theirs (swept only after them, a
stack that the seam cuts was solved top-down there: the dry-stacked brick wall
of the tests leaned 2 cm at dt 1/120 s); the relax sweep, in reverse, takes the
seam first and ends on the parts' lowest rows, the supports, as the uncut sweep
does (ending on the seam, the building's pile sank 0.43 voxels deep against 0.26
uncut, over 2.5-5 s). Within a part and the seam the rows keep the island's
support order, bottom up (a cut across the ground, never through a stack's
height). The cut and the sweeps' order are fixed by the island alone, never by
the thread count: the bytes are the same on any machine (PhysX and Box2D v3 part
islands the same way, by constraint partitions or graph colours).
"""

from __future__ import annotations

import numpy as np

from blastvox.jit import helper

#: Islands of at least this many rows are cut in parts: the second thread pays where
#: one island holds most of a step's rows (a collapse's rubble: 1,300-1,500 of the
#: building's), while the seam costs a stack some accuracy at coarse steps (the
#: dry-stacked wall of the tests, 146 rows at rest and up to 1,116 as it settles,
#: leaned 1.07 cm at dt 1/120 s with islands cut from 256 rows, 0.52 cm from 1,024).
SPLIT_ROWS = 1024
#: The parts a large island is cut in (the same on every machine: the bytes must not
#: depend on the thread count).
PARTS = 2


@helper
def cut_island(ends, rs, es, ids, pos, up):
    """Cut an island in :data:`PARTS` parts (see the module docstring). ends (count, 2):
    the rows' solve indices of their bodies (-1: does not move); rs: the island's rows
    in support order; es: its moving bodies (solve indices, ascending), ids: their
    bodies; pos (B, 3): bodies' positions (m); up (3,): the world's up (zero: none).

    Returns (row_start (PARTS + 2,), part_rows (len(rs),)): part p's rows
    part_rows[row_start[p]:row_start[p + 1]], the seam's last (p = PARTS), each in rs's
    order. Bodies are ranked along the axis (not the up axis) they spread most along,
    and dealt to parts by how many row ends they hold, so the parts sweep alike."""
    axis = _cut_axis(es, ids, pos, up)
    n = 0
    for e in es:
        n = max(n, e + 1)
    where = np.full(n, -1, dtype=np.int64)
    for i in range(len(es)):
        where[es[i]] = i
    weight = np.zeros(len(es), dtype=np.int64)
    for r in rs:
        for side in range(2):
            if ends[r, side] >= 0:
                weight[where[ends[r, side]]] += 1
    along = np.empty(len(es))
    for i in range(len(es)):
        along[i] = pos[ids[es[i]], axis]
    ranked = np.argsort(along, kind="mergesort")
    total = max(weight.sum(), 1)
    part = np.empty(n, dtype=np.int64)
    before = 0
    for i in ranked:
        part[es[i]] = min(PARTS * before // total, PARTS - 1)
        before += weight[i]
    return _group_rows(ends, rs, part)


@helper
def _cut_axis(es, ids, pos, up) -> int:
    """The world axis (0, 1, 2), other than the one nearest ``up``, along which bodies
    es spread most (ties: the lower axis)."""
    skip = -1
    if abs(up[0]) + abs(up[1]) + abs(up[2]) > 0.0:
        skip = 0
        for a in range(1, 3):
            if abs(up[a]) > abs(up[skip]):
                skip = a
    best, spread = -1, -1.0
    for a in range(3):
        if a == skip:
            continue
        lo, hi = np.inf, -np.inf
        for e in es:
            lo, hi = min(lo, pos[ids[e], a]), max(hi, pos[ids[e], a])
        if hi - lo > spread:
            best, spread = a, hi - lo
    return best


@helper
def _group_rows(ends, rs, part):
    """Rows rs grouped by part (part: each moving body's, by solve index), the rows
    between two parts last, each group in rs's order (see :func:`cut_island`)."""
    group = np.empty(len(rs), dtype=np.int64)
    row_start = np.zeros(PARTS + 2, dtype=np.int64)
    for q in range(len(rs)):
        ea, eb = ends[rs[q], 0], ends[rs[q], 1]
        pa = part[ea] if ea >= 0 else -1
        pb = part[eb] if eb >= 0 else -1
        g = pb if pa < 0 else pa if pb < 0 or pa == pb else PARTS
        group[q] = g
        row_start[g + 1] += 1
    for g in range(PARTS + 1):
        row_start[g + 1] += row_start[g]
    part_rows = np.empty(len(rs), dtype=np.int64)
    fill = row_start[:-1].copy()
    for q in range(len(rs)):
        part_rows[fill[group[q]]] = rs[q]
        fill[group[q]] += 1
    return row_start, part_rows
