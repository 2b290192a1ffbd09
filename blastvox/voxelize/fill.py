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

from blastvox.voxelize.conform import clip_volumes
from blastvox.voxelize.topology import face_neighbours, index_grid

#: A kept voxel never weighs less than this fraction of its cell (the contract wants
#: a positive mass; a voxel whose centre is inside holds half its cell or so).
MIN_FILL = 1e-3
#: A clipped cell within this fraction of its whole volume is whole (or, this close to
#: none, empty).
WHOLE = 1e-5


def fill_volumes(solid, candidates: np.ndarray, corners: np.ndarray, local_tris: np.ndarray,
                 block_keys: np.ndarray, cell_volume: np.ndarray, keep: np.ndarray,
                 ijk: np.ndarray, shape: tuple[int, int, int], centroid: np.ndarray,
                 advance=None) -> np.ndarray:
    """Each cell's volume of solid (m^3), (N,), for N cells (lattice indices ijk (N, 3)
    in a grid of ``shape``, centroids (N, 3) m) of which ``keep`` (N,) are voxels:
    ``cell_volume`` (N,) but at the ``candidates`` (K,) (the cells the surface
    crosses; corners (K, 8, 3) m, local_tris (K, 12, 3) and block_keys (K,) as for
    :func:`~blastvox.voxelize.conform.clip_cells`), where it is the cell's volume
    inside ``solid`` (a manifold3d Manifold). What a dropped candidate holds is shared
    equally by its kept face neighbours (a gap cell between two parts feeds both), or
    given to the nearest kept voxel if none; dropped cells end at 0."""
    fill = cell_volume.astype(np.float64).copy()
    if not len(candidates) or not keep.any():
        return fill
    inside = clip_volumes(solid, corners, local_tris, block_keys, advance)
    # a cell whose faces lie on the surface is whole: manifold3d's rounding of the
    # coplanar clip (1e-6) would make a one-voxel cube weigh more than its mesh
    whole = inside >= cell_volume[candidates] * (1.0 - WHOLE)
    empty = inside <= cell_volume[candidates] * WHOLE  # a cell touching it by a face
    fill[candidates] = np.where(whole, cell_volume[candidates], np.where(empty, 0.0, inside))
    dropped = candidates[~keep[candidates] & (fill[candidates] > 0.0)]
    if dropped.size:
        _hand_on(fill, dropped, keep, ijk, shape, centroid)
    fill[~keep] = 0.0
    np.maximum(fill, MIN_FILL * cell_volume, out=fill, where=keep)
    return fill


def _hand_on(fill: np.ndarray, dropped: np.ndarray, keep: np.ndarray, ijk: np.ndarray,
             shape: tuple[int, int, int], centroid: np.ndarray) -> None:
    """Add the fill of the ``dropped`` cells to kept ones (see :func:`fill_volumes`)."""
    kept = np.flatnonzero(keep)
    local = face_neighbours(ijk[dropped], index_grid(ijk[kept], shape))  # places in kept
    count = (local >= 0).sum(axis=1)
    rows, faces = np.nonzero(local >= 0)
    np.add.at(fill, kept[local[rows, faces]], (fill[dropped] / np.maximum(count, 1))[rows])
    lonely = dropped[count == 0]
    if lonely.size:
        from scipy.spatial import cKDTree

        _, nearest = cKDTree(centroid[kept]).query(centroid[lonely])
        np.add.at(fill, kept[nearest], fill[lonely])
