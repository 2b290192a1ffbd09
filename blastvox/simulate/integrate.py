"""Time integration of free bodies at a fixed step.

Momentum form, semi-implicit Euler: the blast impulse of the step (exact, see
:mod:`blastvox.simulate.forces`) and gravity change linear momentum; the blast
angular impulse changes angular momentum (world frame, about the centre of
mass); velocities from the new momenta move the body. Rotation uses the exact
exponential map of omega = I_world^-1 L, so quaternions stay unit and a free
spin keeps |L| exactly. Drag is exponential decay of the momenta (1/s rates),
which is unconditionally stable at any step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from blastvox.simulate import quaternion
from blastvox.simulate.bodies import angular_velocity


@nb.njit(cache=True)
def integrate_bodies(dt: float, gravity: np.ndarray, linear_drag: float, angular_drag: float,
                     impulse: np.ndarray, angular_impulse: np.ndarray, body_mass: np.ndarray,
                     body_inertia: np.ndarray, body_pos: np.ndarray, body_quat: np.ndarray,
                     body_lin: np.ndarray, body_ang: np.ndarray, body_fixed: np.ndarray,
                     body_live: np.ndarray, body_dust: np.ndarray, n_bodies: int) -> None:
    """Advance every live, free, non-dust body by one step of ``dt`` seconds.

    impulse, angular_impulse: (B, 3) N s and N m s received this step (world).
    gravity: (3,) m/s^2 vector.
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
        omega = angular_velocity(body_inertia[b], body_quat[b], body_ang[b])
        body_quat[b] = quaternion.integrate(body_quat[b], omega, dt)
