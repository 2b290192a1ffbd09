"""Small vector products that round the same on every CPU.

numpy hands ``@``, ``np.dot`` and a vector's ``np.linalg.norm`` to BLAS (OpenBLAS),
which picks its kernels by CPU at load time: SkylakeX kernels on an AVX-512 EPYC,
Haswell or Zen kernels on another. They fuse multiply-adds and sum in their own
order, so the same product can differ in its last bit from one host to the next,
and a shot's chaotic fracture turns one bit into different pieces (the golden
caches differed between two EPYC hosts until the simulator stopped using them).
These functions spell the sums out with numpy's elementwise multiply and add, which
round one IEEE operation at a time on every CPU, in a fixed order.

Shapes: a vector is (..., 3), a matrix (..., 3, 3); leading axes broadcast.
"""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a . b over the last axis, (...): a[0] b[0] + a[1] b[1] + a[2] b[2]."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def norm(a: np.ndarray) -> np.ndarray:
    """|a| over the last axis, (...)."""
    return np.sqrt(dot(a, a))


def matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """m v, (..., 3): the matrices m (..., 3, 3) times the column vectors v (..., 3)
    (``m @ v`` for one v, ``v @ m.T`` for rows of vectors)."""
    m, v = np.asarray(m, dtype=np.float64), np.asarray(v, dtype=np.float64)
    return (m[..., :, 0] * v[..., None, 0] + m[..., :, 1] * v[..., None, 1]
            + m[..., :, 2] * v[..., None, 2])


def vecmat(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    """v m, (..., 3): the row vectors v (..., 3) times the matrices m (..., 3, 3)
    (``v @ m``, or ``m.T @ v`` for one v)."""
    m, v = np.asarray(m, dtype=np.float64), np.asarray(v, dtype=np.float64)
    return (v[..., 0, None] * m[..., 0, :] + v[..., 1, None] * m[..., 1, :]
            + v[..., 2, None] * m[..., 2, :])
