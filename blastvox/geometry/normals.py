"""Corner normals of a triangle surface: smooth where the surface is smooth, sharp at creases.

Each corner of a triangle takes the area-weighted mean of the unit normals of the
triangles around its vertex whose normal is within ``crease`` of its own
triangle's (a "smoothing angle", as in Blender's auto smooth, whose default of 30
degrees this takes). A curved surface shades smoothly; a box keeps its flat
faces. Vertices are matched by position, so a seam of split vertices (UV seams
in glTF, OBJ's per-corner indices) does not show as a crease.
"""

from __future__ import annotations

import math

import numpy as np

#: Default crease angle, degrees (Blender's auto smooth default).
CREASE_DEGREES = 30.0


def corner_normals(vertices: np.ndarray, faces: np.ndarray,
                   crease_degrees: float = CREASE_DEGREES) -> np.ndarray:
    """Unit normals (F, 3, 3) at the three corners of each of ``faces`` (F, 3) into
    ``vertices`` (V, 3) (any length unit). A degenerate triangle's corners get the
    mean of their smooth neighbours, or 0 if they have none."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n_faces = len(faces)
    if n_faces == 0:
        return np.zeros((0, 3, 3))
    _, point = np.unique(vertices, axis=0, return_inverse=True)  # merged by position
    corner_point = point.ravel()[faces].ravel()                    # (3F,)
    tri = vertices[faces]
    scaled = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # 2 x area x normal
    length = np.linalg.norm(scaled, axis=1)
    unit = np.divide(scaled, length[:, None], out=np.zeros_like(scaled),
                     where=length[:, None] > 0)
    corner, neighbour = _corner_face_pairs(corner_point)
    own = unit[corner // 3]
    smooth = np.einsum("ij,ij->i", own, unit[neighbour]) >= math.cos(
        math.radians(crease_degrees))
    total = np.zeros((3 * n_faces, 3))
    np.add.at(total, corner[smooth], scaled[neighbour[smooth]])
    norm = np.linalg.norm(total, axis=1)
    out = np.divide(total, norm[:, None], out=np.zeros_like(total), where=norm[:, None] > 0)
    return out.reshape(n_faces, 3, 3)


def _corner_face_pairs(corner_point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every (corner, face) pair that shares a point: corners (3F,) numbered 3 f + k,
    ``corner_point`` (3F,) their points. Returns two (P,) int64 arrays."""
    order = np.argsort(corner_point, kind="stable")
    points = corner_point[order]
    start = np.flatnonzero(np.r_[True, points[1:] != points[:-1]])
    size = np.diff(np.r_[start, len(points)])
    # for each corner in a point's group, every member of the group
    group_size = np.repeat(size, size)                 # (3F,) per sorted corner
    group_start = np.repeat(start, size)
    first = np.repeat(order, group_size)               # the corner
    offset = np.arange(int(group_size.sum())) - np.repeat(
        np.cumsum(group_size) - group_size, group_size)
    second = order[np.repeat(group_start, group_size) + offset]  # a corner sharing it
    return first, second // 3
