"""Shielding: which points and faces the blast wave reaches in a straight line.

A wave loads a face directly only if the segment from the charge to the face
crosses no solid: a wall behind a wall, the far layer of a slab whose layers
have come apart, or a face pressed against another piece is in the shadow and
takes the diffracted load instead (:mod:`blastvox.blast.face_load`). Solid is
an occupancy grid over the rest geometry:

* cells of edge ``cell`` m (the model's typical voxel edge, coarsened so that
  the grid holds at most ``MAX_CELLS`` cells) over the model's bounding box;
* a voxel occupies the cells whose centres lie in its rest bounding box (at
  least the cell of its centroid); a count per cell, so overlapping jittered
  voxels share cells;
* a voxel leaves the grid when it turns to dust or when its body has moved
  more than a quarter cell from rest (debris in flight no longer shadows where
  it started; a moved body's own faces are then always directly loaded).
  Nothing ever re-enters. Moved pieces leave the grid when a wave arrives
  (the first step a wave's front reaches a body, by the engine's step), not
  while it passes: they move little within a wave. A voxel turned to dust
  leaves at once, and fracture takes the points a step's front crosses in
  order of distance from the charge, so a point behind a voxel the same wave
  pulverized sees the gap whatever the step. Every ray is cast afresh.

Rays are walked cell by cell (Amanatides & Woo 1987, "A fast voxel traversal
algorithm for ray tracing", Eurographics), from the point towards the charge,
up to the charge or the grid's edge.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from blastvox.blast._numeric import cbrt
from blastvox.geometry.boxes import corner_boxes, triangle_boxes
from blastvox.jit import helper, kernel

MAX_CELLS = 1 << 23   #: the grid's cell budget (16 MiB of int16 counts)
_HUGE = 1.0e300


class Occupancy(NamedTuple):
    """The shielding grid. origin (3,) m: corner of cell (0, 0, 0); cell (1,) m: edge;
    dims (3,) int64 cells per axis; count (X*Y*Z,) int16: voxels covering each cell;
    member (N,) bool: the voxel still counts in the grid. What each voxel's solid box
    at rest (:func:`solid_boxes`) is worked out from, by :func:`solid_box` (the
    model's arrays, shared: the boxes took 46 MiB at a million voxels): vertices (V, 3)
    m and corners (N, 8), slot (N,) the voxel's row in box_lo, box_hi (C, 3) m, the
    boxes of the conform voxels (:func:`conform_boxes`), or -1."""

    origin: np.ndarray
    cell: np.ndarray
    dims: np.ndarray
    count: np.ndarray
    member: np.ndarray
    vertices: np.ndarray
    corners: np.ndarray
    slot: np.ndarray
    box_lo: np.ndarray
    box_hi: np.ndarray


def conform_boxes(vertices: np.ndarray, corners: np.ndarray, conform_voxels: np.ndarray,
                  conform_offsets: np.ndarray, conform_triangles: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The solid bounding boxes at rest (lo, hi) (C, 3) m of the C conform voxels
    (conform_voxels (C,), conform_offsets (C+1,), conform_triangles (T, 3, 3) m: the
    model's): the box of their exact geometry, or where one has no triangles its
    corners' (vertices (V, 3) m, corners (N, 8)). A cut voxel's lattice cell spans
    air: a 0.3 m plate cut from 0.5 m cells would cover the air before its own face
    and shadow it."""
    lo, hi = corner_boxes(vertices, np.ascontiguousarray(corners[conform_voxels]))
    if len(conform_voxels):
        starts = np.asarray(conform_offsets[:-1], dtype=np.int64)
        has = np.asarray(conform_offsets[1:], dtype=np.int64) > starts
        lo[has], hi[has] = triangle_boxes(conform_triangles, starts[has])
    return lo, hi


def solid_boxes(vertices: np.ndarray, corners: np.ndarray, conform_voxels: np.ndarray,
                box_lo: np.ndarray, box_hi: np.ndarray,
                corner: tuple[np.ndarray, np.ndarray] | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Each voxel's solid bounding box at rest, (lo, hi) (N, 3) m: its corners' box
    (vertices (V, 3) m, corners (N, 8)), or for a conform voxel (conform_voxels (C,))
    its box (box_lo, box_hi (C, 3) m: :func:`conform_boxes`). corner: the corners'
    boxes (lo, hi) if worked out already (:func:`corner_boxes`): they are changed
    into the result."""
    lo, hi = corner_boxes(vertices, corners) if corner is None else corner
    lo[conform_voxels] = box_lo
    hi[conform_voxels] = box_hi
    return lo, hi


@helper
def solid_box(grid, v, a):
    """(lo, hi) m of voxel v's solid box at rest along axis a (:func:`solid_boxes`,
    its values to the bit: the same minima and maxima, in the same order)."""
    s = grid.slot[v]
    if s >= 0:
        return grid.box_lo[s, a], grid.box_hi[s, a]
    corners, vertices = grid.corners, grid.vertices
    x = vertices[corners[v, 0], a]
    lo, hi = x, x
    for k in range(1, 8):
        x = vertices[corners[v, k], a]
        lo = min(lo, x)
        hi = max(hi, x)
    return lo, hi


def build_occupancy(vertices: np.ndarray, corners: np.ndarray, conform: tuple,
                    boxes: tuple, centroid: np.ndarray, cell: float) -> Occupancy:
    """The grid of every voxel at rest. vertices (V, 3) m, corners (N, 8); conform:
    the conform voxels' (slot (N,), their rows or -1; box_lo, box_hi (C, 3) m:
    :func:`conform_boxes`); boxes: (lo, hi) (N, 3) m, every voxel's solid box
    (:func:`solid_boxes`, for the fill; the grid keeps none); centroid (N, 3) m; cell:
    the wanted edge, m (coarsened to MAX_CELLS)."""
    n = len(corners)
    slot, box_lo, box_hi = conform
    if n == 0:
        return Occupancy(np.zeros(3), np.ones(1), np.ones(3, dtype=np.int64),
                         np.zeros(1, dtype=np.int16), np.zeros(0, dtype=bool),
                         vertices, corners, slot, box_lo, box_hi)
    lo, hi = boxes
    low, high = lo.min(axis=0), hi.max(axis=0)
    extent = np.maximum(high - low, 0.0)
    cell = float(cell) if cell > 0.0 and math.isfinite(cell) else float(extent.max() or 1.0)
    while np.prod(np.floor(extent / cell) + 1.0) > MAX_CELLS:
        cell *= 1.25
    dims = (np.floor(extent / cell) + 1).astype(np.int64)
    grid = Occupancy(low.astype(np.float64), np.array([cell]), dims,
                     np.zeros(int(np.prod(dims)), dtype=np.int16), np.ones(n, dtype=bool),
                     vertices, corners, slot, box_lo, box_hi)
    _fill(grid, lo, hi, centroid)
    return grid


def typical_edge(volume: np.ndarray, conform: np.ndarray, vertices: np.ndarray,
                 corners: np.ndarray) -> float:
    """A voxel edge (m) for the grid: the lattice's. The median edge of the whole
    voxels (not cut by a surface), cube roots of their volumes (N,) m^3; where every
    voxel is cut (conform (N,) bool; a thin wall's voxels all are), the median
    smallest edge of their corners' boxes (vertices (V, 3) m, corners (N, 8)): the
    lattice cells they were cut from. A cut voxel's own volume would give a cell
    smaller than the lattice's, out of step with it, so that the cells of a wall
    overlap the air beside it and the wall shadows its own inner face."""
    whole = volume[~conform]
    whole = whole[whole > 0.0]
    if whole.size:
        return float(np.median(cbrt(whole)))
    if len(corners):
        box = vertices[corners]
        edge = (box.max(axis=1) - box.min(axis=1)).min(axis=1)
        edge = edge[edge > 0.0]
        if edge.size:
            return float(np.median(edge))
    return 1.0


@helper
def cell_range(lo, hi, origin, cell, dims, a):
    """First and last cell along axis a whose centre lies in [lo, hi] (may be empty)."""
    first = int(math.ceil((lo - origin[a]) / cell - 0.5 - 1e-9))
    last = int(math.floor((hi - origin[a]) / cell - 0.5 + 1e-9))
    return max(first, 0), min(last, dims[a] - 1)


@helper
def cells_of(grid, centroid, v, lo0, hi0, lo1, hi1, lo2, hi2):
    """(i0, i1, j0, j1, k0, k1): the cells voxel v covers along each axis, the cells
    whose centres lie in its solid box (lo0..hi0, lo1..hi1, lo2..hi2 m:
    :func:`solid_box`), or its centroid's (centroid (N, 3) m) if none does (see the
    module docstring)."""
    origin, cell, dims = grid.origin, grid.cell[0], grid.dims
    i0, i1 = cell_range(lo0, hi0, origin, cell, dims, 0)
    j0, j1 = cell_range(lo1, hi1, origin, cell, dims, 1)
    k0, k1 = cell_range(lo2, hi2, origin, cell, dims, 2)
    if i0 > i1 or j0 > j1 or k0 > k1:  # smaller than a cell: the centroid's cell
        i0 = i1 = min(max(int((centroid[v, 0] - origin[0]) / cell), 0), dims[0] - 1)
        j0 = j1 = min(max(int((centroid[v, 1] - origin[1]) / cell), 0), dims[1] - 1)
        k0 = k1 = min(max(int((centroid[v, 2] - origin[2]) / cell), 0), dims[2] - 1)
    return i0, i1, j0, j1, k0, k1


@helper
def box_cells(grid, centroid, v):
    """:func:`cells_of` voxel v, its solid box worked out (:func:`solid_box`)."""
    lo0, hi0 = solid_box(grid, v, 0)
    lo1, hi1 = solid_box(grid, v, 1)
    lo2, hi2 = solid_box(grid, v, 2)
    return cells_of(grid, centroid, v, lo0, hi0, lo1, hi1, lo2, hi2)


@helper
def _count(grid, cells, delta):
    """Add delta to the count of the cells (i0, i1, j0, j1, k0, k1) (:func:`cells_of`)."""
    dims, count = grid.dims, grid.count
    i0, i1, j0, j1, k0, k1 = cells
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                count[(i * dims[1] + j) * dims[2] + k] += delta


@kernel
def _fill(grid, lo, hi, centroid):
    """Count every voxel in the grid, their solid boxes lo, hi (N, 3) m given."""
    for v in range(lo.shape[0]):
        _count(grid, cells_of(grid, centroid, v, lo[v, 0], hi[v, 0], lo[v, 1], hi[v, 1],
                              lo[v, 2], hi[v, 2]), 1)


@kernel
def refresh_occupancy(grid, geometry, voxels, bodies) -> int:
    """Take out of the grid the voxels that are dust or whose body has moved more
    than a quarter cell from rest; returns how many left. geometry: the model's
    VoxelGeometry; voxels, bodies: the state's."""
    member, alive, voxel_body = grid.member, voxels.alive, voxels.body
    tolerance = 0.25 * grid.cell[0]
    removed = 0
    for v in range(member.shape[0]):
        if not member[v]:
            continue
        if alive[v] and not moved(bodies, voxel_body[v], tolerance):
            continue
        remove_voxel(grid, geometry, v)
        removed += 1
    return removed


@helper
def remove_voxel(grid, geometry, v) -> None:
    """Take voxel v out of the grid (if it is in)."""
    if not grid.member[v]:
        return
    _count(grid, box_cells(grid, geometry.centroid, v), -1)
    grid.member[v] = False


@helper
def moved(bodies, b, tolerance) -> bool:
    """Has body b's farthest point moved more than ``tolerance`` m from rest?"""
    if bodies.fixed[b]:
        return False
    shift = math.sqrt((bodies.pos[b, 0] - bodies.com[b, 0]) ** 2
                      + (bodies.pos[b, 1] - bodies.com[b, 1]) ** 2
                      + (bodies.pos[b, 2] - bodies.com[b, 2]) ** 2)
    w = min(abs(bodies.quat[b, 0]), 1.0)
    angle = 2.0 * math.acos(w)
    return shift + bodies.radius[b] * angle > tolerance


@helper
def grid_cell(grid, x, y, z) -> int:
    """The flat index of the grid cell holding the point (x, y, z) m, or -1 outside."""
    p = (x, y, z)
    q = 0
    for a in range(3):
        i = math.floor((p[a] - grid.origin[a]) / grid.cell[0])
        if i < 0 or i >= grid.dims[a]:
            return -1
        q = q * grid.dims[a] + int(i)
    return q


@helper
def _occupied(grid, i, j, k) -> bool:
    dims = grid.dims
    return grid.count[(i * dims[1] + j) * dims[2] + k] > 0


@helper
def ray_blocked(grid, px, py, pz, qx, qy, qz, skip_own) -> bool:
    """Does the segment from p to q (m) cross an occupied cell? See :func:`sight_line`."""
    return sight_line(grid, px, py, pz, qx, qy, qz, skip_own)[0]


@helper
def sight_line(grid, px, py, pz, qx, qy, qz, skip_own):
    """(blocked, exit axis, exit depth m) of the segment from p to q (m).

    skip_own: the point p lies in solid (a link midpoint, a voxel centre): the
    run of occupied cells that holds p is its own element and is skipped; the
    segment is blocked only by solid after air, and the run's end gives the
    axis (0..2) of the face the segment leaves it through and its length from
    p (the point's depth below the surface facing q); axis -1 and depth 0 when
    p is not in solid. Otherwise the first cell counts too. Outside the grid
    nothing blocks.
    """
    origin, cell, dims = grid.origin, grid.cell[0], grid.dims
    d = (qx - px, qy - py, qz - pz)
    length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    p = (px, py, pz)
    # clip the segment's parameter range [0, 1] to the grid's box
    t_lo, t_hi = 0.0, 1.0
    clip_axis = -1  # the axis of the grid's face the segment leaves it through, if it does
    for a in range(3):
        lo = origin[a]
        hi = origin[a] + dims[a] * cell
        if d[a] == 0.0:
            if p[a] < lo or p[a] >= hi:
                return False, -1, 0.0
            continue
        t0 = (lo - p[a]) / d[a]
        t1 = (hi - p[a]) / d[a]
        if t0 > t1:
            t0, t1 = t1, t0
        t_lo = max(t_lo, t0)
        if t1 < t_hi:
            t_hi, clip_axis = t1, a
    if t_lo > t_hi:
        return False, -1, 0.0
    if t_lo > 0.0 and skip_own:
        skip_own = False  # p is outside the grid: it cannot be inside solid
    # the walk's state in scalars, not arrays: registers, no allocation per ray
    ix, sx, nx, tx = _axis_start(p[0], d[0], origin[0], t_lo, cell, dims[0])
    iy, sy, ny, ty = _axis_start(p[1], d[1], origin[1], t_lo, cell, dims[1])
    iz, sz, nz, tz = _axis_start(p[2], d[2], origin[2], t_lo, cell, dims[2])
    count, stride_x, stride_y = grid.count, dims[1] * dims[2], dims[2]
    flat = (ix * dims[1] + iy) * dims[2] + iz  # as _occupied's index
    in_own = skip_own and count[flat] > 0
    exit_axis, exit_depth = -1, 0.0
    last_axis, last_t = -1, 0.0
    while True:
        solid = count[flat] > 0
        if in_own:
            if not solid:
                in_own = False
                exit_axis, exit_depth = last_axis, last_t * length
        elif solid:
            return True, exit_axis, exit_depth
        # the axis whose next cell boundary comes first (the lower axis on a tie)
        a, t_next = (1, ny) if ny < nx else (0, nx)
        if nz < t_next:
            a, t_next = 2, nz
        if t_next > t_hi:
            break
        if a == 0:
            ix += sx
            if ix < 0 or ix >= dims[0]:
                break
            flat += sx * stride_x
            nx += tx
        elif a == 1:
            iy += sy
            if iy < 0 or iy >= dims[1]:
                break
            flat += sy * stride_y
            ny += ty
        else:
            iz += sz
            if iz < 0 or iz >= dims[2]:
                break
            flat += sz
            nz += tz
        last_axis, last_t = a, t_next
    if in_own:  # never left solid inside the grid: it leaves through the grid's face
        # (the axis of the last cell stepped was not that face's: a wall at the grid's low
        # edge took its inner links as loaded at normal incidence from one side only)
        exit_axis, exit_depth = clip_axis, t_hi * length
    return False, exit_axis, exit_depth


@helper
def _axis_start(p, d, origin, t_lo, cell, dim):
    """One axis of :func:`sight_line`'s walk (Amanatides & Woo): from the point p (m)
    along d (m, the segment's extent on this axis), entering the grid at parameter
    t_lo: (first cell's index, step -1/0/1, parameter of the next cell boundary,
    parameter per cell)."""
    x = (p + t_lo * d - origin) / cell
    idx = min(max(int(math.floor(x)), 0), dim - 1)
    if d > 0.0:
        return idx, 1, t_lo + ((idx + 1) - x) * cell / d, cell / d
    if d < 0.0:
        return idx, -1, t_lo + (idx - x) * cell / d, -cell / d
    return idx, 0, _HUGE, _HUGE


@kernel
def inside_solid(grid, point) -> bool:
    """Is ``point`` (3,) m inside the solid: are the grid cells all around it occupied?

    A point on the solid's surface (a charge snapped to a wall's face, edge or
    corner, as a DCC snaps it) is a contact charge, not a buried one: it is probed
    a thousandth of a cell away along each of the eight diagonals, and is inside
    only if every probe is in an occupied cell."""
    reach = 1e-3 * grid.cell[0]
    for corner in range(8):
        if not _cell_occupied(grid, point[0] + reach * (2 * (corner & 1) - 1),
                              point[1] + reach * (2 * ((corner >> 1) & 1) - 1),
                              point[2] + reach * (2 * ((corner >> 2) & 1) - 1)):
            return False
    return True


@helper
def _cell_occupied(grid, x, y, z) -> bool:
    """Is the grid cell holding the point (x, y, z) m occupied (False outside the grid)?"""
    i = (x - grid.origin[0]) / grid.cell[0]
    j = (y - grid.origin[1]) / grid.cell[0]
    k = (z - grid.origin[2]) / grid.cell[0]
    if not (i >= 0.0 and j >= 0.0 and k >= 0.0):  # NaN is outside too
        return False
    if i >= grid.dims[0] or j >= grid.dims[1] or k >= grid.dims[2]:
        return False
    return _occupied(grid, int(i), int(j), int(k))


@kernel
def rays_blocked(grid, points, target, skip_own):
    """:func:`ray_blocked` from each of points (P, 3) to target (3,), m (for tests and
    tools); returns (P,) bool."""
    out = np.zeros(points.shape[0], dtype=np.bool_)
    for i in range(points.shape[0]):
        out[i] = ray_blocked(grid, points[i, 0], points[i, 1], points[i, 2], target[0],
                             target[1], target[2], skip_own)
    return out
