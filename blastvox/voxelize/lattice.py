"""The voxel lattice: grid placement and voxel spacing.

The hexahedral voxel's corner numbering, face tables and face triangles live in
:mod:`blastvox.geometry.voxel_faces` (shared with export and the simulator) and
are re-exported here for the voxelizer's modules.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from blastvox.geometry.voxel_faces import (
    CORNER_OFFSETS,
    FACE_CORNERS,
    FACE_OFFSETS,
    face_triangles,
    hex_triangles,
)

__all__ = ["CORNER_OFFSETS", "FACE_CORNERS", "FACE_OFFSETS", "Grid", "face_triangles",
           "fit_grid", "hex_triangles", "spacing_for"]


@dataclass(frozen=True)
class Grid:
    """An axis-aligned lattice of ``shape`` cells of size ``spacing`` from ``origin``.

    origin: (3,) metres, the minimum corner of cell (0, 0, 0).
    spacing: (3,) metres, the cell size along x, y, z.
    shape: (3,) cell counts.
    """

    origin: np.ndarray
    spacing: np.ndarray
    shape: tuple[int, int, int]

    @property
    def cell_count(self) -> int:
        return math.prod(self.shape)  # Python ints: never wraps

    def cell_centres(self, ijk: np.ndarray) -> np.ndarray:
        """Centres (N, 3) in metres of the cells at integer indices ``ijk`` (N, 3)."""
        return self.origin + (ijk + 0.5) * self.spacing


def fit_grid(bounds: np.ndarray, spacing: np.ndarray, up_axis: int) -> Grid:
    """The smallest grid of ``spacing`` covering ``bounds`` (2, 3).

    Along the up axis the grid starts exactly at the lowest point, so that the
    bottom voxel layer rests on the ground; along the other axes the slack is
    split evenly on both sides so the voxelisation is centred on the mesh.
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    spacing = np.asarray(spacing, dtype=np.float64)
    extent = bounds[1] - bounds[0]
    # 1e-6: float32 mesh files store "exact" sizes with ~1e-7 relative error
    with np.errstate(over="ignore", invalid="ignore"):
        counts_f = np.maximum(1.0, np.ceil(extent / spacing - 1e-6))
    if not np.all(np.isfinite(counts_f)) or float(np.prod(counts_f)) > 2.0**62:
        # the caller checks the budget first (blastvox.voxelize.budget); never wrap around
        raise ValueError(f"lattice of {counts_f.tolist()} cells is too large to index")
    counts = counts_f.astype(np.int64)
    slack = counts * spacing - extent
    origin = bounds[0] - 0.5 * slack
    origin[up_axis] = bounds[0, up_axis]
    shape = (int(counts[0]), int(counts[1]), int(counts[2]))
    return Grid(origin=origin, spacing=spacing, shape=shape)


def spacing_for(bounds: np.ndarray, voxel_size: float | tuple[float, float, float] | None,
                resolution: int | None) -> np.ndarray:
    """Voxel spacing (3,) in metres from an explicit size or a resolution along the longest axis."""
    if voxel_size is not None:
        size = np.broadcast_to(np.asarray(voxel_size, dtype=np.float64), (3,)).copy()
        return size
    if resolution is None:
        raise ValueError("one of voxel_size or resolution is required")
    longest = float(np.max(np.asarray(bounds)[1] - np.asarray(bounds)[0]))
    return np.full(3, longest / resolution)
