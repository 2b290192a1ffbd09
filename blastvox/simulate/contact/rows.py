"""The contact rows that the fragment and ground phases gather and the solver solves
(:class:`ContactRows`): one per touching voxel pair, or voxel and ground."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class ContactRows(NamedTuple):
    """The contacts of one step, M rows (capacity; a step uses the first ``count``).

    body (M, 2) int64: bodies a and b (-1: the ground), the normal pointing from a
    to b; voxel (M, 2) int64: their voxels (-1: the ground); key (M,) int64: the
    contact's identity from step to step (a voxel pair, or a body's corner on the
    ground), for warm starting; frame (M, 3, 3): rows n, t1, t2, orthonormal;
    corners (M, 4, 3) m and corner_gap (M, 4) m: the contact's points (up to four: a
    face's manifold) and their separations along n at the step's start (< 0:
    penetration); used (M,) int64: how many; gap (M,) m: the smallest; point (M, 3) m:
    their centre, where friction acts; arm (M,) m: the lever of twisting friction
    about it (0 for a point); restitution (M,). Written by the solver: approach (M,)
    m/s, the fastest normal approach of a point before the solve (< 0: approaching);
    impulse (M,) N s, the normal impulse of the step, all points together; friction
    (M, 3) N s, the step's friction impulse on b, world vector (-friction on a).
    grip (M,): the row's share of the scene's friction coefficient (1; 0 for a row
    without friction this step, see :func:`~blastvox.simulate.contact.fragments.mute_member_rows`).
    """

    body: np.ndarray
    voxel: np.ndarray
    key: np.ndarray
    frame: np.ndarray
    corners: np.ndarray
    corner_gap: np.ndarray
    used: np.ndarray
    gap: np.ndarray
    point: np.ndarray
    arm: np.ndarray
    restitution: np.ndarray
    approach: np.ndarray
    impulse: np.ndarray
    friction: np.ndarray
    grip: np.ndarray
