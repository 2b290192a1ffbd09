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

from blastvox.geometry import exact
from blastvox.jit import kernel

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
    length = exact.length(scaled)
    unit = np.divide(scaled, length[:, None], out=np.zeros_like(scaled),
                     where=length[:, None] > 0)
    order = np.argsort(corner_point, kind="stable")
    points = corner_point[order]
    start = np.flatnonzero(np.r_[True, points[1:] != points[:-1]])
    out = np.zeros((3 * n_faces, 3))
    _smooth_corners(order, np.r_[start, len(points)].astype(np.int64), scaled, unit,
                    math.cos(math.radians(crease_degrees)), out)
    return out.reshape(n_faces, 3, 3)


@kernel
def _smooth_corners(order, bounds, scaled, unit, cosine, out) -> None:
    """For each corner (numbered 3 f + k), the unit sum of ``scaled`` (F, 3) over the
    faces at its point whose ``unit`` normal is within ``cosine`` of its own face's;
    ``order`` (3F,) the corners sorted by point, ``bounds`` (G+1,) each point's run
    in it. Writes out (3F, 3); O(sum of valence^2) time, no pair arrays."""
    for g in range(bounds.shape[0] - 1):
        for i in range(bounds[g], bounds[g + 1]):
            corner = order[i]
            face = corner // 3
            sx = 0.0
            sy = 0.0
            sz = 0.0
            for j in range(bounds[g], bounds[g + 1]):
                other = order[j] // 3
                dot = (unit[face, 0] * unit[other, 0] + unit[face, 1] * unit[other, 1]
                       + unit[face, 2] * unit[other, 2])
                if dot >= cosine:
                    sx += scaled[other, 0]
                    sy += scaled[other, 1]
                    sz += scaled[other, 2]
            norm = math.sqrt(sx * sx + sy * sy + sz * sz)
            if norm > 0.0:
                out[corner, 0] = sx / norm
                out[corner, 1] = sy / norm
                out[corner, 2] = sz / norm
