"""Members: how thick the structural element holding each voxel is, through itself.

The pressure-impulse criteria (:mod:`blastvox.simulate.fracture`) scale a
material's impulse asymptote with the thickness of the element the wave loads:
a 0.5 m wall takes twice the impulse of a 0.25 m one. That thickness is a
property of the *member* (the wall, slab or column), measured through it, not
along the line to the charge (a wall edge-on to a charge is as thin as face-on)
and not in voxels (a 0.25 m wall is 0.25 m thick at one, two or four voxels
through it, and 0.25 m when 0.1 m voxels do not divide it).

It is measured once per run on the shielding grid at rest
(:mod:`blastvox.simulate.shielding`): each cell holds the fraction of its
volume that is solid (the voxels' true volumes, spread over the cells each
covers); the chord of solid through a voxel along a direction is the sum of
those fractions along the run of occupied cells through it, times the step's
length; the member's thickness is the shortest chord over the 13 directions of
the grid (3 axes, 6 face diagonals, 4 body diagonals). Each direction is two
sweeps over the grid (running sums forward and backward), so the cost is
linear in the grid's cells, whatever the runs' lengths.

The line from an element to the charge can run along the member and leave it
through an edge (:func:`edge_on`): a wall edge-on to a charge. The wave then
sweeps along both faces at once and squeezes the element; it does not bend it,
and such an element's links do not break by the wave's bending load.

The thickness that resists a wave is at most the member's, and at most the
distance a longitudinal stress wave travels during the load's positive phase,
c t_d with c = sqrt(E / rho) (:func:`effective_thickness`): material deeper
than that has not felt the load when it ends (a massive block under a contact
charge is a crater, not a 10 m wall).
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.jit import helper, kernel
from blastvox.simulate.shielding import Occupancy, cells_of

#: The 13 directions of the grid, one of each opposite pair: (13, 3) cell steps.
DIRECTIONS = np.array([(1, 0, 0), (0, 1, 0), (0, 0, 1),
                       (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1),
                       (1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1)], dtype=np.int64)
#: The unit vectors of DIRECTIONS (13, 3): a member's normal is one of them.
MEMBER_NORMALS = DIRECTIONS / np.linalg.norm(DIRECTIONS, axis=1)[:, None]


@kernel
def solid_fractions(grid, lo, hi, volume, centroid):
    """(X*Y*Z,) the solid fraction (0..1) of each cell of ``grid`` (an
    :class:`~blastvox.simulate.shielding.Occupancy` at rest): each voxel's volume
    (N,) m^3 spread evenly over the cells it covers (the cells whose centres lie in
    its solid box (lo, hi (N, 3) m), or its centroid's (N, 3) m cell:
    :func:`~blastvox.simulate.shielding.cells_of`), clamped to 1."""
    cell, dims = grid.cell[0], grid.dims
    fraction = np.zeros(dims[0] * dims[1] * dims[2])
    cell_volume = cell * cell * cell
    for v in range(volume.shape[0]):
        i0, i1, j0, j1, k0, k1 = cells_of(grid, centroid, v, lo[v, 0], hi[v, 0], lo[v, 1],
                                          hi[v, 1], lo[v, 2], hi[v, 2])
        share = max(volume[v], 0.0) / (cell_volume * (i1 - i0 + 1) * (j1 - j0 + 1)
                                       * (k1 - k0 + 1))
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                for k in range(k0, k1 + 1):
                    fraction[(i * dims[1] + j) * dims[2] + k] += share
    for c in range(fraction.shape[0]):
        fraction[c] = min(fraction[c], 1.0)
    return fraction


@helper
def _run_sums(grid, fraction, di, dj, dk, out):
    """out[cell] = the sum of ``fraction`` over the run of occupied cells that starts
    at cell and goes on in steps (di, dj, dk) (0 for an empty cell): one sweep, each
    cell after the cell one step ahead of it."""
    nx, ny, nz = grid.dims[0], grid.dims[1], grid.dims[2]
    count = grid.count
    for a in range(nx):
        i = nx - 1 - a if di > 0 else a
        for b in range(ny):
            j = ny - 1 - b if dj > 0 else b
            for e in range(nz):
                k = nz - 1 - e if dk > 0 else e
                here = (i * ny + j) * nz + k
                if count[here] <= 0:
                    out[here] = 0.0
                    continue
                total = fraction[here]
                ii, jj, kk = i + di, j + dj, k + dk
                if 0 <= ii < nx and 0 <= jj < ny and 0 <= kk < nz:
                    total += out[(ii * ny + jj) * nz + kk]
                out[here] = total


@kernel
def member_thickness(grid, fraction, centroid, directions):
    """(thickness (N,) m, direction (N,) uint8): each voxel's member thickness, the
    shortest chord of solid through its centroid's (N, 3) m cell over ``directions``
    (D, 3) (see the module docstring), and the row of ``directions`` it runs along
    (the member's normal); grid: the shielding
    :class:`~blastvox.simulate.shielding.Occupancy` at rest, fraction:
    :func:`solid_fractions`. A voxel outside every occupied cell gets one cell's
    edge along the first direction."""
    origin, cell, dims = grid.origin, grid.cell[0], grid.dims
    n = centroid.shape[0]
    home = np.empty(n, dtype=np.int64)
    out = np.full(n, np.inf)
    along = np.zeros(n, dtype=np.uint8)
    for v in range(n):
        i = min(max(int((centroid[v, 0] - origin[0]) / cell), 0), dims[0] - 1)
        j = min(max(int((centroid[v, 1] - origin[1]) / cell), 0), dims[1] - 1)
        k = min(max(int((centroid[v, 2] - origin[2]) / cell), 0), dims[2] - 1)
        home[v] = (i * dims[1] + j) * dims[2] + k
    ahead = np.empty(fraction.shape[0])
    behind = np.empty(fraction.shape[0])
    for d in range(directions.shape[0]):
        di, dj, dk = directions[d, 0], directions[d, 1], directions[d, 2]
        _run_sums(grid, fraction, di, dj, dk, ahead)
        _run_sums(grid, fraction, -di, -dj, -dk, behind)
        step = cell * math.sqrt(di * di + dj * dj + dk * dk)
        for v in range(n):
            c = home[v]
            if grid.count[c] <= 0:
                continue
            chord = (ahead[c] + behind[c] - fraction[c]) * step
            if chord < out[v]:
                out[v] = chord
                along[v] = d
    for v in range(n):
        if not out[v] < np.inf or out[v] <= 0.0:
            out[v] = cell
            along[v] = 0
    return out, along


def thickness_at_rest(grid: Occupancy, boxes: tuple, volume: np.ndarray,
                      centroid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(thickness (N,) m, axis (N,) uint8): :func:`member_thickness` of the voxels
    (solid boxes (lo, hi) (N, 3) m, volume (N,) m^3, centroid (N, 3) m) on the
    shielding grid at rest, and the
    direction it is measured along, the member's normal in the rest frame: a row of
    :data:`MEMBER_NORMALS`."""
    if not len(volume):
        return np.zeros(0), np.zeros(0, dtype=np.uint8)
    fraction = solid_fractions(grid, *boxes, np.ascontiguousarray(volume, dtype=np.float64),
                               centroid)
    return member_thickness(grid, fraction, centroid, DIRECTIONS)


@helper
def edge_on(normal, axis, depth, thickness) -> bool:
    """Does the line to a charge run along the member: leave it through an edge (the
    exit face's ``axis`` 0..2 across the member's unit ``normal`` (3,), world frame,
    |n_axis| < 1/2) after more than twice its ``thickness`` (m) in it (``depth``, m)?
    Such an element is squeezed between the pressures on its two faces, not bent
    (UFC 3-340-02: a side wall is loaded on both faces as the wave sweeps along it)."""
    return axis >= 0 and abs(normal[axis]) < 0.5 and depth > 2.0 * thickness


def wave_speeds(arrays: dict) -> np.ndarray:
    """(M,) m/s: each material's longitudinal (bar) wave speed sqrt(E / rho), from its
    youngs_modulus (30 GPa for a model that predates the column) and density (a
    voxel's: that of its voxel_material)."""
    density = np.asarray(arrays["material_density"], dtype=np.float64)
    modulus = arrays.get("material_youngs_modulus")
    modulus = (np.full(len(density), 30e9) if modulus is None
               else np.asarray(modulus, dtype=np.float64))
    return np.ascontiguousarray(np.sqrt(modulus / density))


@helper
def effective_thickness(member, speed, duration) -> float:
    """The thickness (m) that resists a load of positive phase ``duration`` s: the
    member's (m), at most ``speed`` (m/s) x duration."""
    return min(member, speed * duration)
