"""Small vector products that round the same on every CPU.

numpy hands ``@``, ``np.dot`` and a vector's ``np.linalg.norm`` to BLAS (OpenBLAS),
which picks its kernels by CPU at load time: SkylakeX kernels on an AVX-512 EPYC,
Haswell or Zen kernels on another. They fuse multiply-adds and sum in their own
order, so the same product can differ in its last bit from one host to the next,
and a shot's chaotic fracture turns one bit into different pieces (the golden
caches differed between two EPYC hosts until the simulator stopped using them).
These functions spell the sums out with numpy's elementwise multiply and add, which
round one IEEE operation at a time on every CPU, in a fixed order. The exports use
them too (issue 37: their decisions, a key kept, a rubble face, a quantised value, turn
one ulp into other bytes): :func:`total` and :func:`length` sum left to right, as
``np.linalg.norm(a, axis=-1)`` does, and :func:`lane_dot` in the two lanes numpy's
``einsum`` used when the exports' goldens were made, so the files kept their bytes.
Transcendental functions that round the same are in :mod:`blastvox.geometry.fixed`.

Shapes: a vector is (..., 3), a matrix (..., 3, 3); leading axes broadcast
(:func:`total`, :func:`length` and :func:`lane_dot` take any last axis, or 3 or 4).
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


def turn(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """m v (..., 3) as :func:`matvec`, with no negative zeros: what ``v @ m.T`` gave for
    rows of vectors v (..., 3) and a rotation m (3, 3) that permutes and flips axes
    (a frame change), whose BLAS and numpy loops sum from +0, on every CPU."""
    return matvec(m, v) + 0.0


def vecmat(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    """v m, (..., 3): the row vectors v (..., 3) times the matrices m (..., 3, 3)
    (``v @ m``, or ``m.T @ v`` for one v)."""
    m, v = np.asarray(m, dtype=np.float64), np.asarray(v, dtype=np.float64)
    return (v[..., 0, None] * m[..., 0, :] + v[..., 1, None] * m[..., 1, :]
            + v[..., 2, None] * m[..., 2, :])


def total(a: np.ndarray) -> np.ndarray:
    """a[..., 0] + a[..., 1] + ... over the last axis, left to right, (...)."""
    a = np.asarray(a, dtype=np.float64)
    out = a[..., 0] + 0.0 if a.shape[-1] == 1 else a[..., 0] + a[..., 1]
    for k in range(2, a.shape[-1]):
        out = out + a[..., k]
    return out


def length(a: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Euclidean lengths over the last axis (...) (or (..., 1) with ``keepdims``): the
    squares summed left to right, as ``np.linalg.norm(a, axis=-1)`` sums them."""
    a = np.asarray(a, dtype=np.float64)
    norm = np.sqrt(total(a * a))
    return norm[..., None] if keepdims else norm


def lane_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row dot products over the last axis (3 or 4 components), (...), summed in two
    lanes as numpy's ``einsum("...i,...i->...")`` did when the exports' goldens were
    made: (a0 b0 + a2 b2) + a1 b1, and (a0 b0 + a2 b2) + (a1 b1 + a3 b3)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    p = a * b
    if p.shape[-1] == 3:
        return (p[..., 0] + p[..., 2]) + p[..., 1]
    if p.shape[-1] == 4:
        return (p[..., 0] + p[..., 2]) + (p[..., 1] + p[..., 3])
    raise ValueError(f"lane_dot takes 3 or 4 components, not {p.shape[-1]}")


def mix(weights: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(..., C, D): sum_j weights[..., c, j] rows[..., j, :], summed over j left to right
    (3 weights: as numpy's ``einsum("tcj,tjd->tcd")`` sums them), for weights
    (..., C, J) and rows (..., J, D): barycentric mixes of a triangle's corner values."""
    weights, rows = np.asarray(weights, dtype=np.float64), np.asarray(rows, dtype=np.float64)
    out = weights[..., :, 0, None] * rows[..., None, 0, :]
    for j in range(1, weights.shape[-1]):
        out = out + weights[..., :, j, None] * rows[..., None, j, :]
    return out
