"""Fragment collisions (Martins 2001 §5.1).

Fragments: bounding spheres of bodies (broad phase), then a spatial hash of
the boundary voxels of bodies whose spheres overlap, then voxel spheres of
radius (volume)^(1/3) / 2. Each touching, approaching voxel pair is resolved
once per step with an impulse along the centre line at its midpoint, with the
smaller restitution of the two voxels. Impacts weaken voxels; a voxel whose
strength runs out turns to dust.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from blastvox.geometry.transforms_nb import to_rest
from blastvox.jit import helper, kernel
from blastvox.simulate.bodies import apply_impulse, effective_inverse_mass, point_velocity
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.integrate import angular_velocity, moving, world_tensor_times
from blastvox.simulate.kernels import damp_resting
from blastvox.simulate.spatial_hash import bucket, cell_key, cell_of, hash_buckets
from blastvox.simulate.state import Contacts


@kernel
def static_hash(geometry, offsets, members, bodies, cell):
    """Spatial hash of the boundary voxels of bodies that do not move (fixed or asleep).

    Returns (voxels (S,), positions (S, 3), keys (S,), start): the voxels, their
    world centres and cell keys in bucket order, and the :func:`hash_buckets`
    offsets, so bucket s is the range start[s]:start[s+1] of the three arrays.
    Rebuilt only when the set of resting bodies changes.
    """
    voxel_centroid = geometry.centroid
    body_com, body_pos, body_rot = bodies.com, bodies.pos, bodies.rot
    body_live, body_dust, body_fixed = bodies.live, bodies.dust, bodies.fixed
    body_asleep, n_bodies = bodies.asleep, bodies.count[0]
    count = 0
    for b in range(n_bodies):
        if body_live[b] and not body_dust[b] and (body_fixed[b] or body_asleep[b]):
            count += offsets[b + 1] - offsets[b]
    vox = np.empty(count, dtype=np.int64)
    pos = np.empty((count, 3))
    keys = np.empty(count, dtype=np.int64)
    n = np.int64(0)  # not a literal 0: the callee would compile twice
    for b in range(n_bodies):
        if not (body_live[b] and not body_dust[b] and (body_fixed[b] or body_asleep[b])):
            continue
        for k in range(offsets[b], offsets[b + 1]):
            _place(members[k], b, voxel_centroid, body_com, body_pos, body_rot, pos, n)
            vox[n] = members[k]
            keys[n] = cell_key(cell_of(pos[n, 0], cell), cell_of(pos[n, 1], cell),
                           cell_of(pos[n, 2], cell))
            n += 1
    start, entries = hash_buckets(keys)
    return vox[entries], pos[entries], keys[entries], start


@helper
def _place(v, b, voxel_centroid, body_com, body_pos, body_rot, pos, n) -> None:
    rot = body_rot[b]
    x = voxel_centroid[v, 0] - body_com[b, 0]
    y = voxel_centroid[v, 1] - body_com[b, 1]
    z = voxel_centroid[v, 2] - body_com[b, 2]
    for a in range(3):
        pos[n, a] = body_pos[b, a] + rot[a, 0] * x + rot[a, 1] * y + rot[a, 2] * z


class CollideParams(NamedTuple):
    """wake_speed: m/s of approach that wakes a sleeping body (the sleep speed);
    rest_speed: m/s below which a contact is resting, not an impact; friction:
    Coulomb mu; weakening: fraction of an impact's pressure taken off a voxel's
    yield; cell: hash cell, m (twice the largest contact radius); up (3,)."""

    wake_speed: float
    rest_speed: float
    friction: float
    weakening: float
    cell: float
    up: np.ndarray


# A moving body with at most this many boundary voxels is hashed whole every step;
# a bigger one only where it is inside the bounding sphere of a body it may touch.
SMALL_BODY = 64
_FIELD = 16384  # 14 bits per rest-cell coordinate in a rest-grid key


@helper
def _rest_key(body, i, j, k) -> int:
    """Key of rest cell (i, j, k) of a body; coordinates wrap at 2^14 (a wrapped cell
    only adds candidates, which the distance test then rejects)."""
    return ((body * _FIELD + (i & (_FIELD - 1))) * _FIELD + (j & (_FIELD - 1))) * _FIELD \
        + (k & (_FIELD - 1))


@kernel
def rest_grid(voxel_centroid, voxel_body, members, cell):
    """Boundary voxels hashed by (body, cell of their rest centroid).

    Rest positions never change, so this is rebuilt only when the boundary does.
    Returns (slots (M,), keys (M,), start): boundary slots and their keys in
    bucket order, and the :func:`hash_buckets` offsets.
    """
    keys = np.empty(members.shape[0], dtype=np.int64)
    for k in range(members.shape[0]):
        v = members[k]
        keys[k] = _rest_key(voxel_body[v], cell_of(voxel_centroid[v, 0], cell),
                            cell_of(voxel_centroid[v, 1], cell),
                            cell_of(voxel_centroid[v, 2], cell))
    start, entries = hash_buckets(keys)
    return entries, keys[entries], start


@helper
def _mark_near_rest(b, o, reach, cell, voxel_centroid, members, bodies, rest, world,
                    near) -> int:
    """Mark b's boundary voxels within ``reach`` (m) of body o's centre, found through
    b's rest grid ``rest`` (:func:`rest_grid`): o's centre is taken into b's rest frame.
    Returns how many."""
    body_com, body_pos, body_rot = bodies.com, bodies.pos, bodies.rot
    rest_slot, rest_keys, rest_start = rest
    cx, cy, cz = to_rest(body_rot[b], body_pos[b], body_com[b], body_pos[o, 0],
                         body_pos[o, 1], body_pos[o, 2])
    count = 0
    for i in range(cell_of(cx - reach, cell), cell_of(cx + reach, cell) + 1):
        for j in range(cell_of(cy - reach, cell), cell_of(cy + reach, cell) + 1):
            for k in range(cell_of(cz - reach, cell), cell_of(cz + reach, cell) + 1):
                key = _rest_key(b, i, j, k)
                lo, hi = bucket(key, rest_start)
                for s in range(lo, hi):
                    if rest_keys[s] != key:
                        continue
                    slot = rest_slot[s]
                    if near[slot]:
                        continue
                    v = members[slot]
                    if ((voxel_centroid[v, 0] - cx) ** 2 + (voxel_centroid[v, 1] - cy) ** 2
                            + (voxel_centroid[v, 2] - cz) ** 2) < reach * reach:
                        near[slot] = True
                        _place(v, b, voxel_centroid, body_com, body_pos, body_rot, world, slot)
                        count += 1
    return count


@helper
def _near_voxels(voxel_centroid, offsets, members, bodies, cell, rest, world, near):
    """Mark (in ``near``, by boundary slot) the voxels of moving bodies that may touch
    another body this step, with their world centres in ``world``; returns how many.

    Small bodies (<= SMALL_BODY boundary voxels) take part whole: the voxel hash
    is their broad phase. A bigger moving body takes part where it is within
    ``cell`` of the bounding sphere of a live body whose sphere its own meets:
    a scan of its voxels against a big neighbour, its rest grid (:func:`rest_grid`)
    around a small one, so a big block among thousands of chips stays cheap.
    """
    body_radius, body_com, body_pos, body_rot = bodies.radius, bodies.com, bodies.pos, bodies.rot
    body_fixed, body_live, body_dust = bodies.fixed, bodies.live, bodies.dust
    body_asleep, n_bodies = bodies.asleep, bodies.count[0]
    count = 0
    for b in range(n_bodies):
        if not moving(b, body_live, body_fixed, body_dust, body_asleep):
            continue
        first, last = offsets[b], offsets[b + 1]
        if last - first <= SMALL_BODY:
            for k in range(first, last):
                _place(members[k], b, voxel_centroid, body_com, body_pos, body_rot, world, k)
                near[k] = True
            count += last - first
            continue
        placed = False
        for o in range(n_bodies):
            if o == b or not body_live[o] or body_dust[o]:
                continue
            d2 = ((body_pos[b, 0] - body_pos[o, 0]) ** 2 + (body_pos[b, 1] - body_pos[o, 1]) ** 2
                  + (body_pos[b, 2] - body_pos[o, 2]) ** 2)
            if d2 >= (body_radius[b] + body_radius[o]) ** 2:
                continue
            reach = body_radius[o] + cell
            cells = (2.0 * reach / cell + 2.0) ** 3
            if cells < last - first:
                count += _mark_near_rest(b, o, reach, cell, voxel_centroid, members, bodies,
                                         rest, world, near)
                continue
            if not placed:
                for k in range(first, last):
                    _place(members[k], b, voxel_centroid, body_com, body_pos, body_rot, world, k)
                placed = True
            for k in range(first, last):
                if not near[k] and ((world[k, 0] - body_pos[o, 0]) ** 2
                                    + (world[k, 1] - body_pos[o, 1]) ** 2
                                    + (world[k, 2] - body_pos[o, 2]) ** 2) < reach * reach:
                    near[k] = True
                    count += 1
    return count


@kernel
def collide_bodies(geometry, voxels, bodies, contacts, marks, params, boundary, static,
                   rest) -> int:
    """Find and resolve voxel-sphere contacts between different bodies, once each.

    geometry.contact_radius (N,): collision radius (m), at most params.cell / 2;
    boundary: (offsets, members) each body's boundary voxels; params:
    :class:`CollideParams`; static: :func:`static_hash`; rest: :func:`rest_grid`. The boundary
    voxels of moving bodies that may touch something (:func:`_near_voxels`) go
    into a spatial hash each step; voxels of bodies at rest (fixed or asleep)
    come from ``static_*`` (:func:`static_hash`), so a big standing structure
    costs nothing per step. Contacts are resolved in hash order (deterministic)
    with restitution and Coulomb ``friction`` (mu), and rolling resistance
    (:func:`_resist_rolling`). A gentle contact (approach speed below
    ``rest_speed``, m/s) does not bounce, flags both bodies in ``resting`` (B,)
    for resting-contact damping, and, where one body lies on the other (along
    ``up`` (3,)), lets the lower one hold like the ground if it is flagged in
    ``supported`` (B,) (last step's); the upper one is then flagged in
    ``supported_next`` (B,).
    Impacts weaken the voxels they hit by ``weakening`` x the impact pressure
    rho v_n^2 / 2 (Pa; rho the voxel's density in kg/m^3, v_n the approach
    speed): a stone voxel shrugs off 5 m/s (33 kPa) and turns to dust at
    20 m/s (520 kPa, above its yield). A voxel whose yield that pressure
    exceeds is marked in ``destroyed`` (its body in ``dirty``). hits_out (H, 4)
    receives contact points and approach speeds (m/s, for dust); returns the
    number of contacts resolved.
    """
    offsets, members = boundary
    static_vox, static_pos, static_keys, static_start = static
    voxel_alive, voxel_body, voxel_radius = voxels.alive, voxels.body, geometry.contact_radius
    cell = params.cell
    world = np.empty((members.shape[0], 3))  # world centres, by boundary slot
    near = np.zeros(members.shape[0], dtype=np.bool_)
    count = _near_voxels(geometry.centroid, offsets, members, bodies, cell, rest, world, near)
    if count == 0:
        return 0
    slot = np.empty(count, dtype=np.int64)
    ijk = np.empty((count, 3), dtype=np.int64)
    keys = np.empty(count, dtype=np.int64)
    n = 0
    for k in range(members.shape[0]):
        if near[k]:
            slot[n] = k
            for a in range(3):
                ijk[n, a] = cell_of(world[k, a], cell)
            keys[n] = cell_key(ijk[n, 0], ijk[n, 1], ijk[n, 2])
            n += 1
    start, entries = hash_buckets(keys)
    resolved = np.int64(0)  # not a literal 0: the callee would compile twice
    for i in range(n):
        vi = members[slot[i]]
        bi = voxel_body[vi]
        ci = world[slot[i]]
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    key = cell_key(ijk[i, 0] + dx, ijk[i, 1] + dy, ijk[i, 2] + dz)
                    # moving against moving: each pair once (lower voxel first)
                    lo, hi = bucket(key, start)
                    for jj in range(lo, hi):
                        j = entries[jj]
                        if keys[j] != key:
                            continue
                        vj = members[slot[j]]
                        bj = voxel_body[vj]
                        if vj <= vi or bj == bi or not voxel_alive[vi] or not voxel_alive[vj]:
                            continue
                        cj = world[slot[j]]
                        if not _touching(ci, cj, voxel_radius[vi] + voxel_radius[vj]):
                            continue
                        resolved += _resolve_pair(vi, vj, ci, cj, geometry, voxels, bodies,
                                                  contacts, marks, params, resolved)
                    # moving against resting
                    lo, hi = bucket(key, static_start)
                    for jj in range(lo, hi):
                        if static_keys[jj] != key:
                            continue
                        vj = static_vox[jj]
                        bj = voxel_body[vj]
                        if bj == bi or not voxel_alive[vi] or not voxel_alive[vj]:
                            continue
                        cj = static_pos[jj]
                        if not _touching(ci, cj, voxel_radius[vi] + voxel_radius[vj]):
                            continue
                        resolved += _resolve_pair(vi, vj, ci, cj, geometry, voxels, bodies,
                                                  contacts, marks, params, resolved)
    return resolved


@helper
def _touching(ci, cj, reach) -> bool:
    """Do spheres at ci and cj (3,) with radii summing to ``reach`` (m) overlap?"""
    d2 = (cj[0] - ci[0]) ** 2 + (cj[1] - ci[1]) ** 2 + (cj[2] - ci[2]) ** 2
    return d2 < reach * reach


@helper
def _resolve_pair(vi, vj, ci, cj, geometry, voxels, bodies, contacts, marks, params,
                  index) -> int:
    """Resolve the contact of voxel vi at ci (3,) with voxel vj at cj (m), of different
    bodies, if they touch and approach; the ``index``-th contact of the step is recorded
    in contacts.hits. Returns 1 if resolved, else 0 (see :func:`collide_bodies`)."""
    bi, bj = voxels.body[vi], voxels.body[vj]
    voxel_radius, voxel_restitution = geometry.contact_radius, geometry.restitution
    voxel_density, voxel_yield, voxel_alive = geometry.density, voxels.yield_pa, voxels.alive
    body_inv_inertia, body_rot, body_ang = bodies.inv_inertia, bodies.rot, bodies.ang
    body_pos, body_lin, body_mass = bodies.pos, bodies.lin, bodies.mass
    body_fixed, body_asleep = bodies.fixed, bodies.asleep
    wake_speed, rest_speed, friction = params.wake_speed, params.rest_speed, params.friction
    weakening, up = params.weakening, params.up
    destroyed, dirty = marks.destroyed, marks.dirty
    resting, supported, supported_next = (contacts.resting, contacts.supported,
                                          contacts.supported_next)
    hits_out = contacts.hits
    dx, dy, dz = cj[0] - ci[0], cj[1] - ci[1], cj[2] - ci[2]
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    reach = voxel_radius[vi] + voxel_radius[vj]
    if dist >= reach or dist <= 0.0:
        return 0
    nx, ny, nz = dx / dist, dy / dist, dz / dist
    px, py, pz = 0.5 * (ci[0] + cj[0]), 0.5 * (ci[1] + cj[1]), 0.5 * (ci[2] + cj[2])
    wi = angular_velocity(body_rot[bi], body_inv_inertia[bi], body_ang[bi])
    wj = angular_velocity(body_rot[bj], body_inv_inertia[bj], body_ang[bj])
    va = point_velocity(bi, px, py, pz, body_pos, body_lin, body_mass, wi)
    vb = point_velocity(bj, px, py, pz, body_pos, body_lin, body_mass, wj)
    vn = (vb[0] - va[0]) * nx + (vb[1] - va[1]) * ny + (vb[2] - va[2]) * nz
    if vn >= 0.0:
        return 0
    gentle = -vn < rest_speed
    if gentle:
        resting[bi] = True
        resting[bj] = True
    # an asleep body hit (not gently touched) wakes; otherwise it counts as
    # immovable. Waking on gentle contacts too had debris creeping at about the
    # sleep speed wake its resting neighbours every step, and they fell asleep
    # again the next, for ever.
    if body_asleep[bi] and not gentle and -vn > wake_speed:
        body_asleep[bi] = False
    if body_asleep[bj] and not gentle and -vn > wake_speed:
        body_asleep[bj] = False
    move_i = not (body_fixed[bi] | body_asleep[bi])
    move_j = not (body_fixed[bj] | body_asleep[bj])
    # shock propagation (Guendelman et al. 2003) for stacks: where one body lies on
    # the other, the lower one, if it was supported (by the ground, a body at rest,
    # or a supported body) last step, holds like the ground: what presses it down,
    # its support takes. Resolving each contact once per step, a column of voxels
    # otherwise passes its weight down one contact per step and sinks into itself
    # for ever. A body on something that holds is supported next step.
    # Only a lower body that is all but still (contact point slower than
    # wake_speed) holds, so the upper one's velocity is matched to nearly zero:
    # that can add no more than m (wake_speed)^2 / 2 to it, and usually removes.
    lift = nx * up[0] + ny * up[1] + nz * up[2]  # > 0: bj is above bi
    if lift > 0.5:
        if supported[bi] and va[0] ** 2 + va[1] ** 2 + va[2] ** 2 < wake_speed ** 2:
            move_i = False
        if not move_i:
            supported_next[bj] = True
    elif lift < -0.5:
        if supported[bj] and vb[0] ** 2 + vb[1] ** 2 + vb[2] ** 2 < wake_speed ** 2:
            move_j = False
        if not move_j:
            supported_next[bi] = True
    k = _pair_inverse_mass(bi, bj, move_i, move_j, px, py, pz, nx, ny, nz, bodies)
    if k <= 0.0:
        return 0
    # a contact slower than a few steps of gravity is resting, not an impact: no
    # bounce (restitution there would keep a pile hopping, as at the ground)
    e = 0.0 if gentle else min(voxel_restitution[vi], voxel_restitution[vj])
    j = -(1.0 + e) * vn / k
    _impulse_pair(bi, bj, j * nx, j * ny, j * nz, px, py, pz, bodies, move_i, move_j)
    # Coulomb friction: remove the sliding velocity at the contact, within mu * j
    wi = angular_velocity(body_rot[bi], body_inv_inertia[bi], body_ang[bi])
    wj = angular_velocity(body_rot[bj], body_inv_inertia[bj], body_ang[bj])
    va = point_velocity(bi, px, py, pz, body_pos, body_lin, body_mass, wi)
    vb = point_velocity(bj, px, py, pz, body_pos, body_lin, body_mass, wj)
    rx, ry, rz = vb[0] - va[0], vb[1] - va[1], vb[2] - va[2]
    rn = rx * nx + ry * ny + rz * nz
    tx, ty, tz = rx - rn * nx, ry - rn * ny, rz - rn * nz
    slide = math.sqrt(tx * tx + ty * ty + tz * tz)
    if slide > 1e-12 and friction > 0.0:
        tx, ty, tz = tx / slide, ty / slide, tz / slide
        k_t = _pair_inverse_mass(bi, bj, move_i, move_j, px, py, pz, tx, ty, tz, bodies)
        jt = min(slide / k_t, friction * j)
        _impulse_pair(bi, bj, -jt * tx, -jt * ty, -jt * tz, px, py, pz, bodies, move_i,
                      move_j)
    _resist_rolling(bi, bj, j * 0.5 * reach, bodies, move_i, move_j)
    for side in range(2):
        v = vi if side == 0 else vj
        b = bi if side == 0 else bj
        pressure = 0.5 * voxel_density[v] * vn * vn
        if pressure > voxel_yield[v]:
            voxel_alive[v] = False
            destroyed[v] = True
            dirty[b] = True
        else:
            voxel_yield[v] = max(0.0, voxel_yield[v] - weakening * pressure)
    if index < hits_out.shape[0]:
        hits_out[index, 0] = px
        hits_out[index, 1] = py
        hits_out[index, 2] = pz
        hits_out[index, 3] = -vn
    return 1


@helper
def _pair_inverse_mass(bi, bj, move_i, move_j, px, py, pz, nx, ny, nz, bodies) -> float:
    """Inverse mass (1/kg) the pair bi, bj shows an impulse along unit (nx, ny, nz) at
    point p: :func:`effective_inverse_mass` summed over the bodies that move here."""
    body_mass, body_rot, body_inv_inertia, body_pos = (bodies.mass, bodies.rot,
                                                       bodies.inv_inertia, bodies.pos)
    k = 0.0
    for side in range(2):
        b = bi if side == 0 else bj
        if not (move_i if side == 0 else move_j):
            continue
        k += effective_inverse_mass(1.0 / body_mass[b], body_rot[b], body_inv_inertia[b],
                                     px - body_pos[b, 0], py - body_pos[b, 1],
                                     pz - body_pos[b, 2], nx, ny, nz)
    return k


@helper
def _resist_rolling(bi, bj, limit, bodies, move_i, move_j) -> None:
    """Rolling resistance: remove the relative spin of bi and bj with an opposite pair of
    angular impulses, up to ``limit`` (N m s).

    The contact spheres stand in for voxels, and a voxel, unlike a sphere, does
    not roll: tipping a cube over an edge takes a couple of about its weight
    times half its edge. With limit = j x (half the contact distance), debris
    on a pile stops rolling instead of creeping down it forever. A couple
    changes no linear momentum and, being equal and opposite, no angular
    momentum either; it only removes relative rotation, so it never adds energy.
    """
    body_rot, body_inv_inertia, body_ang = bodies.rot, bodies.inv_inertia, bodies.ang
    wi = angular_velocity(body_rot[bi], body_inv_inertia[bi], body_ang[bi])
    wj = angular_velocity(body_rot[bj], body_inv_inertia[bj], body_ang[bj])
    sx, sy, sz = wj[0] - wi[0], wj[1] - wi[1], wj[2] - wi[2]
    spin = math.sqrt(sx * sx + sy * sy + sz * sz)
    if spin <= 1e-12 or limit <= 0.0:
        return
    ux, uy, uz = sx / spin, sy / spin, sz / spin
    k = 0.0  # spin change per unit angular impulse along u
    for side in range(2):
        b = bi if side == 0 else bj
        if move_i if side == 0 else move_j:
            ix, iy, iz = world_tensor_times(body_rot[b], body_inv_inertia[b], ux, uy, uz)
            k += ux * ix + uy * iy + uz * iz
    if k <= 0.0:
        return
    jr = min(spin / k, limit)
    if move_i:
        body_ang[bi, 0] += jr * ux
        body_ang[bi, 1] += jr * uy
        body_ang[bi, 2] += jr * uz
    if move_j:
        body_ang[bj, 0] -= jr * ux
        body_ang[bj, 1] -= jr * uy
        body_ang[bj, 2] -= jr * uz


@helper
def _impulse_pair(bi, bj, jx, jy, jz, px, py, pz, bodies, move_i, move_j) -> None:
    """Impulse (jx, jy, jz) (N s) on bj at point p, and its opposite on bi; a body that
    does not move here (fixed, asleep or holding a stack) takes none."""
    if move_i:
        apply_impulse(bi, (-jx, -jy, -jz), (px, py, pz), bodies.pos, bodies.lin, bodies.ang)
    if move_j:
        apply_impulse(bj, (jx, jy, jz), (px, py, pz), bodies.pos, bodies.lin, bodies.ang)


def begin_contacts(state) -> None:
    """Per-step contact bookkeeping: no voxel destroyed or body dirty yet, and last
    step's support flags become this step's, the next ones starting empty."""
    state.marks.destroyed[:] = False
    state.marks.dirty[:state.n_bodies] = False
    c = state.contacts  # swap the two flag arrays (the constructor: _replace is ~10x slower)
    state.contacts = Contacts(c.resting, c.supported_next, c.supported, c.hits, c.points,
                              c.vertex_stamp)
    c.supported[:] = False


def collide_phase(model, state, settings, dt: float) -> int:
    """Phase: contacts between fragments, at velocity level, then resting-contact damping.

    Reads the bodies' poses and momenta and the boundary; writes momenta,
    asleep, voxels' yield and alive (impacts), marks.destroyed and dirty, the
    contact flags and contacts.hits. Returns how many of this step's contacts
    are in contacts.hits (for dust); a caller splits bodies when
    marks.destroyed has any. ``settings``: the run's SimSettings.
    """
    s = settings
    boundary = boundary_of(model, state)
    begin_contacts(state)
    cell = 2.0 * model.max_contact_radius
    params = CollideParams(wake_speed=s.sleep_speed,
                           rest_speed=s.sleep_speed + 2.0 * abs(s.gravity) * dt,
                           friction=s.friction, weakening=s.weakening, cell=cell, up=model.up)
    resolved = collide_bodies(model.voxels, state.voxels, state.bodies, state.contacts,
                              state.marks, params, boundary, _static(model, state, cell),
                              _rest_grid(model, state, cell))
    state.counters.collisions += int(resolved)
    b = state.bodies
    damp_resting(state.contacts.resting, b.mass, b.inv_inertia, b.rot, b.lin, b.ang, b.radius,
                 state.n_bodies, math.exp(-s.rest_damping * dt), 4.0 * s.sleep_speed)
    return min(int(resolved), len(state.contacts.hits))


def _rest_grid(model, state, cell: float) -> tuple:
    """Boundary voxels by body and rest cell, rebuilt when the boundary changes."""
    caches = state.caches
    if caches.rest_version != caches.version:
        caches.rest = rest_grid(model.voxels.centroid, state.voxels.body, caches.boundary[1],
                                cell)
        caches.rest_version = caches.version
    return caches.rest


def _static(model, state, cell: float) -> tuple:
    """The hash of resting bodies' voxels, rebuilt when what rests changes."""
    b, n, caches = state.bodies, state.n_bodies, state.caches
    resting = b.live[:n] & ~b.dust[:n] & (b.fixed[:n] | b.asleep[:n])
    key = (caches.version, resting.tobytes())
    if caches.static_key != key:
        offsets, members = caches.boundary
        caches.static = static_hash(model.voxels, offsets, members, state.bodies, cell)
        caches.static_key = key
    return caches.static
