"""Boundary voxels: the voxels of a body with an exposed face (or a conform surface),
the only ones that take blast pressure or touch anything."""

from __future__ import annotations

import numpy as np

from blastvox.jit import kernel


@kernel
def boundary_lists(voxels, conform_slot, n_bodies):
    """CSR (offsets (B+1,), voxels) of each body's alive boundary voxels, in voxel order.

    A voxel is on the boundary if a face has no alive link (voxels.link_mask)
    or it has a conform surface (conform_slot (N,) >= 0)."""
    voxel_body, voxel_alive, voxel_link_mask = voxels.body, voxels.alive, voxels.link_mask
    count = np.zeros(n_bodies + 1, dtype=np.int64)
    for v in range(voxel_body.shape[0]):
        if voxel_alive[v] and (voxel_link_mask[v] != 0x3F or conform_slot[v] >= 0):
            count[voxel_body[v] + 1] += 1
    for b in range(n_bodies):
        count[b + 1] += count[b]
    fill = count[:-1].copy()
    out = np.empty(count[n_bodies], dtype=np.int64)
    for v in range(voxel_body.shape[0]):
        if voxel_alive[v] and (voxel_link_mask[v] != 0x3F or conform_slot[v] >= 0):
            b = voxel_body[v]
            out[fill[b]] = v
            fill[b] += 1
    return count, out


def boundary_of(model, state) -> tuple[np.ndarray, np.ndarray]:
    """Each body's boundary voxels (offsets (B+1,), voxels), rebuilt only after a topology
    change (:func:`blastvox.simulate.topology.split_phase` drops the cache)."""
    caches = state.caches
    if caches.boundary is None:
        caches.boundary = boundary_lists(state.voxels, model.voxels.conform_slot,
                                         state.n_bodies)
        caches.version += 1
    return caches.boundary
