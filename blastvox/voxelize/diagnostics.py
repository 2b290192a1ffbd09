"""What the voxels say about an asset that would spoil a shot, warned about at voxelize.

Neither is an error: the model is valid and the run works, but the shot would not be
what the artist modelled. Each check warns with one line naming the meshes and what
to change.

* :func:`warn_islands`: parts of one mesh that the voxel size cut off from the rest
  (an ear tip, a handle), which become free objects that fall or fly.
* :func:`warn_overlaps`: objects whose solids overlap, whose pieces push each other
  apart as soon as they move (a blockout of intersecting boxes).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from blastvox.voxelize.components import component_labels
from blastvox.voxelize.lattice import Grid

#: A connected part of one mesh's voxels with fewer than this fraction of its largest
#: part's voxels is a fragment the voxel size cut off, not a part of the asset.
ISLAND_FRACTION = 0.05


def warn_islands(name: str, link_voxels: np.ndarray, count: int, size_label: str,
                 warn: Callable[[str], None]) -> None:
    """Warn about the voxels of one mesh (``count`` voxels, linked by link_voxels (L, 2))
    that the voxel size cut off from the rest: where the mesh is thinner than a voxel,
    the voxels do not touch, and each such island becomes an object of its own."""
    counts = np.bincount(component_labels(link_voxels, count))
    small = np.sort(counts[counts < ISLAND_FRACTION * counts.max()])
    if small.size:
        sizes = f"{small[0]:,}" if small[0] == small[-1] else f"{small[0]:,} to {small[-1]:,}"
        warn(f"{size_label}: {small.size} part(s) of {sizes} voxels lie cut off from the rest "
             f"of {name} ({counts.max():,} voxels) where the mesh is thinner than a "
             "voxel; each is an object of its own that falls or flies free: use a smaller "
             "voxel size")


def warn_overlaps(objects: list[tuple[str, Grid, np.ndarray, np.ndarray, np.ndarray]],
                  warn: Callable[[str], None]) -> None:
    """Warn about each pair of objects whose voxels overlap. objects: per requested mesh,
    (name, its grid, its voxels' cells (N, 3) int, centroids (N, 3) m, volumes (N,) m^3).
    A voxel of the second whose centroid lies in a cell the first fills is inside it.

    Only pairs whose bounding boxes overlap are compared (sweep and prune along x), so
    a thousand separate objects cost a sort, not half a million comparisons (1,000
    cubes: 33 s of a 48 s voxelize before); at most :data:`MAX_OVERLAP_WARNINGS` pairs
    are named, then one line counts the rest."""
    boxes = np.array([_box(grid, ijk) for _, grid, ijk, _, _ in objects]).reshape(-1, 2, 3)
    warned = 0
    for i, j in _touching_pairs(boxes):
        name_a, grid_a, ijk_a, _, _ = objects[i]
        name_b, _, _, centroid_b, volume_b = objects[j]
        inside = _inside(grid_a, ijk_a, centroid_b)
        if not inside.any():
            continue
        warned += 1
        if warned <= MAX_OVERLAP_WARNINGS:
            warn(f"{name_b} overlaps {name_a}: {int(inside.sum()):,} of its voxels "
                 f"({float(volume_b[inside].sum()):.3g} m3) lie inside it; once they "
                 "move, the overlapping pieces push each other apart and throw debris: "
                 "model them apart, or as one mesh")
    if warned > MAX_OVERLAP_WARNINGS:
        warn(f"{warned - MAX_OVERLAP_WARNINGS:,} more pairs of objects overlap (the first "
             f"{MAX_OVERLAP_WARNINGS} are named above)")


#: The overlapping pairs named one by one; the rest are counted in one line.
MAX_OVERLAP_WARNINGS = 20


def _box(grid: Grid, ijk: np.ndarray) -> np.ndarray:
    """(2, 3) m: the box of the cells ``ijk`` fills in ``grid``."""
    if not len(ijk):
        return np.array([[np.inf] * 3, [-np.inf] * 3])
    lo = grid.origin + ijk.min(axis=0) * grid.spacing
    return np.array([lo, grid.origin + (ijk.max(axis=0) + 1) * grid.spacing])


def _touching_pairs(boxes: np.ndarray) -> list[tuple[int, int]]:
    """The pairs (i < j) of boxes (K, 2, 3) that overlap, in (i, j) order: sweep and
    prune along x."""
    order = np.argsort(boxes[:, 0, 0], kind="stable")
    pairs = []
    active: list[int] = []
    for k in order.tolist():
        lo_x = boxes[k, 0, 0]
        active = [a for a in active if boxes[a, 1, 0] >= lo_x]
        for a in active:
            if np.all(boxes[a, 0] <= boxes[k, 1]) and np.all(boxes[k, 0] <= boxes[a, 1]):
                pairs.append((min(a, k), max(a, k)))
        active.append(k)
    return sorted(pairs)


def _inside(grid_a: Grid, ijk_a: np.ndarray, centroid_b: np.ndarray) -> np.ndarray:
    """(M,) bool: which centroids (M, 3) lie in a cell that ijk_a fills in grid_a."""
    filled = np.ravel_multi_index(ijk_a.T, grid_a.shape)
    cell = np.floor((centroid_b - grid_a.origin) / grid_a.spacing).astype(np.int64)
    within = np.all((cell >= 0) & (cell < np.asarray(grid_a.shape)), axis=1)
    inside = np.zeros(len(cell), dtype=bool)
    inside[within] = np.isin(np.ravel_multi_index(cell[within].T, grid_a.shape), filled)
    return inside
