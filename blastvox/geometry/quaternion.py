"""Unit quaternions (w, x, y, z): one implementation with a numba and a NumPy face.

A body's quaternion rotates its rest frame (the VoxelModel's coordinates) into
the world: ``x_world = p + R(q) (x_rest - c_rest)`` (see
:mod:`blastvox.geometry.transforms`). Quaternions are dimensionless; a
quaternion and its negative are the same rotation.

* numba face, for compiled kernels, in :mod:`blastvox.geometry.quaternion_nb`
  (so that export and preview never load numba): ``matrix_into`` (one
  quaternion -> a (3, 3) matrix, no allocation) and ``integrate`` (turn by an
  angular velocity in place).
* NumPy face, here, for Python callers (export, preview, tests), on stacks of
  quaternions ``(..., 4)`` as float64: :func:`normalize`, :func:`to_matrix`
  (the same arithmetic as ``matrix_into``, element for element),
  :func:`from_matrix`, :func:`multiply`, :func:`conjugate`, :func:`rotate` and
  :func:`sign_continuous` (one sign per key over time, for interpolation).
"""

from __future__ import annotations

import numpy as np

from blastvox.geometry import exact

_CONJUGATE = np.array([1.0, -1.0, -1.0, -1.0])


def normalize(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) scaled to unit length, as float64 (..., 4)."""
    q = np.asarray(q, dtype=np.float64)
    return q / exact.length(q, keepdims=True)


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) float64 of unit quaternions (..., 4) (w, x, y, z).

    ``to_matrix(q) @ v`` rotates column vectors v (3,) by q. Element for element
    the arithmetic of :func:`matrix_into` (bit-identical results); q is not
    normalised here: use ``to_matrix(normalize(q))`` for quaternions that may
    be off unit length (float32 caches, Blender's quaternions).
    """
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.stack([
        np.stack([1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)], -1),
        np.stack([2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)], -1),
        np.stack([2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)], -1),
    ], axis=-2)


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) float64 (w, x, y, z) of proper rotation matrices (..., 3, 3).

    Shepperd's method: from the trace when it is positive, else from the largest
    diagonal element, so no branch divides by a small number. The result is
    normalised; its sign is whichever the branch gives (w >= 0 for trace > 0).
    """
    m = np.asarray(m, dtype=np.float64)
    shape = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    q = np.zeros((len(m), 4))
    trace = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    pos = trace > 0
    a = m[pos]
    s = 2.0 * np.sqrt(trace[pos] + 1.0)
    q[pos, 0] = 0.25 * s
    q[pos, 1] = (a[:, 2, 1] - a[:, 1, 2]) / s
    q[pos, 2] = (a[:, 0, 2] - a[:, 2, 0]) / s
    q[pos, 3] = (a[:, 1, 0] - a[:, 0, 1]) / s
    b = m[~pos]
    r = np.arange(len(b))
    i = np.argmax(np.diagonal(b, axis1=1, axis2=2), axis=1)
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * np.sqrt(1.0 + b[r, i, i] - b[r, j, j] - b[r, k, k])
    qb = np.zeros((len(b), 4))
    qb[:, 0] = (b[r, k, j] - b[r, j, k]) / s
    qb[r, 1 + i] = 0.25 * s
    qb[r, 1 + j] = (b[r, j, i] + b[r, i, j]) / s
    qb[r, 1 + k] = (b[r, k, i] + b[r, i, k]) / s
    q[~pos] = qb
    q /= exact.length(q, keepdims=True)
    return q.reshape(*shape, 4)


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products a b (..., 4) of quaternions a, b (..., 4) (broadcast): the
    rotation b followed by a."""
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def rotation_vector(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3), axis times angle in rad (angle in [0, pi]), of unit
    quaternions q (..., 4) (w, x, y, z); q and -q give the same vector."""
    q = np.where(q[..., :1] < 0, -q, q)
    sine = exact.length(q[..., 1:], keepdims=True)
    from blastvox.geometry import fixed  # numba: not loaded by the preview

    angle = 2.0 * fixed.arctan2(sine, q[..., :1])
    # angle / sine -> 2 as the rotation vanishes (and stays finite at sine == 0)
    scale = np.where(sine > 1e-12, angle / np.maximum(sine, 1e-300), 2.0)
    return q[..., 1:] * scale


def conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugates (w, -x, -y, -z) (..., 4): the inverse rotations of unit quaternions."""
    return q * _CONJUGATE


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors v (..., 3) rotated by unit quaternions q (..., 4) (broadcast): (..., 3).

    ``v + 2w (u x v) + u x (2 u x v)`` with u = (x, y, z): no matrix is built.
    """
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def sign_continuous(q: np.ndarray) -> np.ndarray:
    """Quaternion keys (F, ..., 4) over F frames, each flipped to the hemisphere of the
    previous frame's (non-negative dot product): the same rotations, and linear
    interpolation (nlerp, slerp) between keys then takes the short way. Returns q
    itself if F < 2, else a new array."""
    if len(q) < 2:
        return q
    keys = q.reshape(len(q), -1, 4)
    dots = exact.lane_dot(keys[1:], keys[:-1])
    sign = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
    out = keys.copy()
    out[1:] *= sign[..., None]
    return out.reshape(q.shape)
