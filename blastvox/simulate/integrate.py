"""Time integration of free bodies at a fixed step, in two halves around contacts.

Momentum form, semi-implicit Euler: :func:`integrate_velocities` adds the
blast impulse of the step (exact, see :mod:`blastvox.simulate.forces`),
gravity and drag to the momenta; contacts then change momenta at velocity
level; :func:`integrate_positions` moves bodies with the resulting velocities.
Rotation uses the exact exponential map of omega = R I_rest^-1 R^T L, so
quaternions stay unit and a free spin keeps L exactly. Drag is exponential
decay of the momenta (1/s rates), stable at any step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from blastvox.simulate import quaternion


@nb.njit(cache=True)
def moving(b, body_live, body_fixed, body_dust, body_asleep) -> bool:
    """True for a body the integrator moves."""
    return body_live[b] and not body_fixed[b] and not body_dust[b] and not body_asleep[b]


@nb.njit(cache=True)
def integrate_velocities(dt: float, gravity: np.ndarray, linear_drag: float,
                         angular_drag: float, impulse: np.ndarray, angular_impulse: np.ndarray,
                         body_mass: np.ndarray, body_lin: np.ndarray, body_ang: np.ndarray,
                         body_fixed: np.ndarray, body_live: np.ndarray, body_dust: np.ndarray,
                         body_asleep: np.ndarray, n_bodies: int) -> None:
    """Momenta after this step's blast impulse (N s, N m s; (B, 3)), gravity (m/s^2) and drag."""
    lin_decay = math.exp(-linear_drag * dt)
    ang_decay = math.exp(-angular_drag * dt)
    for b in range(n_bodies):
        if not moving(b, body_live, body_fixed, body_dust, body_asleep):
            continue
        m = body_mass[b]
        for a in range(3):
            body_lin[b, a] = (body_lin[b, a] + impulse[b, a] + m * gravity[a] * dt) * lin_decay
            body_ang[b, a] = (body_ang[b, a] + angular_impulse[b, a]) * ang_decay


@nb.njit(cache=True)
def integrate_positions(dt: float, body_mass: np.ndarray, body_inv_inertia: np.ndarray,
                        body_rot: np.ndarray, body_pos: np.ndarray, body_quat: np.ndarray,
                        body_lin: np.ndarray, body_ang: np.ndarray, body_fixed: np.ndarray,
                        body_live: np.ndarray, body_dust: np.ndarray, body_asleep: np.ndarray,
                        n_bodies: int) -> None:
    """Move bodies by their current velocities for ``dt`` seconds.

    body_inv_inertia: (B, 3, 3) rest-frame I^-1; body_rot: (B, 3, 3) rotation
    matrices of the current quaternions.
    """
    for b in range(n_bodies):
        if not moving(b, body_live, body_fixed, body_dust, body_asleep):
            continue
        m = body_mass[b]
        for a in range(3):
            body_pos[b, a] += body_lin[b, a] / m * dt
        wx, wy, wz = angular_velocity(body_rot[b], body_inv_inertia[b], body_ang[b])
        quaternion.integrate(body_quat[b], wx, wy, wz, dt)


@nb.njit(cache=True)
def angular_velocity(rot, inv, ang):
    """omega = R I^-1 R^T L (rad/s, world) without allocation."""
    lx, ly, lz = ang[0], ang[1], ang[2]
    r0 = rot[0, 0] * lx + rot[1, 0] * ly + rot[2, 0] * lz
    r1 = rot[0, 1] * lx + rot[1, 1] * ly + rot[2, 1] * lz
    r2 = rot[0, 2] * lx + rot[1, 2] * ly + rot[2, 2] * lz
    s0 = inv[0, 0] * r0 + inv[0, 1] * r1 + inv[0, 2] * r2
    s1 = inv[1, 0] * r0 + inv[1, 1] * r1 + inv[1, 2] * r2
    s2 = inv[2, 0] * r0 + inv[2, 1] * r1 + inv[2, 2] * r2
    wx = rot[0, 0] * s0 + rot[0, 1] * s1 + rot[0, 2] * s2
    wy = rot[1, 0] * s0 + rot[1, 1] * s1 + rot[1, 2] * s2
    wz = rot[2, 0] * s0 + rot[2, 1] * s1 + rot[2, 2] * s2
    return wx, wy, wz
