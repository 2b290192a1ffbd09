"""Small bookkeeping kernels shared by the step."""

from __future__ import annotations

import numba as nb
import numpy as np

from blastvox.simulate.quaternion import matrix_into


@nb.njit(cache=True)
def body_rotations(body_quat, body_live, n_bodies, out) -> None:
    """Rotation matrices (B, 3, 3) of the live bodies' quaternions."""
    for b in range(n_bodies):
        if body_live[b]:
            matrix_into(body_quat[b], out[b])


@nb.njit(cache=True)
def link_masks(link_voxels, link_face, link_alive, voxel_link_mask) -> None:
    """Bit f of voxel_link_mask[v] set iff an alive link leaves voxel v across face f."""
    voxel_link_mask[:] = 0
    for link in range(link_voxels.shape[0]):
        if link_alive[link]:
            f = link_face[link]
            voxel_link_mask[link_voxels[link, 0]] |= np.uint8(1 << f)
            voxel_link_mask[link_voxels[link, 1]] |= np.uint8(1 << (f - 1))


@nb.njit(cache=True)
def link_alive_counts(offsets, link_ids, link_alive) -> np.ndarray:
    """Number of alive links per voxel (N,)."""
    n = offsets.shape[0] - 1
    out = np.zeros(n, dtype=np.int64)
    for v in range(n):
        for k in range(offsets[v], offsets[v + 1]):
            if link_alive[link_ids[k]]:
                out[v] += 1
    return out
