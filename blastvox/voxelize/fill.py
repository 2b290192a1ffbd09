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

#: A kept voxel never weighs less than this fraction of its cell (the contract wants
#: a positive mass; a voxel whose centre is inside holds half its cell or so).
MIN_FILL = 1e-3
#: A clipped cell within this fraction of its whole volume is whole (or, this close to
#: none, empty).
WHOLE = 1e-5


def fill_volumes(solid, candidates: np.ndarray, corners: np.ndarray, local_tris: np.ndarray,
                 block_keys: np.ndarray, cell_volume: np.ndarray, keep: np.ndarray,
                 ijk: np.ndarray, centroid: np.ndarray, advance=None) -> np.ndarray:
    """Each cell's volume of solid (m^3), (N,), for N cells (lattice indices ijk (N, 3),
    centroids (N, 3) m) of which ``keep`` (N,) are voxels: ``cell_volume`` (N,) but at
    the ``candidates`` (K,) (the cells the surface crosses; corners (K, 8, 3) m,
    local_tris (K, 12, 3) and block_keys (K,) as for
    :func:`~blastvox.voxelize.conform.clip_cells`), where it is the cell's volume
    inside ``solid`` (a manifold3d Manifold). What a dropped candidate holds is shared
    equally by its kept face neighbours (a gap cell between two parts feeds both), or
    given to the nearest kept voxel if none; dropped cells end at 0."""
    from blastvox.voxelize.conform import clip_volumes

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
        _hand_on(fill, dropped, keep, ijk, centroid)
    fill[~keep] = 0.0
    np.maximum(fill, MIN_FILL * cell_volume, out=fill, where=keep)
    return fill


def _hand_on(fill: np.ndarray, dropped: np.ndarray, keep: np.ndarray, ijk: np.ndarray,
             centroid: np.ndarray) -> None:
    """Add the fill of the ``dropped`` cells to kept ones (see :func:`fill_volumes`)."""
    kept = np.flatnonzero(keep)
    span = ijk.max(axis=0) + 3
    def key(cells: np.ndarray) -> np.ndarray:
        c = cells + 1  # neighbours of the lowest cells stay >= 0
        return (c[:, 0] * span[1] + c[:, 1]) * span[2] + c[:, 2]
    order = np.argsort(key(ijk[kept]))
    sorted_keys = key(ijk[kept])[order]
    neighbour = np.full((len(dropped), 6), -1, dtype=np.int64)
    for f, step in enumerate(((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1),
                              (0, 0, -1))):
        k = key(ijk[dropped] + np.array(step))
        at = np.minimum(np.searchsorted(sorted_keys, k), len(sorted_keys) - 1)
        found = sorted_keys[at] == k
        neighbour[found, f] = kept[order[at[found]]]
    count = (neighbour >= 0).sum(axis=1)
    has = count > 0
    rows, faces = np.nonzero(neighbour >= 0)
    np.add.at(fill, neighbour[rows, faces], (fill[dropped] / np.maximum(count, 1))[rows])
    if not has.all():
        from scipy.spatial import cKDTree

        lonely = dropped[~has]
        _, nearest = cKDTree(centroid[kept]).query(centroid[lonely])
        np.add.at(fill, kept[nearest], fill[lonely])
