"""Links between face-adjacent voxels and the exposed faces of the intact object."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blastvox.voxelize.lattice import FACE_CORNERS, face_triangles


@dataclass
class Links:
    """Links of one lattice (indices local to that lattice's voxel list).

    voxels: (L, 2) voxel a < b; face: (L,) face of a crossed (1, 3 or 5);
    midpoint: (L, 3) m; area: (L,) m^2.
    """

    voxels: np.ndarray
    face: np.ndarray
    midpoint: np.ndarray
    area: np.ndarray


def index_grid(ijk: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
    """Dense (nx, ny, nz) int64 array: voxel number at each cell, -1 where empty."""
    grid = np.full(shape, -1, dtype=np.int64)
    grid[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = np.arange(len(ijk))
    return grid


def face_neighbours(ijk: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """(N, 6) voxel number across each face (-x,+x,-y,+y,-z,+z), -1 if none."""
    n = len(ijk)
    out = np.full((n, 6), -1, dtype=np.int64)
    shape = np.asarray(grid.shape)
    for f in range(6):
        axis, step = divmod(f, 2)
        other = ijk.copy()
        other[:, axis] += 1 if step else -1
        ok = (other[:, axis] >= 0) & (other[:, axis] < shape[axis])
        out[ok, f] = grid[other[ok, 0], other[ok, 1], other[ok, 2]]
    return out


def hex_face_area_centroid(vertices: np.ndarray, voxel_vertices: np.ndarray,
                           face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area (K,) and area centroid (K, 3) of face ``face[k]`` of hexahedral voxel k.

    The face is split into two triangles along the same diagonal as everywhere
    else (lattice.face_triangles), so jittered faces are measured exactly.
    """
    quads = voxel_vertices[np.arange(len(face))[:, None], FACE_CORNERS[face]]
    tris = vertices[face_triangles(quads)]  # (K, 2, 3, 3)
    cross = np.cross(tris[:, :, 1] - tris[:, :, 0], tris[:, :, 2] - tris[:, :, 0])
    areas = 0.5 * np.linalg.norm(cross, axis=-1)  # (K, 2)
    centres = tris.mean(axis=2)  # (K, 2, 3)
    total = areas.sum(axis=1)
    safe = np.where(total > 0, total, 1.0)
    centroid = (areas[:, :, None] * centres).sum(axis=1) / safe[:, None]
    return total, centroid


def tagged_area_centroid(triangles: np.ndarray, tags: np.ndarray, offsets: np.ndarray,
                         which: np.ndarray, face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area and area centroid of the conform triangles of set ``which[k]`` tagged ``face[k]``."""
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    tri_area = 0.5 * np.linalg.norm(cross, axis=-1)
    tri_centre = triangles.mean(axis=1)
    area = np.zeros(len(which))
    centroid = np.zeros((len(which), 3))
    for k, (s, f) in enumerate(zip(which.tolist(), face.tolist(), strict=True)):
        sl = slice(offsets[s], offsets[s + 1])
        mask = tags[sl] == f
        a = tri_area[sl][mask]
        area[k] = a.sum()
        if area[k] > 0:
            centroid[k] = (a[:, None] * tri_centre[sl][mask]).sum(axis=0) / area[k]
    return area, centroid
