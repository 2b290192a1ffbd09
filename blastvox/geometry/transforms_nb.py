"""Rigid transforms of bodies: the numba face, for compiled kernels.

``x_world = pos + R (x_rest - com)`` with R a body's (3, 3) rotation matrix
(:func:`blastvox.geometry.quaternion_nb.matrix_into`), pos (3,) m its centre of
mass in the world and com (3,) m in the rest frame. Helpers: callable from
compiled code only. The NumPy face is :mod:`blastvox.geometry.transforms`.
Hot loops that cannot afford a row view write the same sums inline by index
(forces, fracture, contacts); they say "as to_world_into".
"""

from __future__ import annotations

from blastvox.jit import helper


@helper
def to_world_into(rot, pos, com, rest, out) -> None:
    """out (3,) = pos + rot (rest - com), m; no allocation."""
    x, y, z = rest[0] - com[0], rest[1] - com[1], rest[2] - com[2]
    for a in range(3):
        out[a] = pos[a] + rot[a, 0] * x + rot[a, 1] * y + rot[a, 2] * z


@helper
def rotate_into(rot, vec, out) -> None:
    """out (3,) = rot vec: a rest-frame vector (an area, a direction) in the world."""
    for a in range(3):
        out[a] = rot[a, 0] * vec[0] + rot[a, 1] * vec[1] + rot[a, 2] * vec[2]


@helper
def to_rest(rot, pos, com, x, y, z):
    """A world point (x, y, z) m in the rest frame of a body at ``pos`` with rotation
    ``rot`` and rest centre of mass ``com``: R^T (x - pos) + com, as a 3-tuple."""
    dx, dy, dz = x - pos[0], y - pos[1], z - pos[2]
    return (rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz + com[0],
            rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz + com[1],
            rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz + com[2])
