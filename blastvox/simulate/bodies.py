"""Rigid bodies: mass properties from voxels, and momentum-exact splits.

Bodies live in flat arrays with one slot per possible body (a body is a set
of voxels; there are never more bodies than voxels plus the initial objects).
Per body: mass (kg), rest centre of mass ``com`` (m, model frame), inertia
``inertia`` (kg m^2, about the rest centre of mass, model frame), world
position ``pos`` of the centre of mass (m), orientation ``quat`` (rest -> world),
linear momentum ``lin`` (kg m/s) and angular momentum ``ang`` about the centre
of mass (kg m^2/s, world frame).

A split gives each fragment the velocity of the parent's rigid motion at the
fragment's centre of mass, v + omega x (c_frag - c), and keeps omega. The
velocity field is unchanged, so total linear and angular momentum are
conserved exactly (to round-off), unlike the mass-weighted shares of
Martins 2001 eqs. 4-6/4-7, which lose the orbital part.
"""

from __future__ import annotations

import numpy as np

from blastvox.jit import helper, kernel
from blastvox.simulate.integrate import world_tensor_times


@kernel
def aggregate(members: np.ndarray, voxel_mass: np.ndarray, voxel_centroid: np.ndarray,
              voxel_inertia: np.ndarray):
    """Mass (kg), centre of mass (3,) and inertia (3, 3) about it of the voxels ``members``.

    The inertia is the sum of each voxel's own inertia and its parallel-axis
    term, all in the model (rest) frame.
    """
    mass = 0.0
    first = np.zeros(3)
    for v in members:
        m = voxel_mass[v]
        mass += m
        for a in range(3):
            first[a] += m * voxel_centroid[v, a]
    com = first / mass if mass > 0.0 else voxel_centroid[members[0]].copy()
    inertia = np.zeros((3, 3))
    for v in members:
        m = voxel_mass[v]
        d0 = voxel_centroid[v, 0] - com[0]
        d1 = voxel_centroid[v, 1] - com[1]
        d2 = voxel_centroid[v, 2] - com[2]
        dd = d0 * d0 + d1 * d1 + d2 * d2
        d = (d0, d1, d2)
        for r in range(3):
            for s in range(3):
                inertia[r, s] += voxel_inertia[v, r, s] - m * d[r] * d[s]
            inertia[r, r] += m * dd
    return mass, com, inertia


@kernel
def inverse_inertia(inertia: np.ndarray) -> np.ndarray:
    """I^-1 (3, 3) of a rest-frame inertia tensor by its adjugate; zeros if singular.

    Written out (no LAPACK call) because it is tiny and numba compiles it in a blink.
    """
    a, b, c = inertia[0, 0], inertia[0, 1], inertia[0, 2]
    d, e, f = inertia[1, 0], inertia[1, 1], inertia[1, 2]
    g, h, k = inertia[2, 0], inertia[2, 1], inertia[2, 2]
    co0 = e * k - f * h
    co1 = f * g - d * k
    co2 = d * h - e * g
    det = a * co0 + b * co1 + c * co2
    out = np.zeros((3, 3))
    scale = max(abs(a), abs(e), abs(k))
    if scale <= 0.0 or abs(det) <= 1e-12 * scale ** 3:
        return out
    inv = 1.0 / det
    out[0, 0] = co0 * inv
    out[0, 1] = (c * h - b * k) * inv
    out[0, 2] = (b * f - c * e) * inv
    out[1, 0] = co1 * inv
    out[1, 1] = (a * k - c * g) * inv
    out[1, 2] = (c * d - a * f) * inv
    out[2, 0] = co2 * inv
    out[2, 1] = (b * g - a * h) * inv
    out[2, 2] = (a * e - b * d) * inv
    return out


@helper
def point_velocity(b, px, py, pz, body_pos, body_lin, body_mass, omega):
    """Velocity (m/s) of world point p (m) riding on body b spinning at omega (3,) rad/s.

    This and :func:`apply_impulse` take the body arrays they use, not the Bodies
    container: numba passes every field of a container to a compiled callee, and
    helpers called in the innermost contact loops compile faster without them."""
    rx, ry, rz = px - body_pos[b, 0], py - body_pos[b, 1], pz - body_pos[b, 2]
    m = body_mass[b]
    return (body_lin[b, 0] / m + omega[1] * rz - omega[2] * ry,
            body_lin[b, 1] / m + omega[2] * rx - omega[0] * rz,
            body_lin[b, 2] / m + omega[0] * ry - omega[1] * rx)


@helper
def effective_inverse_mass(inv_mass, rot, inv, rx, ry, rz, nx, ny, nz):
    """1/m + n . ((I^-1 (r x n)) x r): inverse mass seen by an impulse along n at r."""
    cx, cy, cz = ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx
    ix, iy, iz = world_tensor_times(rot, inv, cx, cy, cz)
    tx, ty, tz = iy * rz - iz * ry, iz * rx - ix * rz, ix * ry - iy * rx
    return inv_mass + nx * tx + ny * ty + nz * tz


@helper
def apply_impulse(b, j, p, body_pos, body_lin, body_ang):
    """Impulse j = (jx, jy, jz) (N s) on body b at world point p = (px, py, pz) (m):
    momentum and angular momentum about its centre of mass."""
    jx, jy, jz = j
    px, py, pz = p
    body_lin[b, 0] += jx
    body_lin[b, 1] += jy
    body_lin[b, 2] += jz
    rx, ry, rz = px - body_pos[b, 0], py - body_pos[b, 1], pz - body_pos[b, 2]
    body_ang[b, 0] += ry * jz - rz * jy
    body_ang[b, 1] += rz * jx - rx * jz
    body_ang[b, 2] += rx * jy - ry * jx
