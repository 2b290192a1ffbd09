"""Unit quaternions (w, x, y, z): the numba face, for compiled kernels.

Helpers (:func:`blastvox.jit.helper`): callable from compiled code only, their
``py_func`` from Python. The NumPy face, with the same arithmetic, is
:mod:`blastvox.geometry.quaternion`.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.jit import helper


@helper
def matrix_into(q: np.ndarray, m: np.ndarray) -> None:
    """Write the rotation matrix of unit quaternion q into m (3, 3), no allocation."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    m[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    m[0, 1] = 2.0 * (x * y - w * z)
    m[0, 2] = 2.0 * (x * z + w * y)
    m[1, 0] = 2.0 * (x * y + w * z)
    m[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    m[1, 2] = 2.0 * (y * z - w * x)
    m[2, 0] = 2.0 * (x * z - w * y)
    m[2, 1] = 2.0 * (y * z + w * x)
    m[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@helper
def integrate(q: np.ndarray, wx: float, wy: float, wz: float, dt: float) -> None:
    """Rotate q in place by the world angular velocity (wx, wy, wz) rad/s for dt s.

    Uses the exact exponential map exp(omega dt / 2), so a spin of any rate
    advances by exactly |omega| dt radians per step, then renormalises so |q|
    stays 1 to round-off.
    """
    rate = math.sqrt(wx * wx + wy * wy + wz * wz)
    if rate * dt < 1e-12:
        d0, d1, d2, d3 = 1.0, 0.5 * wx * dt, 0.5 * wy * dt, 0.5 * wz * dt
    else:
        s = math.sin(0.5 * rate * dt) / rate
        d0, d1, d2, d3 = math.cos(0.5 * rate * dt), wx * s, wy * s, wz * s
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    o0 = d0 * q0 - d1 * q1 - d2 * q2 - d3 * q3
    o1 = d0 * q1 + d1 * q0 + d2 * q3 - d3 * q2
    o2 = d0 * q2 - d1 * q3 + d2 * q0 + d3 * q1
    o3 = d0 * q3 + d1 * q2 - d2 * q1 + d3 * q0
    norm = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2 + o3 * o3)
    q[0], q[1], q[2], q[3] = o0 / norm, o1 / norm, o2 / norm, o3 / norm
