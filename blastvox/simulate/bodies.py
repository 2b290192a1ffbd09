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

import numba as nb
import numpy as np

from blastvox.simulate.quaternion import to_matrix


@nb.njit(cache=True)
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


@nb.njit(cache=True)
def inverse_inertia(inertia: np.ndarray) -> np.ndarray:
    """I^-1 (3, 3) of a rest-frame inertia tensor; zeros if it is singular (no rotation)."""
    scale = max(abs(inertia[0, 0]), abs(inertia[1, 1]), abs(inertia[2, 2]))
    if scale <= 0.0 or abs(np.linalg.det(inertia)) <= 1e-12 * scale ** 3:
        return np.zeros((3, 3))
    return np.linalg.inv(inertia)


@nb.njit(cache=True)
def angular_velocity(inv_inertia: np.ndarray, quat: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """omega (rad/s, world) = R I_rest^-1 R^T L from angular momentum about the centre of mass."""
    rot = to_matrix(quat)
    return rot @ (inv_inertia @ (rot.T @ ang))
