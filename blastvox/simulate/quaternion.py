"""Unit quaternions (w, x, y, z) as float64 arrays, numba-compiled.

A body's quaternion rotates its rest frame (the VoxelModel's coordinates) into
the world: ``x_world = p + R(q) (x_rest - c_rest)``.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np


@nb.njit(cache=True, inline="always")
def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion q = (w, x, y, z)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    m = np.empty((3, 3))
    m[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    m[0, 1] = 2.0 * (x * y - w * z)
    m[0, 2] = 2.0 * (x * z + w * y)
    m[1, 0] = 2.0 * (x * y + w * z)
    m[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    m[1, 2] = 2.0 * (y * z - w * x)
    m[2, 0] = 2.0 * (x * z - w * y)
    m[2, 1] = 2.0 * (y * z + w * x)
    m[2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return m


@nb.njit(cache=True, inline="always")
def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b."""
    out = np.empty(4)
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]
    return out


@nb.njit(cache=True)
def integrate(q: np.ndarray, omega: np.ndarray, dt: float) -> np.ndarray:
    """Rotate q by the world angular velocity omega (rad/s) for dt seconds, renormalised.

    Uses the exact exponential map exp(omega dt / 2), so a spin of any rate
    advances by exactly |omega| dt radians per step and |q| stays 1.
    """
    rate = math.sqrt(omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2)
    half = 0.5 * rate * dt
    d = np.empty(4)
    if rate * dt < 1e-12:
        d[0] = 1.0
        d[1] = 0.5 * omega[0] * dt
        d[2] = 0.5 * omega[1] * dt
        d[3] = 0.5 * omega[2] * dt
    else:
        s = math.sin(half) / rate
        d[0] = math.cos(half)
        d[1] = omega[0] * s
        d[2] = omega[1] * s
        d[3] = omega[2] * s
    out = multiply(d, q)
    norm = math.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)
    return out / norm
