"""Axis-aligned boxes of voxels at rest: of a cell's corners, of a set of triangles.

Minima and maxima are exact, so every caller gets the same bits: voxelize's solid
boxes (``voxel_solid_box``) and the simulator's shielding and contact boxes agree
where they describe the same cell.
"""

from __future__ import annotations

import numpy as np

from blastvox.jit import kernel

__all__ = ["corner_boxes", "triangle_boxes"]


@kernel
def corner_boxes(vertices, corners):
    """(lo, hi) (N, 3) m: the box of each voxel's corners (vertices (V, 3) m, corners
    (N, 8) rows of it); one pass, no (N, 8, 3) gather."""
    n = corners.shape[0]
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    for v in range(n):
        for a in range(3):
            x = vertices[corners[v, 0], a]
            lo[v, a] = x
            hi[v, a] = x
        for k in range(1, 8):
            for a in range(3):
                x = vertices[corners[v, k], a]
                lo[v, a] = min(lo[v, a], x)
                hi[v, a] = max(hi[v, a], x)
    return lo, hi


def triangle_boxes(triangles: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (K, 3) m: the box of each of K consecutive, non-empty triangle sets
    (triangles (T, 3, 3) m; set k starts at starts[k] and ends where the next begins):
    a conform voxel's solid."""
    if not len(starts):
        return np.zeros((0, 3)), np.zeros((0, 3))
    return (np.minimum.reduceat(triangles.min(axis=1), starts, axis=0),
            np.maximum.reduceat(triangles.max(axis=1), starts, axis=0))
