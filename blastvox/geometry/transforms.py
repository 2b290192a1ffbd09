"""Rigid transforms of bodies and pieces: rest frame <-> world, and change of frame.

A body (a simulated fragment, an exported piece) is rigid: a point at
``x_rest`` in the rest frame (the VoxelModel's coordinates, metres) is at

    ``x_world = p + R(q) (x_rest - c_rest)``

where ``c_rest`` (3,) m is the body's pivot in the rest frame (its rest centre
of mass), ``p`` (3,) m where the pivot is in the world and ``q`` (4,) the unit
quaternion (w, x, y, z) of its turn (:mod:`blastvox.geometry.quaternion`).
Piece-local coordinates are ``x_rest - c_rest`` (pass ``centre=None``).

All functions take NumPy arrays that broadcast against each other (one body
per row, or one body for many points) and return new float64 arrays. The
numba face is :mod:`blastvox.geometry.transforms_nb`, with the
same formula.
"""

from __future__ import annotations

import numpy as np

from blastvox.geometry import exact, quaternion


def rest_to_world(x_rest: np.ndarray, position: np.ndarray, orientation: np.ndarray,
                  centre: np.ndarray | None = None) -> np.ndarray:
    """World points (..., 3) m: ``position + R(orientation) (x_rest - centre)``.

    x_rest (..., 3) m: rest-frame points, or piece-local points if ``centre`` is None;
    position (..., 3) m: world position of each body's pivot; orientation (..., 4):
    unit quaternions (w, x, y, z); centre (..., 3) m: the pivot in the rest frame.
    """
    local = x_rest if centre is None else x_rest - centre
    return position + quaternion.rotate(orientation, local)


def world_to_rest(x_world: np.ndarray, position: np.ndarray, orientation: np.ndarray,
                  centre: np.ndarray | None = None) -> np.ndarray:
    """The inverse of :func:`rest_to_world`: rest-frame points (..., 3) m
    ``centre + R(orientation)^T (x_world - position)`` (piece-local if ``centre`` is None)."""
    local = quaternion.rotate(quaternion.conjugate(orientation), x_world - position)
    return local if centre is None else centre + local


def change_frame(position: np.ndarray, orientation: np.ndarray,
                 change: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rigid transforms re-expressed in another frame, x' = C x.

    position (..., 3) m and orientation (..., 4) unit quaternions (w, x, y, z)
    map piece-local points to the world; ``change`` (3, 3) is the rotation C
    (e.g. :func:`blastvox.geometry.frames.frame_change`), applied to the world
    and to the piece-local frame alike. Returns float64 position' = C position
    (..., 3) and orientation' = q_C q q_C^-1 (..., 4), renormalised.
    """
    qc = quaternion.from_matrix(change)
    position = exact.turn(change, np.asarray(position).astype(np.float64))
    orientation = quaternion.multiply(
        quaternion.multiply(qc, np.asarray(orientation).astype(np.float64)),
        quaternion.conjugate(qc))
    orientation /= exact.length(orientation, keepdims=True)
    return position, orientation
