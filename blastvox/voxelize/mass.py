"""Mass properties of polyhedral voxels: volume, centroid, inertia.

Exact integrals over closed triangle surfaces by the divergence theorem
(D. Eberly, "Polynomial Integrals over Polyhedra", Geometric Tools, 2002),
evaluated relative to a reference point inside each voxel so that tiny voxels
far from the origin keep full precision. Results are per unit density: volume
in m^3, centroid in m, inertia in m^5 (multiply by density in kg/m^3 to get
kg*m^2), about the centroid, as full symmetric (3, 3) tensors.
"""

from __future__ import annotations

import numpy as np

from blastvox.geometry.voxel_faces import FACE_CORNERS
from blastvox.jit import kernel


@kernel
def _subexpressions(w0: float, w1: float, w2: float):
    temp0 = w0 + w1
    f1 = temp0 + w2
    temp1 = w0 * w0
    temp2 = temp1 + w1 * temp0
    f2 = temp2 + w2 * f1
    f3 = w0 * temp1 + w1 * temp2 + w2 * f2
    g0 = f2 + w0 * (f1 + w0)
    g1 = f2 + w1 * (f1 + w1)
    g2 = f2 + w2 * (f1 + w2)
    return f1, f2, f3, g0, g1, g2


@kernel
def _accumulate(acc: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
                ref: np.ndarray) -> None:
    """Add one outward triangle's contribution to the 10 integrals in ``acc``."""
    x0, y0, z0 = a[0] - ref[0], a[1] - ref[1], a[2] - ref[2]
    x1, y1, z1 = b[0] - ref[0], b[1] - ref[1], b[2] - ref[2]
    x2, y2, z2 = c[0] - ref[0], c[1] - ref[1], c[2] - ref[2]
    e1x, e1y, e1z = x1 - x0, y1 - y0, z1 - z0
    e2x, e2y, e2z = x2 - x0, y2 - y0, z2 - z0
    d0 = e1y * e2z - e2y * e1z
    d1 = e2x * e1z - e1x * e2z
    d2 = e1x * e2y - e2x * e1y
    f1x, f2x, f3x, g0x, g1x, g2x = _subexpressions(x0, x1, x2)
    f1y, f2y, f3y, g0y, g1y, g2y = _subexpressions(y0, y1, y2)
    f1z, f2z, f3z, g0z, g1z, g2z = _subexpressions(z0, z1, z2)
    acc[0] += d0 * f1x
    acc[1] += d0 * f2x
    acc[2] += d1 * f2y
    acc[3] += d2 * f2z
    acc[4] += d0 * f3x
    acc[5] += d1 * f3y
    acc[6] += d2 * f3z
    acc[7] += d0 * (y0 * g0x + y1 * g1x + y2 * g2x)
    acc[8] += d1 * (z0 * g0y + z1 * g1y + z2 * g2y)
    acc[9] += d2 * (x0 * g0z + x1 * g1z + x2 * g2z)


@kernel
def _finish(acc: np.ndarray, ref: np.ndarray, volume: np.ndarray, centroid: np.ndarray,
            inertia: np.ndarray, i: int) -> None:
    vol = acc[0] / 6.0
    volume[i] = vol
    if vol <= 0.0:
        for r in range(3):
            centroid[i, r] = ref[r]
            for s in range(3):
                inertia[i, r, s] = 0.0
        return
    cx = acc[1] / 24.0 / vol
    cy = acc[2] / 24.0 / vol
    cz = acc[3] / 24.0 / vol
    xx = acc[4] / 60.0
    yy = acc[5] / 60.0
    zz = acc[6] / 60.0
    xy = acc[7] / 120.0
    yz = acc[8] / 120.0
    zx = acc[9] / 120.0
    ixx = yy + zz - vol * (cy * cy + cz * cz)
    iyy = zz + xx - vol * (cz * cz + cx * cx)
    izz = xx + yy - vol * (cx * cx + cy * cy)
    ixy = -(xy - vol * cx * cy)
    iyz = -(yz - vol * cy * cz)
    izx = -(zx - vol * cz * cx)
    centroid[i, 0] = cx + ref[0]
    centroid[i, 1] = cy + ref[1]
    centroid[i, 2] = cz + ref[2]
    inertia[i, 0, 0] = ixx
    inertia[i, 1, 1] = iyy
    inertia[i, 2, 2] = izz
    inertia[i, 0, 1] = inertia[i, 1, 0] = ixy
    inertia[i, 1, 2] = inertia[i, 2, 1] = iyz
    inertia[i, 0, 2] = inertia[i, 2, 0] = izx


@kernel
def _hex_kernel(vertices, voxel_vertices, face_corners, volume, centroid, inertia):
    acc = np.zeros(10)
    for i in range(voxel_vertices.shape[0]):
        acc[:] = 0.0
        ref = vertices[voxel_vertices[i, 0]]
        for f in range(6):
            q0 = voxel_vertices[i, face_corners[f, 0]]
            q1 = voxel_vertices[i, face_corners[f, 1]]
            q2 = voxel_vertices[i, face_corners[f, 2]]
            q3 = voxel_vertices[i, face_corners[f, 3]]
            smallest = min(q0, q1, q2, q3)
            if smallest == q0 or smallest == q2:  # the diagonal rule of voxel_faces.face_triangles
                _accumulate(acc, vertices[q0], vertices[q1], vertices[q2], ref)
                _accumulate(acc, vertices[q0], vertices[q2], vertices[q3], ref)
            else:
                _accumulate(acc, vertices[q1], vertices[q2], vertices[q3], ref)
                _accumulate(acc, vertices[q1], vertices[q3], vertices[q0], ref)
        _finish(acc, ref, volume, centroid, inertia, i)


@kernel
def _soup_kernel(triangles, offsets, volume, centroid, inertia):
    acc = np.zeros(10)
    for i in range(offsets.shape[0] - 1):
        acc[:] = 0.0
        start, stop = offsets[i], offsets[i + 1]
        if stop <= start:
            _finish(acc, np.zeros(3), volume, centroid, inertia, i)
            continue
        ref = triangles[start, 0].copy()
        for t in range(start, stop):
            _accumulate(acc, triangles[t, 0], triangles[t, 1], triangles[t, 2], ref)
        _finish(acc, ref, volume, centroid, inertia, i)


def hex_mass_properties(vertices: np.ndarray, voxel_vertices: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit-density mass properties of hexahedral voxels.

    vertices: (V, 3) float64 metres; voxel_vertices: (N, 8) corner indices.
    Returns volume (N,) m^3, centroid (N, 3) m, inertia (N, 3, 3) m^5 about the centroid.
    """
    n = len(voxel_vertices)
    volume = np.empty(n)
    centroid = np.empty((n, 3))
    inertia = np.empty((n, 3, 3))
    _hex_kernel(np.ascontiguousarray(vertices, dtype=np.float64),
                np.ascontiguousarray(voxel_vertices, dtype=np.int64), FACE_CORNERS,
                volume, centroid, inertia)
    return volume, centroid, inertia


def soup_mass_properties(triangles: np.ndarray, offsets: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit-density mass properties of closed triangle sets.

    triangles: (T, 3, 3) float64 metres, outward-oriented; set ``i`` is
    ``triangles[offsets[i]:offsets[i + 1]]``. Returns as :func:`hex_mass_properties`.
    """
    n = len(offsets) - 1
    volume = np.empty(n)
    centroid = np.empty((n, 3))
    inertia = np.empty((n, 3, 3))
    _soup_kernel(np.ascontiguousarray(triangles, dtype=np.float64),
                 np.ascontiguousarray(offsets, dtype=np.int64), volume, centroid, inertia)
    return volume, centroid, inertia
