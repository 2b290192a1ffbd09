"""Mass that does not depend on the voxel size: each cube voxel's share of the solid.

A cube voxel is kept when its centre is inside the mesh, so a wall whose thickness
the voxel size does not divide gains or loses a whole layer (a 0.25 m brick wall in
0.1 m cubes is three voxels thick: 0.3 m, +20 % of its mass). The voxels keep their
cube shape (contacts, links and the look are the lattice's), but their mass is the
solid's: where the surface crosses a cell, the cell's volume inside the mesh (the
cell clipped by the solid with manifold3d, exactly), and what a dropped cell (centre
outside) holds inside goes to the nearest kept voxel. So a model weighs its mesh's
volume times its density at any voxel size (to the clip's rounding).
"""

from __future__ import annotations

import numpy as np

from blastvox.errors import MeshError
from blastvox.geometry.boxes import corner_boxes, triangle_boxes
from blastvox.voxelize.conform import (
    block_keys_for,
    clip_volumes,
    solid_manifold,
)
from blastvox.voxelize.topology import face_neighbours, index_grid

#: A kept voxel never weighs less than this fraction of its cell (the contract wants
#: a positive mass; a voxel whose centre is inside holds half its cell or so).
MIN_FILL = 1e-3
#: A clipped cell within this fraction of its whole volume is whole (or, this close to
#: none, empty).
WHOLE = 1e-5


def fill_volumes(solid, candidates: np.ndarray, clip: tuple, cell_volume: np.ndarray,
                 keep: np.ndarray, ijk: np.ndarray, shape: tuple[int, int, int],
                 centroid: np.ndarray, bounds: np.ndarray, advance=None) -> np.ndarray:
    """Each cell's volume of solid (m^3), (N,), for N cells (lattice indices ijk (N, 3)
    in a grid of ``shape``, centroids (N, 3) m) of which ``keep`` (N,) are voxels:
    ``cell_volume`` (N,) but at the ``candidates`` (K,) (the cells the surface
    crosses; clip: the lattice vertices (V, 3) m, the candidates' corners (K, 8) rows of
    them and block_keys (K,), as for :func:`~blastvox.voxelize.conform.clip_cells`),
    where it is the cell's volume inside ``solid`` (a manifold3d Manifold). What a
    dropped candidate holds is shared equally by its kept face neighbours (a gap cell
    between two parts feeds both), or given to the nearest kept voxel if none; dropped
    cells end at 0.

    bounds (N, 2, 3) m: each cell's (lo, hi), updated in place to the bounds of the
    solid it holds: a candidate's clipped solid, grown by what it was handed (the
    voxel's contact box, :func:`blastvox.simulate.contact.fragments.voxel_boxes`: so a
    0.25 m slab in 0.2 m cubes touches what it touches, not 0.15 m beyond)."""
    fill = cell_volume.astype(np.float64).copy()
    if not len(candidates) or not keep.any():
        return fill
    inside, clipped = clip_volumes(solid, *clip, advance)
    # a cell whose faces lie on the surface is whole: manifold3d's rounding of the
    # coplanar clip (1e-6) would make a one-voxel cube weigh more than its mesh
    whole = inside >= cell_volume[candidates] * (1.0 - WHOLE)
    empty = inside <= cell_volume[candidates] * WHOLE  # a cell touching it by a face
    fill[candidates] = np.where(whole, cell_volume[candidates], np.where(empty, 0.0, inside))
    cut = candidates[~whole & ~empty]
    bounds[cut] = clipped[~whole & ~empty]
    dropped = candidates[~keep[candidates] & (fill[candidates] > 0.0)]
    if dropped.size:
        _hand_on(fill, bounds, dropped, keep, ijk, shape, centroid)
    fill[~keep] = 0.0
    np.maximum(fill, MIN_FILL * cell_volume, out=fill, where=keep)
    return fill


def _hand_on(fill: np.ndarray, bounds: np.ndarray, dropped: np.ndarray, keep: np.ndarray,
             ijk: np.ndarray, shape: tuple[int, int, int], centroid: np.ndarray) -> None:
    """Add the fill of the ``dropped`` cells to kept ones, and their solid's bounds to
    the kept ones' (see :func:`fill_volumes`)."""
    kept = np.flatnonzero(keep)
    local = face_neighbours(ijk[dropped], index_grid(ijk[kept], shape))  # places in kept
    count = (local >= 0).sum(axis=1)
    rows, faces = np.nonzero(local >= 0)
    to = kept[local[rows, faces]]
    np.add.at(fill, to, (fill[dropped] / np.maximum(count, 1))[rows])
    # a receiver's box reaches across the shared face to the far side of the solid it
    # took, when it is the only one: the solid of a gap cell between two parts is two
    # slivers, one against each, and a cell in a corner where two walls meet holds an
    # L whose box, added to both, would make them overlap
    alone = count[rows] == 1
    axis, below = faces // 2, faces % 2 == 0  # face f of the dropped cell: -x, +x, ...
    grow = alone & below  # the receiver lies below: its top moves up
    np.maximum.at(bounds[:, 1], (to[grow], axis[grow]), bounds[dropped[rows[grow]], 1,
                                                              axis[grow]])
    grow = alone & ~below
    np.minimum.at(bounds[:, 0], (to[grow], axis[grow]), bounds[dropped[rows[grow]], 0,
                                                              axis[grow]])
    lonely = dropped[count == 0]
    if lonely.size:  # a speck of solid off the voxels: its mass, not its reach
        from scipy.spatial import cKDTree

        _, nearest = cKDTree(centroid[kept]).query(centroid[lonely])
        np.add.at(fill, kept[nearest], fill[lonely])


def corner_bounds(positions: np.ndarray, voxel_vertices: np.ndarray) -> np.ndarray:
    """(N, 2, 3) m: (lo, hi) of each cell's corners (positions (V, 3) m, voxel_vertices
    (N, 8) rows of it)."""
    return np.stack(corner_boxes(positions, voxel_vertices), axis=1)


def triangle_bounds(triangles: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(C, 2, 3) m: (lo, hi) of each of C triangle sets (triangles (T, 3, 3) m; set c is
    offsets[c]:offsets[c+1], none empty): a conform voxel's solid."""
    return np.stack(triangle_boxes(triangles, np.asarray(offsets[:-1], dtype=np.int64)),
                    axis=1)


def cube_fill(solids, chosen, shape: tuple[int, int, int], cells: tuple, volume: np.ndarray,
              keep: np.ndarray, centroid: np.ndarray, solid_box: np.ndarray, progress,
              origin) -> np.ndarray:
    """Each cell's volume of solid (m^3, (N,)): the cells the surface crosses
    (``chosen``, :mod:`blastvox.voxelize.cells`) clipped by the closed ``solids``,
    dropped ones given to the nearest kept voxel (:func:`fill_volumes`), and solid_box
    (N, 2, 3) m set to their solid's bounds. cells: (positions (V, 3) m, voxel_vertices
    (N, 8)) in a grid of ``shape``; volume (N,) m^3 the cells'. A surface that is not a
    closed manifold (holes, a soup: the winding number still says what is inside)
    encloses no exact volume to clip: its voxels weigh, and reach, their cells."""
    candidates = np.flatnonzero(chosen.touched)
    if not solids or not candidates.size:
        return volume.copy()
    try:
        solid = solid_manifold(solids[0].mesh, solids[0].label, origin)
        for other in solids[1:]:
            solid = solid + solid_manifold(other.mesh, other.label, origin)
    except MeshError:
        return volume.copy()
    progress.start(f"fill ({len(candidates):,} cells)", len(candidates))
    positions, voxel_vertices = cells
    clip = (positions, voxel_vertices[candidates], block_keys_for(chosen.ijk[candidates]))
    return fill_volumes(solid, candidates, clip, volume, keep, chosen.ijk, shape, centroid,
                        solid_box, progress.advance)


def solid_mass_frame(volume: np.ndarray, solid_box: np.ndarray, cell_box: np.ndarray,
                     centroid: np.ndarray, inertia: np.ndarray) -> None:
    """Cube cells whose solid's box (solid_box (N, 2, 3) m) is not their cell's
    (cell_box), cut by the surface or grown by a dropped neighbour's solid, are centred
    on that box and take its inertia (per unit density, scaled to the cell's volume
    (N,) m^3 as ``inertia`` (N, 3, 3) is): a 0.25 m slab's face layer in 0.2 m cubes
    weighs, turns and touches where its solid is, not 0.1 m off it."""
    cut = np.flatnonzero((solid_box != cell_box).any(axis=(1, 2)))
    if not cut.size:
        return
    lo, hi = solid_box[cut, 0], solid_box[cut, 1]
    centroid[cut] = 0.5 * (lo + hi)
    half_sq = (0.5 * (hi - lo)) ** 2
    inertia[cut] = 0.0
    for a in range(3):
        inertia[cut, a, a] = volume[cut] * (half_sq.sum(axis=1) - half_sq[:, a]) / 3.0
