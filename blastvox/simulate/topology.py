"""Fragments: connected components of the alive-link graph, recomputed only where needed.

After fracture marks links broken or voxels destroyed, the bodies they belong
to are "dirty". Only dirty bodies are searched (breadth-first over alive
links). A dirty body that is still one piece is left alone; one that fell
apart is retired and each component becomes a new body whose motion is the
parent's rigid motion (see :mod:`blastvox.simulate.bodies`). A destroyed voxel
has no alive links, so it comes out as its own component and becomes a dust
body: frozen, invisible from then on, its momentum handed to dust particles.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from blastvox.simulate.bodies import aggregate, angular_velocity, inverse_inertia
from blastvox.simulate.quaternion import to_matrix


@nb.njit(cache=True)
def label_components(dirty: np.ndarray, voxel_body: np.ndarray, link_alive: np.ndarray,
                     link_voxels: np.ndarray, offsets: np.ndarray, link_ids: np.ndarray,
                     component: np.ndarray, order: np.ndarray) -> int:
    """Label the voxels of dirty bodies by component; return the number of components.

    component (N,) gets a component id (others -1); ``order`` receives the
    voxels grouped by component (BFS order), each group starting at its lowest
    voxel index, groups in order of that index.
    """
    n = voxel_body.shape[0]
    count = 0
    head = 0
    for v in range(n):
        component[v] = -1
    for seed in range(n):
        if not dirty[voxel_body[seed]] or component[seed] >= 0:
            continue
        component[seed] = count
        order[head] = seed
        tail = head + 1
        while head < tail:
            v = order[head]
            head += 1
            for k in range(offsets[v], offsets[v + 1]):
                link = link_ids[k]
                if not link_alive[link]:
                    continue
                w = link_voxels[link, 0]
                if w == v:
                    w = link_voxels[link, 1]
                if component[w] < 0:
                    component[w] = count
                    order[tail] = w
                    tail += 1
        count += 1
    return count


@nb.njit(cache=True)
def split_bodies(dirty, step, voxel_body, voxel_alive, voxel_foundation, link_alive,
                 link_voxels, offsets, link_ids, voxel_mass, voxel_centroid, voxel_inertia,
                 body_mass, body_com, body_inertia, body_inv_inertia, body_pos, body_quat,
                 body_lin, body_ang,
                 body_fixed, body_live, body_dust, body_parent, body_born, body_died,
                 n_bodies, component, order) -> int:
    """Split every dirty body that fell apart. Returns the number of new bodies."""
    n = voxel_body.shape[0]
    ncomp = label_components(dirty, voxel_body, link_alive, link_voxels, offsets, link_ids,
                             component, order)
    if ncomp == 0:
        return 0
    # component boundaries in `order`, and how many components each parent has
    start = np.zeros(ncomp + 1, dtype=np.int64)
    for v in range(n):
        if component[v] >= 0:
            start[component[v] + 1] += 1
    for c in range(ncomp):
        start[c + 1] += start[c]
    pieces = np.zeros(body_mass.shape[0], dtype=np.int64)
    for c in range(ncomp):
        pieces[voxel_body[order[start[c]]]] += 1
    created = 0
    for c in range(ncomp):
        members = order[start[c]:start[c + 1]]
        parent = voxel_body[members[0]]
        if pieces[parent] < 2:
            # still one piece; a lone voxel that was destroyed becomes dust in place
            if members.shape[0] == 1 and not voxel_alive[members[0]]:
                body_dust[parent] = True
            continue
        b = n_bodies[0]
        n_bodies[0] += 1
        created += 1
        mass, com, inertia = aggregate(members, voxel_mass, voxel_centroid, voxel_inertia)
        rot = to_matrix(body_quat[parent])
        pos = body_pos[parent] + rot @ (com - body_com[parent])
        fixed = False
        for v in members:
            voxel_body[v] = b
            if voxel_foundation[v] and voxel_alive[v]:
                fixed = True
        body_mass[b] = mass
        body_com[b] = com
        body_inertia[b] = inertia
        body_inv_inertia[b] = inverse_inertia(inertia)
        body_pos[b] = pos
        body_quat[b] = body_quat[parent]
        body_fixed[b] = fixed
        body_live[b] = True
        body_dust[b] = members.shape[0] == 1 and not voxel_alive[members[0]]
        body_parent[b] = parent
        body_born[b] = step
        body_died[b] = -1
        if body_fixed[parent]:
            body_lin[b] = 0.0
            body_ang[b] = 0.0
        else:
            pm = body_mass[parent]
            v_parent = body_lin[parent] / pm
            omega = angular_velocity(body_inv_inertia[parent], body_quat[parent],
                                     body_ang[parent])
            v_new = v_parent + np.cross(omega, pos - body_pos[parent])
            body_lin[b] = mass * v_new
            body_ang[b] = rot @ inertia @ rot.T @ omega
    for p in range(body_mass.shape[0]):
        if pieces[p] >= 2:
            body_live[p] = False
            body_died[p] = step
    return created


@nb.njit(cache=True)
def refresh_fixed(voxel_body, voxel_alive, voxel_foundation, body_fixed, body_live,
                  body_lin, body_ang) -> None:
    """A body is fixed while it has a live foundation voxel; a freed body starts at rest."""
    has = np.zeros(body_fixed.shape[0], dtype=np.bool_)
    for v in range(voxel_body.shape[0]):
        if voxel_alive[v] and voxel_foundation[v]:
            has[voxel_body[v]] = True
    for b in range(body_fixed.shape[0]):
        if body_live[b] and body_fixed[b] and not has[b]:
            body_fixed[b] = False
            body_lin[b] = 0.0
            body_ang[b] = 0.0
