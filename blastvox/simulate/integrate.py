"""Time integration of free bodies at a fixed step, in two halves around contacts.

Momentum form, semi-implicit Euler: :func:`integrate_velocities` adds the
blast impulse of the step (exact, see :mod:`blastvox.simulate.forces`),
gravity and drag to the momenta; contacts then change momenta at velocity
level; :func:`integrate_positions` moves bodies with the resulting velocities.
Drag is exponential decay of the momenta (1/s rates), stable at any step.

Rotation (:func:`rotate_free`) keeps the world angular momentum L fixed and
turns the body by the exact exponential map of an angular velocity omega that
is implicit in the step: omega = R I^-1 R^T (L + exp(-h omega^) L) / 2, the
inertia applied to the mean of the body-frame momentum at both ends of the
step (the implicit midpoint rule of Euler's equations, with the exponential
map instead of the Cayley map). That conserves, to round-off, what a free
rigid body conserves: |q| = 1 (a unit rotation), L (never touched) and the
kinetic energy L . omega / 2 (the body-frame momentum turns about omega, so
its change is orthogonal to I^-1 times its mean). A spin about a principal
axis keeps its exact phase (then omega = I^-1 L, as before). The explicit
update omega = R I^-1 R^T L of the papers pumps energy into a tumbling,
asymmetric body until it spins about its axis of least inertia (twice the
energy within 10 s at 1e3 rad/s, even at dt = 1/2400 s). omega is found by
fixed-point iteration, on sub-steps of at most :data:`SUBSTEP_RAD` of spin so
the iteration contracts; a body spinning more than :data:`MAX_SPIN_PER_STEP`
rad per step falls back to one explicit update (and
:mod:`blastvox.simulate.limits` warns).

Between the halves, the contact solver (:func:`blastvox.simulate.contact.solver.solve_contacts`)
works on velocities (and moves the bodies its sub-steps push apart); what it needs of
a contact row (the velocity at its point, an impulse there) is at the end of this
module.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.geometry import quaternion_nb
from blastvox.jit import helper, kernel

#: Spin (rad) of one rotation sub-step, measured as h |L| tr(I^-1) / 3 (|omega| h
#: for a body of isotropic inertia): small enough that the fixed-point iteration
#: for the implicit omega contracts by about 4x per iteration whatever the shape.
SUBSTEP_RAD = 1.0 / 6.0
#: Sub-steps at most per step; beyond MAX_SPIN_PER_STEP rad per step of spin the
#: rotation falls back to one explicit update (energy then bounded by L^2 / 2 I_min,
#: not conserved) and the run warns (blastvox.simulate.limits).
MAX_SUBSTEPS = 240
MAX_SPIN_PER_STEP = SUBSTEP_RAD * MAX_SUBSTEPS  # 40 rad
_MAX_ITERATIONS = 60


@helper
def moving(b, body_live, body_fixed, body_dust, body_asleep) -> bool:
    """True for a body the integrator moves."""
    # bitwise, not `a and not b ...` or ifs: numba compiles this test, in the loop
    # over all bodies of every kernel, ~15x slower with short-circuit branches
    return body_live[b] & (not (body_fixed[b] | body_dust[b] | body_asleep[b]))


@kernel
def integrate_velocities(dt: float, gravity: np.ndarray, linear_drag: float,
                         angular_drag: float, loads, bodies) -> None:
    """Momenta after this step's blast impulse (loads.impulse, loads.angular: N s, N m s;
    (B, 3)), gravity (3,) m/s^2 and drag (1/s)."""
    impulse, angular_impulse = loads.impulse, loads.angular
    body_mass, body_lin, body_ang = bodies.mass, bodies.lin, bodies.ang
    body_fixed, body_live, body_dust = bodies.fixed, bodies.live, bodies.dust
    body_asleep, n_bodies = bodies.asleep, bodies.count[0]
    lin_decay = math.exp(-linear_drag * dt)
    ang_decay = math.exp(-angular_drag * dt)
    for b in range(n_bodies):
        if not moving(b, body_live, body_fixed, body_dust, body_asleep):
            continue
        m = body_mass[b]
        for a in range(3):
            body_lin[b, a] = (body_lin[b, a] + impulse[b, a] + m * gravity[a] * dt) * lin_decay
            body_ang[b, a] = (body_ang[b, a] + angular_impulse[b, a]) * ang_decay


@kernel
def integrate_positions(dt: float, bodies) -> None:
    """Move bodies by their current velocities for ``dt`` seconds.

    Reads bodies.inv_inertia (B, 3, 3) rest-frame I^-1 and bodies.rot (B, 3, 3),
    the rotation matrices of the current quaternions; writes pos and quat.
    """
    body_mass, body_inv_inertia, body_rot = bodies.mass, bodies.inv_inertia, bodies.rot
    body_pos, body_quat, body_lin, body_ang = bodies.pos, bodies.quat, bodies.lin, bodies.ang
    body_fixed, body_live, body_dust = bodies.fixed, bodies.live, bodies.dust
    body_asleep, n_bodies = bodies.asleep, bodies.count[0]
    scratch = np.empty((3, 3))
    for b in range(n_bodies):
        if not moving(b, body_live, body_fixed, body_dust, body_asleep):
            continue
        m = body_mass[b]
        for a in range(3):
            body_pos[b, a] += body_lin[b, a] / m * dt
        rotate_free(body_quat[b], body_rot[b], body_inv_inertia[b], body_ang[b], dt, scratch)


@helper
def world_tensor_times(rot, tensor, x, y, z):
    """R T R^T (x, y, z), no allocation: a rest-frame tensor T (3, 3) (inertia, or its
    inverse) applied in the world frame of a body with rotation ``rot`` (3, 3)."""
    r0 = rot[0, 0] * x + rot[1, 0] * y + rot[2, 0] * z
    r1 = rot[0, 1] * x + rot[1, 1] * y + rot[2, 1] * z
    r2 = rot[0, 2] * x + rot[1, 2] * y + rot[2, 2] * z
    s0 = tensor[0, 0] * r0 + tensor[0, 1] * r1 + tensor[0, 2] * r2
    s1 = tensor[1, 0] * r0 + tensor[1, 1] * r1 + tensor[1, 2] * r2
    s2 = tensor[2, 0] * r0 + tensor[2, 1] * r1 + tensor[2, 2] * r2
    return (rot[0, 0] * s0 + rot[0, 1] * s1 + rot[0, 2] * s2,
            rot[1, 0] * s0 + rot[1, 1] * s1 + rot[1, 2] * s2,
            rot[2, 0] * s0 + rot[2, 1] * s1 + rot[2, 2] * s2)


@helper
def angular_velocity(rot, inv, ang):
    """omega = R I^-1 R^T L (rad/s, world) without allocation."""
    return world_tensor_times(rot, inv, ang[0], ang[1], ang[2])


@helper
def spin_rate(inv, ang) -> float:
    """|L| tr(I^-1) / 3 (rad/s): |omega| for isotropic inertia, otherwise between |omega| / 3
    and |L| / I_min (inv: (3, 3) rest-frame I^-1 in 1/(kg m^2); ang: (3,) L in N m s)."""
    norm = math.sqrt(ang[0] * ang[0] + ang[1] * ang[1] + ang[2] * ang[2])
    return norm * (inv[0, 0] + inv[1, 1] + inv[2, 2]) / 3.0


@helper
def _turn(wx, wy, wz, h, vx, vy, vz):
    """(vx, vy, vz) rotated by the angle |omega| h about omega (Rodrigues), h of any sign."""
    rate = math.sqrt(wx * wx + wy * wy + wz * wz)
    if rate == 0.0:
        return vx, vy, vz
    ax, ay, az = wx / rate, wy / rate, wz / rate
    c, s = math.cos(rate * h), math.sin(rate * h)
    d = (ax * vx + ay * vy + az * vz) * (1.0 - c)
    return (vx * c + (ay * vz - az * vy) * s + ax * d,
            vy * c + (az * vx - ax * vz) * s + ay * d,
            vz * c + (ax * vy - ay * vx) * s + az * d)


@helper
def rotate_free(q, rot, inv, ang, dt, scratch) -> None:
    """Turn unit quaternion q (w, x, y, z) by dt s of torque-free motion (see module doc).

    rot: (3, 3) rotation matrix of q; inv: (3, 3) rest-frame I^-1 (1/(kg m^2));
    ang: (3,) world angular momentum L (N m s), unchanged; scratch: (3, 3) work array.
    """
    lx, ly, lz = ang[0], ang[1], ang[2]
    spin = spin_rate(inv, ang) * dt
    if spin == 0.0:
        return
    if spin > MAX_SPIN_PER_STEP:
        wx, wy, wz = angular_velocity(rot, inv, ang)
        quaternion_nb.integrate(q, wx, wy, wz, dt)
        return
    k = max(1, int(math.ceil(spin / SUBSTEP_RAD)))
    h = dt / k
    for sub in range(k):
        r = rot
        if sub > 0:
            quaternion_nb.matrix_into(q, scratch)
            r = scratch
        wx, wy, wz = world_tensor_times(r, inv, lx, ly, lz)
        for _ in range(_MAX_ITERATIONS):
            ex, ey, ez = _turn(wx, wy, wz, -h, lx, ly, lz)
            nx, ny, nz = world_tensor_times(r, inv, 0.5 * (lx + ex), 0.5 * (ly + ey),
                                            0.5 * (lz + ez))
            change = abs(nx - wx) + abs(ny - wy) + abs(nz - wz)
            wx, wy, wz = nx, ny, nz
            if change <= 1e-14 * (abs(wx) + abs(wy) + abs(wz)):
                break
        quaternion_nb.integrate(q, wx, wy, wz, h)


# --------------------------------------------------------------------------- contacts
# The contact solver (:func:`blastvox.simulate.contact.solver.solve_contacts`) changes the
# velocities between the two halves, and moves the bodies it pushes apart. What it
# needs of a contact row is here.

# Work arrays of a solve. bw (n, 30), by moving body: velocity (m/s), angular velocity
# (rad/s), then both as they were before the solve, 1 / mass (1/kg), world inverse
# inertia R I^-1 R^T (1/(kg m^2), row by row), two unused columns, then the step's
# change of velocity and angular velocity by its loads and
# gravity (m/s, rad/s). rw (count, RW_WIDTH), by row: lever arms r_a, r_b of its centre
# (m, from each centre of mass; 0 for a body that does not move); effective masses of
# friction along t1, t2 (kg) and of twist about n (kg m^2), and their inverses; the
# accumulated impulses of a sub-step (the corners' normals (N s, four), friction along
# t1, t2 (N s), twist (N m s)); the corners' normal velocities before the solve (m/s,
# < 0: approaching); r_a x n and r_b x n of each corner (m); the corners' coupling
# matrix K (1/kg, its upper triangle by rows).
#: Sweeps at most of the projected Gauss-Seidel solve of one row's corners together, and
#: the change of a corner's normal velocity (m/s) at which it stops.
CORNER_SWEEPS = 16
CORNER_TOLERANCE = 1e-10

RW_EFF, RW_K, RW_ACC, RW_TARGET, RW_CA, RW_CB, RW_KN, RW_WIDTH = (
    6, 9, 12, 19, 23, 35, 47, 57)


@helper
def relative_velocity(r, ea, eb, bw, rw):
    """Velocity (m/s) of body b relative to body a at row r's centre (ea, eb: their solve
    indices, -1 for one that does not move)."""
    vx, vy, vz = 0.0, 0.0, 0.0
    for side in range(2):
        e = ea if side == 0 else eb
        if e < 0:
            continue
        o = 3 * side
        rx, ry, rz = rw[r, o], rw[r, o + 1], rw[r, o + 2]
        ux = bw[e, 0] + bw[e, 4] * rz - bw[e, 5] * ry
        uy = bw[e, 1] + bw[e, 5] * rx - bw[e, 3] * rz
        uz = bw[e, 2] + bw[e, 3] * ry - bw[e, 4] * rx
        if side == 0:
            vx, vy, vz = vx - ux, vy - uy, vz - uz
        else:
            vx, vy, vz = vx + ux, vy + uy, vz + uz
    return vx, vy, vz


@helper
def corner_speed(r, i, ends, frame, bw, rw) -> float:
    """Normal velocity (m/s) of body b relative to body a at row r's corner i."""
    s = 0.0
    for side in range(2):
        e = ends[r, side]
        if e < 0:
            continue
        o = (RW_CA if side == 0 else RW_CB) + 3 * i
        u = (frame[r, 0, 0] * bw[e, 0] + frame[r, 0, 1] * bw[e, 1] + frame[r, 0, 2] * bw[e, 2]
             + rw[r, o] * bw[e, 3] + rw[r, o + 1] * bw[e, 4] + rw[r, o + 2] * bw[e, 5])
        s += u if side == 1 else -u
    return s


@helper
def push_corner(e, impulse, r, i, side, frame, bw, rw) -> None:
    """Normal impulse (N s, along row r's n) at its corner i on the body of solve index e
    (side 0: a, 1: b): its velocities in bw."""
    o = (RW_CA if side == 0 else RW_CB) + 3 * i
    turn_by(e, impulse * rw[r, o], impulse * rw[r, o + 1], impulse * rw[r, o + 2], bw)
    for a in range(3):
        bw[e, a] += impulse * bw[e, 12] * frame[r, 0, a]


@helper
def apply_at(e, sign, px, py, pz, r, side, bw, rw) -> None:
    """Impulse sign (px, py, pz) (N s) at row r's centre on the body of solve index e
    (its lever arm rw[r, 3 side:]): its velocities in bw."""
    if e < 0:
        return
    px, py, pz = sign * px, sign * py, sign * pz
    o = 3 * side
    rx, ry, rz = rw[r, o], rw[r, o + 1], rw[r, o + 2]
    turn_by(e, ry * pz - rz * py, rz * px - rx * pz, rx * py - ry * px, bw)
    inv_mass = bw[e, 12]
    bw[e, 0] += px * inv_mass
    bw[e, 1] += py * inv_mass
    bw[e, 2] += pz * inv_mass


@helper
def turn_by(e, mx, my, mz, bw) -> None:
    """Angular impulse (mx, my, mz) (N m s) on the body of solve index e: its angular
    velocity in bw."""
    wx = bw[e, 13] * mx + bw[e, 14] * my + bw[e, 15] * mz
    wy = bw[e, 16] * mx + bw[e, 17] * my + bw[e, 18] * mz
    wz = bw[e, 19] * mx + bw[e, 20] * my + bw[e, 21] * mz
    bw[e, 3] += wx
    bw[e, 4] += wy
    bw[e, 5] += wz
