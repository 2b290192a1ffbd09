"""The hexahedral voxel: corner numbering, face tables, face triangles, the surface tag.

A voxel is a hexahedron given by 8 corners. Corner ``c`` of the voxel at lattice
index ``(i, j, k)`` is lattice vertex ``(i + dx, j + dy, k + dz)`` with
``c = dx + 2*dy + 4*dz`` (:data:`CORNER_OFFSETS`). Faces are numbered ``0..5`` =
``-x, +x, -y, +y, -z, +z`` (lattice axes, which are the object-space axes): face
``f`` is across axis ``f // 2``, on its positive side if ``f`` is odd, and face
``f ^ 1`` is the opposite one. :data:`FACE_CORNERS` lists each face's corners
counter-clockwise seen from outside; :func:`face_triangles` splits a face into
two triangles the same way for both voxels that share it.

Where a triangle or a voxel lies is one number, 0..6: ``0..5`` on that cell face
(inside the intact object; exposed when it breaks there), :data:`SURFACE_TAG` =
6 on the original surface (VoxelModel ``conform_tag``); in the VoxelModel's
``voxel_boundary`` bits, bit ``f`` (0..5) is set if face ``f`` is exposed in the
intact object and bit :data:`SURFACE_BIT` = 6 if the voxel has original surface.

All tables are int64 NumPy arrays (numba kernels may read them as globals).
"""

from __future__ import annotations

import numpy as np

#: faces of a hexahedral voxel (-x, +x, -y, +y, -z, +z)
FACE_COUNT = 6
#: corners of a hexahedral voxel
CORNER_COUNT = 8
#: (8, 3) lattice offset ``(dx, dy, dz)`` of corners 0..7 (``c = dx + 2*dy + 4*dz``)
CORNER_OFFSETS = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)],
                          dtype=np.int64)
#: (6, 4) corners of each face, counter-clockwise seen from outside (outward normal)
FACE_CORNERS = np.array(
    [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]],
    dtype=np.int64,
)
#: (6, 3) lattice offset of the neighbour across each face (also the outward normal)
FACE_OFFSETS = np.array(
    [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], dtype=np.int64
)
#: (6,) the face across the voxel from each face (``f ^ 1``)
OPPOSITE_FACE = np.array([1, 0, 3, 2, 5, 4], dtype=np.int64)
#: tag of a conform triangle on the original surface (0..5: on that cell face)
SURFACE_TAG = FACE_COUNT
#: bit of ``voxel_boundary`` set for voxels with original surface (bits 0..5: exposed faces)
SURFACE_BIT = FACE_COUNT

#: Boundary triangles of the volume cells read from meshio (VTK node order), outward:
#: a tetrahedron's 4 faces, a hexahedron's 6 faces as 2 triangles each (-z, +z, -y, +x,
#: +y, -x). VTK numbers hexahedron nodes round the bottom, then the top:
#: node n is voxel corner :data:`VTK_HEXAHEDRON_CORNERS` [n].
VTK_CELL_FACES = {
    "tetra": np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]),
    "hexahedron": np.array([[0, 3, 2], [0, 2, 1], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                            [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]),
}
#: (8,) voxel corner number of VTK hexahedron node 0..7
VTK_HEXAHEDRON_CORNERS = np.array([0, 1, 3, 2, 4, 5, 7, 6], dtype=np.int64)


def face_triangles(quads: np.ndarray) -> np.ndarray:
    """Split quads (..., 4) of global vertex ids into triangles (..., 2, 3) of vertex ids.

    The split diagonal is the one through the quad's smallest vertex id, so the
    two voxels that share a face (and so its four vertex ids) split it the same
    way and their jittered faces coincide exactly. Winding is kept (outward
    quads give outward triangles).
    """
    quads = np.asarray(quads)
    first = np.argmin(quads, axis=-1)
    use_ac = (first % 2) == 0
    a, b, c, d = (quads[..., n] for n in range(4))
    tri_ac = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], -2)
    tri_bd = np.stack([np.stack([b, c, d], -1), np.stack([b, d, a], -1)], -2)
    return np.where(use_ac[..., None, None], tri_ac, tri_bd)


def hex_triangles(voxel_vertices: np.ndarray) -> np.ndarray:
    """Outward triangles (N, 12, 3) of global vertex ids for voxels (N, 8) of vertex ids.

    Triangle ``2*f`` and ``2*f + 1`` lie on face ``f``.
    """
    quads = voxel_vertices[:, FACE_CORNERS]  # (N, 6, 4)
    return face_triangles(quads).reshape(len(voxel_vertices), 12, 3)
