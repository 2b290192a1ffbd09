"""The voxel lattice: grid placement, corner numbering and hexahedron faces.

A voxel is a hexahedron given by 8 corners. Corner ``c`` of the voxel at lattice
index ``(i, j, k)`` is lattice vertex ``(i + dx, j + dy, k + dz)`` with
``c = dx + 2*dy + 4*dz``. Faces are numbered ``0..5`` = ``-x, +x, -y, +y, -z, +z``
(lattice axes, which are the object-space axes) and :data:`FACE_CORNERS` lists
each face's corners counter-clockwise seen from outside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Corners of each face, counter-clockwise seen from outside (outward normal).
FACE_CORNERS = np.array(
    [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]],
    dtype=np.int64,
)
#: Lattice offset of the neighbour across each face.
FACE_OFFSETS = np.array(
    [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], dtype=np.int64
)
#: Corner offsets ``(dx, dy, dz)`` for corner numbers 0..7.
CORNER_OFFSETS = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)], dtype=np.int64)


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
        return int(np.prod(self.shape))

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
    counts = np.maximum(1, np.ceil(extent / spacing - 1e-6)).astype(np.int64)
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


def face_triangles(quads: np.ndarray) -> np.ndarray:
    """Split quads (..., 4) of global vertex ids into triangles (..., 2, 3).

    The split diagonal is the one through the quad's smallest vertex id, so the
    two voxels that share a face (and so its four vertex ids) split it the same
    way and their jittered faces coincide exactly.
    """
    quads = np.asarray(quads)
    first = np.argmin(quads, axis=-1)
    use_ac = (first % 2) == 0
    a, b, c, d = (quads[..., n] for n in range(4))
    tri_ac = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], -2)
    tri_bd = np.stack([np.stack([b, c, d], -1), np.stack([b, d, a], -1)], -2)
    return np.where(use_ac[..., None, None], tri_ac, tri_bd)


def hex_triangles(voxel_vertices: np.ndarray) -> np.ndarray:
    """Outward triangles (N, 12, 3) of global vertex ids for voxels (N, 8).

    Triangle ``2*f`` and ``2*f + 1`` lie on face ``f``.
    """
    quads = voxel_vertices[:, FACE_CORNERS]  # (N, 6, 4)
    return face_triangles(quads).reshape(len(voxel_vertices), 12, 3)
