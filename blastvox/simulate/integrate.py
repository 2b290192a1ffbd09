"""Time integration of free bodies at a fixed step.

Momentum form, semi-implicit Euler: the blast impulse of the step (exact, see
:mod:`blastvox.simulate.forces`) and gravity change linear momentum; the blast
angular impulse changes angular momentum (world frame, about the centre of
mass); velocities from the new momenta move the body. Rotation uses the exact
exponential map of omega = R I_rest^-1 R^T L, so quaternions stay unit and a
free spin keeps L exactly. Drag is exponential decay of the momenta (1/s
rates), stable at any step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from blastvox.simulate import quaternion


@nb.njit(cache=True)
def integrate_bodies(dt: float, gravity: np.ndarray, linear_drag: float, angular_drag: float,
                     impulse: np.ndarray, angular_impulse: np.ndarray, body_mass: np.ndarray,
                     body_inv_inertia: np.ndarray, body_rot: np.ndarray, body_pos: np.ndarray,
                     body_quat: np.ndarray, body_lin: np.ndarray, body_ang: np.ndarray,
                     body_fixed: np.ndarray, body_live: np.ndarray, body_dust: np.ndarray,
                     n_bodies: int) -> None:
    """Advance every live, free, non-dust body by one step of ``dt`` seconds.

    impulse, angular_impulse: (B, 3) N s and N m s received this step (world).
    gravity: (3,) m/s^2. body_inv_inertia: (B, 3, 3) rest-frame I^-1;
    body_rot: (B, 3, 3) rotation matrices of the current quaternions.
    """
    lin_decay = math.exp(-linear_drag * dt)
    ang_decay = math.exp(-angular_drag * dt)
    for b in range(n_bodies):
        if not body_live[b] or body_fixed[b] or body_dust[b]:
            continue
        m = body_mass[b]
        for a in range(3):
            body_lin[b, a] = (body_lin[b, a] + impulse[b, a] + m * gravity[a] * dt) * lin_decay
            body_ang[b, a] = (body_ang[b, a] + angular_impulse[b, a]) * ang_decay
            body_pos[b, a] += body_lin[b, a] / m * dt
        rot = body_rot[b]
        inv = body_inv_inertia[b]
        lx, ly, lz = body_ang[b, 0], body_ang[b, 1], body_ang[b, 2]
        # omega = R I^-1 R^T L
        r0 = rot[0, 0] * lx + rot[1, 0] * ly + rot[2, 0] * lz
        r1 = rot[0, 1] * lx + rot[1, 1] * ly + rot[2, 1] * lz
        r2 = rot[0, 2] * lx + rot[1, 2] * ly + rot[2, 2] * lz
        s0 = inv[0, 0] * r0 + inv[0, 1] * r1 + inv[0, 2] * r2
        s1 = inv[1, 0] * r0 + inv[1, 1] * r1 + inv[1, 2] * r2
        s2 = inv[2, 0] * r0 + inv[2, 1] * r1 + inv[2, 2] * r2
        wx = rot[0, 0] * s0 + rot[0, 1] * s1 + rot[0, 2] * s2
        wy = rot[1, 0] * s0 + rot[1, 1] * s1 + rot[1, 2] * s2
        wz = rot[2, 0] * s0 + rot[2, 1] * s1 + rot[2, 2] * s2
        quaternion.integrate(body_quat[b], wx, wy, wz, dt)
