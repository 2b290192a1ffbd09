"""Fragments: connected components of the alive-link graph, recomputed only where needed.

After fracture marks links broken or voxels destroyed, the bodies they belong
to are "dirty". Only dirty bodies are searched (union-find over alive
links). A dirty body that is still one piece is left alone; one that fell
apart is retired and each component becomes a new body whose motion is the
parent's rigid motion (see :mod:`blastvox.simulate.bodies`). A destroyed voxel
has no alive links, so it comes out as its own component and becomes a dust
body: frozen, invisible from then on, its momentum handed to dust particles.
"""

from __future__ import annotations

import numpy as np

from blastvox.geometry.quaternion_nb import matrix_into
from blastvox.jit import helper, kernel
from blastvox.simulate.bodies import aggregate, inverse_inertia
from blastvox.simulate.integrate import angular_velocity, world_tensor_times
from blastvox.simulate.kernels import body_radii, body_rotations, link_masks, release_held
from blastvox.simulate.state import grow_bodies


@helper
def root_of(parent, v) -> int:
    """Union-find root of v, halving the path on the way."""
    while parent[v] != v:
        parent[v] = parent[parent[v]]
        v = parent[v]
    return v


@helper
def label_components(dirty: np.ndarray, voxel_body: np.ndarray, link_alive: np.ndarray,
                     link_voxels: np.ndarray, offsets: np.ndarray, link_ids: np.ndarray,
                     component: np.ndarray, order: np.ndarray):
    """Label the voxels of dirty bodies by component.

    component (N,) gets a component id (others -1); ``order`` receives the
    voxels grouped by component, ascending within each group, groups in order
    of their lowest voxel index. Returns (count, start (count + 1,)): group c
    is order[start[c]:start[c + 1]]. Union-find over the alive links in voxel
    order (sequential memory access, unlike a breadth-first search): a larger
    root always hangs under a smaller one, so every root is its set's lowest
    voxel and parents only ever point down.
    """
    n = voxel_body.shape[0]
    parent = order  # scratch until the grouping pass
    for v in range(n):
        parent[v] = v if dirty[voxel_body[v]] else -1
    for v in range(n):
        if parent[v] < 0:
            continue
        for k in range(offsets[v], offsets[v + 1]):
            link = link_ids[k]
            if not link_alive[link]:
                continue
            w = np.int64(link_voxels[link, 0])  # int64 as v: one root_of for both
            if w == v:
                w = np.int64(link_voxels[link, 1])
            if w < v:
                continue  # each link once, from its lower voxel
            ra = root_of(parent, v)
            rb = root_of(parent, w)
            if ra < rb:
                parent[rb] = ra
            elif rb < ra:
                parent[ra] = rb
    count = 0
    for v in range(n):  # ascending: parent[v] < v is labelled already
        if parent[v] < 0:
            component[v] = -1
        elif parent[v] == v:
            component[v] = count
            count += 1
        else:
            component[v] = component[root_of(parent, v)]
    start = np.zeros(count + 1, dtype=np.int64)
    for v in range(n):
        if component[v] >= 0:
            start[component[v] + 1] += 1
    for c in range(count):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    for v in range(n):
        c = component[v]
        if c >= 0:
            order[fill[c]] = v
            fill[c] += 1
    return count, start


@kernel
def split_bodies(dirty, step, geometry, link_geometry, voxels, links, bodies, component,
                 order) -> int:
    """Split every body flagged in ``dirty`` (B,) that fell apart, at step ``step``.

    New bodies take the next free slots (bodies.count grows); the parents are
    retired (live False, died = step). component, order (N,) int32: work arrays.
    Returns the number of new bodies, or minus the number it needs when the body
    arrays have too few free slots (nothing is changed then: grow them and call
    again, :func:`split_phase`)."""
    voxel_body, voxel_alive, voxel_foundation = voxels.body, voxels.alive, voxels.foundation
    link_alive, link_voxels = links.alive, link_geometry.voxels
    offsets, link_ids = geometry.link_offsets, geometry.link_ids
    voxel_mass, voxel_centroid, voxel_inertia = geometry.mass, geometry.centroid, geometry.inertia
    body_mass, body_com, body_inertia = bodies.mass, bodies.com, bodies.inertia
    body_inv_inertia, body_pos, body_quat = bodies.inv_inertia, bodies.pos, bodies.quat
    body_lin, body_ang, body_fixed, body_live = bodies.lin, bodies.ang, bodies.fixed, bodies.live
    body_dust, body_parent, body_born = bodies.dust, bodies.parent, bodies.born
    body_died, n_bodies = bodies.died, bodies.count
    ncomp, start = label_components(dirty, voxel_body, link_alive, link_voxels, offsets,
                                    link_ids, component, order)
    if ncomp == 0:
        return 0
    # how many components each parent has
    pieces = np.zeros(body_mass.shape[0], dtype=np.int64)
    for c in range(ncomp):
        pieces[voxel_body[order[start[c]]]] += 1
    needed = 0
    for c in range(ncomp):
        if pieces[voxel_body[order[start[c]]]] >= 2:
            needed += 1
    if n_bodies[0] + needed > body_mass.shape[0]:
        return -needed
    created = 0
    rot = np.empty((3, 3))
    pos = np.empty(3)
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
        matrix_into(body_quat[parent], rot)
        dx = com[0] - body_com[parent, 0]
        dy = com[1] - body_com[parent, 1]
        dz = com[2] - body_com[parent, 2]
        for a in range(3):
            pos[a] = body_pos[parent, a] + rot[a, 0] * dx + rot[a, 1] * dy + rot[a, 2] * dz
        fixed = False
        for v in members:
            voxel_body[v] = b
            if voxel_foundation[v] and voxel_alive[v]:
                fixed = True
        # element-wise copies: row assignment would compile numba's shape-error machinery
        inv = inverse_inertia(inertia)
        body_mass[b] = mass
        for a in range(3):
            body_com[b, a] = com[a]
            body_pos[b, a] = pos[a]
            for c in range(3):
                body_inertia[b, a, c] = inertia[a, c]
                body_inv_inertia[b, a, c] = inv[a, c]
        for a in range(4):
            body_quat[b, a] = body_quat[parent, a]
        body_fixed[b] = fixed
        body_live[b] = True
        body_dust[b] = members.shape[0] == 1 and not voxel_alive[members[0]]
        body_parent[b] = parent
        body_born[b] = step
        body_died[b] = -1
        if body_fixed[parent]:
            body_lin[b] = 0.0
            body_ang[b] = 0.0
            continue
        # rigid kinematics: v + omega x (c_new - c), omega kept, L = I_world omega
        wx, wy, wz = angular_velocity(rot, body_inv_inertia[parent], body_ang[parent])
        rx = pos[0] - body_pos[parent, 0]
        ry = pos[1] - body_pos[parent, 1]
        rz = pos[2] - body_pos[parent, 2]
        pm = body_mass[parent]
        body_lin[b, 0] = mass * (body_lin[parent, 0] / pm + wy * rz - wz * ry)
        body_lin[b, 1] = mass * (body_lin[parent, 1] / pm + wz * rx - wx * rz)
        body_lin[b, 2] = mass * (body_lin[parent, 2] / pm + wx * ry - wy * rx)
        # L = I_world omega = R I R^T omega
        lx, ly, lz = world_tensor_times(rot, inertia, wx, wy, wz)
        body_ang[b, 0], body_ang[b, 1], body_ang[b, 2] = lx, ly, lz
    for p in range(body_mass.shape[0]):
        if pieces[p] >= 2:
            body_live[p] = False
            body_died[p] = step
    return created


@kernel
def refresh_fixed(voxels, bodies) -> None:
    """A body is fixed while it has a live foundation voxel; a freed body starts at rest."""
    voxel_body, voxel_alive, voxel_foundation = voxels.body, voxels.alive, voxels.foundation
    body_fixed, body_live, body_lin, body_ang = bodies.fixed, bodies.live, bodies.lin, bodies.ang
    has = np.zeros(body_fixed.shape[0], dtype=np.bool_)
    for v in range(voxel_body.shape[0]):
        if voxel_alive[v] and voxel_foundation[v]:
            has[voxel_body[v]] = True
    for b in range(body_fixed.shape[0]):
        if body_live[b] and body_fixed[b] and not has[b]:
            body_fixed[b] = False
            body_lin[b] = 0.0
            body_ang[b] = 0.0


def split_phase(model, state, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Phase: apply the links broken and voxels destroyed (marks) since the last split.

    Links of destroyed voxels die with them; link masks are rebuilt; dirty
    bodies that fell apart are split (:func:`split_bodies`, new bodies awake,
    poses and radii refreshed); freed pieces take their held blast impulse.
    Returns (broken links, destroyed voxels), the ids applied, and clears
    marks.broken, marks.destroyed and the boundary cache. Both empty: nothing
    to do, nothing changed.
    """
    marks = state.marks
    destroyed = np.flatnonzero(marks.destroyed)
    broken = np.flatnonzero(marks.broken)
    if not destroyed.size and not broken.size:
        return broken, destroyed
    state.counters.topology_version += 1
    if destroyed.size:
        kill_links_of(marks.destroyed, model.voxels.link_offsets, model.voxels.link_ids,
                      state.links.alive)
    link_masks(model.links, state.links, state.voxels)
    created = split_bodies(marks.dirty, step, model.voxels, model.links, state.voxels,
                           state.links, state.bodies, state.scratch.component,
                           state.scratch.order)
    if created < 0:  # more pieces than free body slots
        grow_bodies(state, state.n_bodies - created)
        marks = state.marks
        split_bodies(marks.dirty, step, model.voxels, model.links, state.voxels, state.links,
                     state.bodies, state.scratch.component, state.scratch.order)
    n = state.n_bodies
    state.bodies.asleep[:n][marks.dirty[:n]] = False
    body_rotations(state.bodies.quat, state.bodies.live, n, state.bodies.rot)
    if state.holding:
        release_held(model.voxels, state.voxels, state.bodies, state.loads)
    body_radii(model.voxels, state.voxels, state.bodies)
    state.caches.boundary = None
    marks.broken[:] = False
    marks.destroyed[:] = False
    return broken, destroyed


@kernel
def kill_links_of(destroyed, voxel_link_offsets, voxel_link_ids, link_alive) -> None:
    """A dusted voxel's links vanish with it (not counted as breaks)."""
    for v in range(destroyed.shape[0]):
        if not destroyed[v]:
            continue
        for k in range(voxel_link_offsets[v], voxel_link_offsets[v + 1]):
            link_alive[voxel_link_ids[k]] = False
