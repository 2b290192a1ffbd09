"""Fragment collisions (Martins 2001 §5.1), solved with the ground's contacts.

Broad phase: bounding spheres of bodies, then a spatial hash of the boundary
voxels of bodies whose spheres overlap (:func:`static_hash` keeps resting
bodies' voxels). Narrow phase: each voxel is a box (:func:`voxel_boxes`), and
two boxes of different bodies that touch, or may touch within the step
(speculative contacts), make one contact row: the separating axis of least
penetration over the six face normals picks a reference face, the facing face
of the other box is clipped to it (as Bullet's and ODE's box-box tests do),
and the clipped points make a patch: a point at its centre, the separation of
its closest point, and its half extents. The normal impulse at the centre,
with moments about the two tangents bounded by the normal impulse times the
patch's half extents, is exactly what forces at the patch corners can do, so a
box rests on a face, tips over an edge and rolls on a corner. The rows, and
the ground's (:mod:`blastvox.simulate.contact.ground`), are solved together by
:func:`~blastvox.simulate.contact.solver.solve_contacts`: sequential impulses, warm
started, restitution the smaller of the two voxels', Coulomb friction,
penetration removed by moving bodies. Impacts weaken voxels; a voxel whose
strength runs out turns to dust.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from blastvox.jit import helper, kernel
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.contact.ground import (
    SLOP,
    ground_rows,
    grow_rows,
    new_memory,
    pick_four,
    rest_speed,
    settle_on_ground,
    solver_params,
)
from blastvox.simulate.contact.pairs import (
    bucket,
    cell_key,
    cell_of,
    hash_buckets,
    near_voxels,
    rest_grid,
    static_hash,
)
from blastvox.simulate.contact.solver import solve_contacts
from blastvox.simulate.integrate import angular_velocity
from blastvox.simulate.limits import voxel_size
from blastvox.simulate.state import Contacts


class CollideParams(NamedTuple):
    """dt: step, s; wake_speed: m/s of approach that wakes a sleeping body (the sleep
    speed); rest_speed: m/s below which a contact is resting, not an impact;
    weakening: fraction of an impact's pressure taken off a voxel's yield; cell: hash
    cell, m (twice the largest box half diagonal, plus reach); reach: m, the most a
    contact looks ahead (half the largest voxel); slop: m, the solver's
    (:func:`~blastvox.simulate.contact.ground.solver_params`)."""

    dt: float
    wake_speed: float
    rest_speed: float
    weakening: float
    cell: float
    reach: float
    slop: float


@kernel
def voxel_boxes(vertices, corners, contact_radius):
    """Contact boxes (half extents (N, 3) m, half diagonals (N,) m) of the voxels.

    A voxel's box is its corners' bounding box in the rest frame, scaled about the
    centroid to the voxel's volume ((2 contact_radius)^3, m^3): the voxel itself
    for a lattice cell, a box of the same volume and proportions for a jittered
    or conform one (whose corners span more than its solid).
    """
    n = corners.shape[0]
    half = np.empty((n, 3))
    radius = np.empty(n)
    for v in range(n):
        for a in range(3):
            lo = vertices[corners[v, 0], a]
            hi = lo
            for c in range(1, 8):
                x = vertices[corners[v, c], a]
                lo = min(lo, x)
                hi = max(hi, x)
            half[v, a] = 0.5 * (hi - lo)
        box = 8.0 * half[v, 0] * half[v, 1] * half[v, 2]
        volume = (2.0 * contact_radius[v]) ** 3
        if box > 0.0 and volume < box * (1.0 - 1e-9):
            scale = (volume / box) ** (1.0 / 3.0)
            for a in range(3):
                half[v, a] *= scale
        radius[v] = math.sqrt(half[v, 0] ** 2 + half[v, 1] ** 2 + half[v, 2] ** 2)
    return half, radius


@kernel
def collide_bodies(geometry, voxels, bodies, params, boundary, static, rest, memory) -> int:
    """Contact rows (memory.rows, from row 0) of voxel boxes of different bodies, once each.

    boundary: (offsets, members) each body's boundary voxels; params:
    :class:`CollideParams`; static: :func:`static_hash`; rest: :func:`rest_grid`.
    The boundary voxels of moving bodies that may touch something
    (:func:`~blastvox.simulate.contact.pairs.near_voxels`) go into a spatial hash
    each step; voxels of bodies at rest (fixed or asleep) come from ``static``,
    so a big standing structure costs nothing per step. Pairs whose bounding
    spheres (memory.radius) may touch within the step (:func:`_lookahead`) go to the
    box test
    (:func:`_box_contact`), in hash order (deterministic). Returns the number of
    rows; rows past the capacity are counted, not written (grow and call again). When
    they fit, the sleeping bodies they strike wake (:func:`_wake_struck`).
    """
    offsets, members = boundary
    static_vox, static_pos, static_keys, static_start = static
    voxel_alive, voxel_body = voxels.alive, voxels.body
    radius, cell, reach = memory.radius, params.cell, params.reach
    world = np.empty((members.shape[0], 3))  # world centres, by boundary slot
    near = np.zeros(members.shape[0], dtype=np.bool_)
    count = near_voxels(geometry.centroid, offsets, members, bodies, cell, rest, world, near)
    if count == 0:
        return 0
    slot = np.empty(count, dtype=np.int64)
    ijk = np.empty((count, 3), dtype=np.int64)
    keys = np.empty(count, dtype=np.int64)
    motion = np.empty((count, 4))  # body velocity (m/s), then spin x reach of the box (m/s)
    n = 0
    for k in range(members.shape[0]):
        if near[k]:
            slot[n] = k
            for a in range(3):
                ijk[n, a] = cell_of(world[k, a], cell)
            keys[n] = cell_key(ijk[n, 0], ijk[n, 1], ijk[n, 2])
            _motion(members[k], voxel_body[members[k]], world[k], bodies, radius, motion[n])
            n += 1
    start, entries = hash_buckets(keys)
    centres = np.empty((2, 3))
    still = np.zeros(4)
    work = (np.empty((3, 3)), np.empty((3, 8, 3)), np.empty(32))
    pair = np.empty(8, dtype=np.int64)  # bodies and voxels, then picks
    found = np.int64(0)  # not a literal 0: the callee would compile twice
    for i in range(n):
        vi = members[slot[i]]
        bi = voxel_body[vi]
        if not voxel_alive[vi]:
            continue
        for a in range(3):
            centres[0, a] = world[slot[i], a]
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    key = cell_key(ijk[i, 0] + dx, ijk[i, 1] + dy, ijk[i, 2] + dz)
                    # moving against moving, each pair once: from the cell of either,
                    # the other in one of the 13 cells that follow it, or in the same
                    # cell, the lower voxel first
                    forward = (dx, dy, dz) > (0, 0, 0)
                    lo, hi = bucket(key, start)
                    for jj in range(lo if forward or (dx, dy, dz) == (0, 0, 0) else hi, hi):
                        j = entries[jj]
                        if keys[j] != key:
                            continue
                        vj = members[slot[j]]
                        bj = voxel_body[vj]
                        if (not forward and vj <= vi) or bj == bi or not voxel_alive[vj]:
                            continue
                        ahead = _lookahead(motion[i], motion[j], reach, params.dt)
                        if not _touching(centres[0], world[slot[j]],
                                         radius[vi] + radius[vj] + ahead):
                            continue
                        for a in range(3):
                            centres[1, a] = world[slot[j], a]
                        pair[0], pair[1], pair[2], pair[3] = bi, vi, bj, vj
                        if _box_contact(bodies.rot, memory.half, pair, centres, ahead, work):
                            _emit(found, vi, vj, bi, bj, work[2], geometry.restitution,
                                  memory.rows)
                            found += 1
                    # moving against resting
                    if static_vox.shape[0] == 0:
                        continue
                    lo, hi = bucket(key, static_start)
                    for jj in range(lo, hi):
                        if static_keys[jj] != key:
                            continue
                        vj = static_vox[jj]
                        bj = voxel_body[vj]
                        if bj == bi or not voxel_alive[vj]:
                            continue
                        ahead = _lookahead(motion[i], still, reach, params.dt)
                        if not _touching(centres[0], static_pos[jj],
                                         radius[vi] + radius[vj] + ahead):
                            continue
                        for a in range(3):
                            centres[1, a] = static_pos[jj, a]
                        pair[0], pair[1], pair[2], pair[3] = bi, vi, bj, vj
                        if _box_contact(bodies.rot, memory.half, pair, centres, ahead, work):
                            _emit(found, vi, vj, bi, bj, work[2], geometry.restitution,
                                  memory.rows)
                            found += 1
    if found <= memory.rows.key.shape[0]:
        _wake_struck(memory.rows, found, bodies, params)
    return found


@helper
def _touching(ci, cj, reach) -> bool:
    """Are ci and cj (3,) closer than ``reach`` (m)?"""
    d2 = (cj[0] - ci[0]) ** 2 + (cj[1] - ci[1]) ** 2 + (cj[2] - ci[2]) ** 2
    return d2 < reach * reach


@helper
def _motion(v, b, centre, bodies, radius, out) -> None:
    """out (4,): the velocity (m/s) of moving body b, and its spin (rad/s) times the
    reach of voxel v's box (centre (3,) m, half diagonal radius[v]) from b's centre."""
    m = bodies.mass[b]
    for a in range(3):
        out[a] = bodies.lin[b, a] / m
    w = angular_velocity(bodies.rot[b], bodies.inv_inertia[b], bodies.ang[b])
    arm = math.sqrt((centre[0] - bodies.pos[b, 0]) ** 2 + (centre[1] - bodies.pos[b, 1]) ** 2
                    + (centre[2] - bodies.pos[b, 2]) ** 2) + radius[v]
    out[3] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * arm


@helper
def _lookahead(a, b, reach, dt) -> float:
    """How close (m) two boxes whose :func:`_motion` are a and b (4,) may come within a
    step of dt s: their relative speed bound times dt, at most ``reach`` (m)."""
    speed = math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)
    return min(reach, (speed + a[3] + b[3]) * dt)


@helper
def _emit(r, vi, vj, bi, bj, patch, restitution, rows) -> None:
    """Write the contact :func:`_box_contact` left in patch as row r of rows (unless r is
    past the capacity): bodies bi, bj, voxels vi, vj, the smaller restitution."""
    if r >= rows.key.shape[0]:
        return
    flip = 1.0 if patch[15] > 0.0 else -1.0  # the normal from a to b
    for a in range(3):
        rows.point[r, a] = patch[a]
        rows.frame[r, 0, a] = flip * patch[3 + a]
        rows.frame[r, 1, a] = patch[6 + a]
        rows.frame[r, 2, a] = patch[9 + a]
        for i in range(4):
            rows.corners[r, i, a] = patch[16 + 3 * i + a]
    for i in range(4):
        rows.corner_gap[r, i] = patch[28 + i]
    rows.gap[r], rows.arm[r], rows.used[r] = patch[12], patch[13], int(patch[14])
    rows.body[r, 0], rows.body[r, 1] = bi, bj
    rows.voxel[r, 0], rows.voxel[r, 1] = vi, vj
    rows.key[r] = min(vi, vj) * restitution.shape[0] + max(vi, vj)
    rows.restitution[r] = min(restitution[vi], restitution[vj])


@helper
def _box_contact(rot, half, pair, centres, ahead, work) -> bool:
    """Do the boxes of voxels pair[1] (of body pair[0], centre centres[0], m) and pair[3]
    (body pair[2], centres[1]) touch, or come within ``ahead`` (m)? rot (B, 3, 3): the
    bodies' rotations; half (N, 3): the boxes' half extents (m) along their rest axes.
    If so the patch is in work[2] (:func:`_manifold`; [15] > 0: on box a's face). work:
    scratch (3, 3), (3, 8, 3), (32,). Separating axes: the six face normals; the
    edge-edge axes are left out (a pair they would separate gets a contact a little
    early)."""
    cross, poly, patch = work
    ba, va, bb, vb = pair[0], pair[1], pair[2], pair[3]
    dx, dy, dz = (centres[1, 0] - centres[0, 0], centres[1, 1] - centres[0, 1],
                  centres[1, 2] - centres[0, 2])
    for k in range(3):
        for m in range(3):
            cross[k, m] = (rot[ba, 0, k] * rot[bb, 0, m] + rot[ba, 1, k] * rot[bb, 1, m]
                           + rot[ba, 2, k] * rot[bb, 2, m])
    sa, ka, sb, kb = -np.inf, 0, -np.inf, 0
    for k in range(3):
        s = (abs(dx * rot[ba, 0, k] + dy * rot[ba, 1, k] + dz * rot[ba, 2, k]) - half[va, k]
             - half[vb, 0] * abs(cross[k, 0]) - half[vb, 1] * abs(cross[k, 1])
             - half[vb, 2] * abs(cross[k, 2]))
        if s > sa:
            sa, ka = s, k
        s = (abs(dx * rot[bb, 0, k] + dy * rot[bb, 1, k] + dz * rot[bb, 2, k]) - half[vb, k]
             - half[va, 0] * abs(cross[0, k]) - half[va, 1] * abs(cross[1, k])
             - half[va, 2] * abs(cross[2, k]))
        if s > sb:
            sb, kb = s, k
    slop = 1e-3 * min(half[va, 0], half[va, 1], half[va, 2], half[vb, 0], half[vb, 1],
                      half[vb, 2])
    ahead += slop
    if max(sa, sb) > ahead:
        return False
    on_a = not sb > sa + slop  # a's face unless b's separates clearly more: stable
    kept = _manifold(rot, half, pair, centres, 0 if on_a else 1, ka if on_a else kb, poly,
                     ahead, patch, pair[4:])
    patch[15] = 1.0 if on_a else -1.0
    return kept > 0


@helper
def _manifold(rot, half, pair, centres, ref, k, poly, ahead, patch, picks) -> int:
    """Clip the face of the other box (``ref`` 0: box a is the reference, 1: b; see
    :func:`_box_contact`) that faces the reference box's face across its axis k to that
    face; keep the points within ``ahead`` (m) of it, or a quarter of the face's smaller
    half extent, four at most (the deepest, the
    farthest from it, and the farthest on either side of the line through both). patch
    (32,) receives: their centre (3, m), the reference normal towards the other box (3),
    the reference face's axes t1 (3) and t2 (3), the smallest separation (m), the
    lever of twisting friction (m, 0.54 times the points' mean distance from their
    centre: 0.765 h, the mean lever of a square of half side h, from its corners),
    how many points, [16:28] the points (m, midway between the faces), [28:32] their
    separations (m). Returns how many points were kept (0: no contact)."""
    br, vr, bi, vi = pair[2 * ref], pair[2 * ref + 1], pair[2 - 2 * ref], pair[3 - 2 * ref]
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    t1x, t1y, t1z = rot[br, 0, k1], rot[br, 1, k1], rot[br, 2, k1]
    t2x, t2y, t2z = rot[br, 0, k2], rot[br, 1, k2], rot[br, 2, k2]
    nx, ny, nz = rot[br, 0, k], rot[br, 1, k], rot[br, 2, k]
    dx, dy, dz = (centres[1 - ref, 0] - centres[ref, 0], centres[1 - ref, 1] - centres[ref, 1],
                  centres[1 - ref, 2] - centres[ref, 2])
    if dx * nx + dy * ny + dz * nz < 0.0:
        nx, ny, nz = -nx, -ny, -nz
    m, best = 0, -1.0
    for c in range(3):
        dot = abs(nx * rot[bi, 0, c] + ny * rot[bi, 1, c] + nz * rot[bi, 2, c])
        if dot > best:
            m, best = c, dot
    m1, m2 = (m + 1) % 3, (m + 2) % 3
    # the incident face's normal opposes the reference's
    side = -half[vi, m] if nx * rot[bi, 0, m] + ny * rot[bi, 1, m] + nz * rot[bi, 2, m] > 0.0 \
        else half[vi, m]
    # incident face centre and half edges, in (t1, t2, n) coordinates of the reference face
    fx = dx + side * rot[bi, 0, m] - half[vr, k] * nx
    fy = dy + side * rot[bi, 1, m] - half[vr, k] * ny
    fz = dz + side * rot[bi, 2, m] - half[vr, k] * nz
    ex, ey, ez = half[vi, m1] * rot[bi, 0, m1], half[vi, m1] * rot[bi, 1, m1], \
        half[vi, m1] * rot[bi, 2, m1]
    gx, gy, gz = half[vi, m2] * rot[bi, 0, m2], half[vi, m2] * rot[bi, 1, m2], \
        half[vi, m2] * rot[bi, 2, m2]
    for a in range(3):
        ux, uy, uz = (t1x, t1y, t1z) if a == 0 else ((t2x, t2y, t2z) if a == 1 else (nx, ny, nz))
        base = fx * ux + fy * uy + fz * uz
        e1 = ex * ux + ey * uy + ez * uz
        e2 = gx * ux + gy * uy + gz * uz
        poly[0, 0, a] = base + e1 + e2
        poly[0, 1, a] = base - e1 + e2
        poly[0, 2, a] = base - e1 - e2
        poly[0, 3, a] = base + e1 - e2
    h1, h2 = half[vr, k1], half[vr, k2]
    n = 4
    inside = True
    for i in range(4):
        inside &= abs(poly[0, i, 0]) <= h1 and abs(poly[0, i, 1]) <= h2
    if not inside:
        n = _clip(poly, 0, n, 0, 1.0, h1, 1)
        n = _clip(poly, 1, n, 0, -1.0, h1, 0)
        n = _clip(poly, 0, n, 1, 1.0, h2, 1)
        n = _clip(poly, 1, n, 1, -1.0, h2, 0)
    kept = 0
    keep = max(ahead, 0.25 * min(h1, h2))  # near points too: a turn the solve starts
    for i in range(n):                     # may swing them down within the step
        if poly[0, i, 2] <= keep:
            for a in range(3):
                poly[2, kept, a] = poly[0, i, a]
            kept += 1
    if kept == 0:
        return 0
    used = pick_four(poly[2], kept, picks)
    hk = half[vr, k]
    c1 = c2 = cs = 0.0
    gap = np.inf
    for i in range(used):
        p1, p2, s = poly[2, picks[i], 0], poly[2, picks[i], 1], poly[2, picks[i], 2]
        c1, c2, cs, gap = c1 + p1 / used, c2 + p2 / used, cs + s / used, min(gap, s)
        patch[16 + 3 * i] = centres[ref, 0] + (hk + 0.5 * s) * nx + p1 * t1x + p2 * t2x
        patch[17 + 3 * i] = centres[ref, 1] + (hk + 0.5 * s) * ny + p1 * t1y + p2 * t2y
        patch[18 + 3 * i] = centres[ref, 2] + (hk + 0.5 * s) * nz + p1 * t1z + p2 * t2z
        patch[28 + i] = s
    spread = 0.0
    for i in range(used):
        spread += math.sqrt((poly[2, picks[i], 0] - c1) ** 2
                            + (poly[2, picks[i], 1] - c2) ** 2) / used
    patch[0] = centres[ref, 0] + (hk + 0.5 * cs) * nx + c1 * t1x + c2 * t2x
    patch[1] = centres[ref, 1] + (hk + 0.5 * cs) * ny + c1 * t1y + c2 * t2y
    patch[2] = centres[ref, 2] + (hk + 0.5 * cs) * nz + c1 * t1z + c2 * t2z
    patch[3], patch[4], patch[5] = nx, ny, nz
    patch[6], patch[7], patch[8] = t1x, t1y, t1z
    patch[9], patch[10], patch[11] = t2x, t2y, t2z
    patch[12], patch[13], patch[14] = gap, 0.54 * spread, used
    return used


@helper
def _clip(poly, src, n, axis, sign, limit, dst) -> int:
    """Sutherland-Hodgman: the convex polygon poly[src, :n] (rows (t1, t2, depth)) cut to
    sign * coordinate ``axis`` <= limit, into poly[dst]; returns its vertex count."""
    out = 0
    di = sign * poly[src, 0, axis] - limit
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        dj = sign * poly[src, j, axis] - limit
        if di <= 0.0:
            poly[dst, out, 0], poly[dst, out, 1] = poly[src, i, 0], poly[src, i, 1]
            poly[dst, out, 2] = poly[src, i, 2]
            out += 1
        if (di <= 0.0) != (dj <= 0.0):
            t = di / (di - dj)
            for a in range(3):
                poly[dst, out, a] = poly[src, i, a] + t * (poly[src, j, a] - poly[src, i, a])
            out += 1
        di = dj
    return out


@helper
def _wake_struck(rows, count, bodies, params) -> None:
    """Wake the sleeping bodies that the first ``count`` rows strike: approach faster
    than params.rest_speed (m/s), closing the gap (but params.slop) within the step,
    as the solver's bounces (:func:`~blastvox.simulate.contact.solver.solve_contacts`). A gentle
    touch does
    not wake (debris creeping at about the sleep speed woke its resting neighbours every
    step, and they fell asleep again the next, for ever); an asleep body is immovable."""
    for r in range(count):
        a, b = rows.body[r, 0], rows.body[r, 1]
        if not (bodies.asleep[a] or bodies.asleep[b]):
            continue
        vn = 0.0
        for side in range(2):
            o = a if side == 0 else b
            w = angular_velocity(bodies.rot[o], bodies.inv_inertia[o], bodies.ang[o])
            rx = rows.point[r, 0] - bodies.pos[o, 0]
            ry = rows.point[r, 1] - bodies.pos[o, 1]
            rz = rows.point[r, 2] - bodies.pos[o, 2]
            m = bodies.mass[o]
            u = (rows.frame[r, 0, 0] * (bodies.lin[o, 0] / m + w[1] * rz - w[2] * ry)
                 + rows.frame[r, 0, 1] * (bodies.lin[o, 1] / m + w[2] * rx - w[0] * rz)
                 + rows.frame[r, 0, 2] * (bodies.lin[o, 2] / m + w[0] * ry - w[1] * rx))
            vn += u if side == 1 else -u
        if -vn > params.rest_speed and vn * params.dt < params.slop - rows.gap[r]:
            bodies.asleep[a] = False
            bodies.asleep[b] = False


#: Voxels closer than this fraction of the smaller one's edge at a step's start touch:
#: a contact between them pushes and never strikes (the solver's slop; a lattice's
#: shared face is at 0, a gap closing within a step is far wider).
TOUCHING = 1e-3


@helper
def _edge(half, va, vb) -> float:
    """The smaller edge (m) of voxels va's and vb's contact boxes (half (N, 3) m)."""
    return 2.0 * min(half[va, 0], half[va, 1], half[va, 2], half[vb, 0], half[vb, 1],
                     half[vb, 2])


@helper
def _touching_gap(half, va, vb) -> float:
    """Gap (m) below which voxels va and vb touch (:data:`TOUCHING`)."""
    return TOUCHING * _edge(half, va, vb)


@kernel
def contact_effects(rows, count, density, voxels, marks, resting, hits, params, half,
                    crush) -> int:
    """What the step's solved fragment contacts (the first ``count`` rows) did: a
    contact that pushed and approached slower than params.rest_speed is resting and
    flags both bodies in ``resting`` (for :func:`damp_resting`); one that struck
    weakens both voxels by params.weakening x the impact pressure rho v_n^2 / 2 (Pa;
    rho the voxel's density in kg/m^3, v_n the approach speed): a stone voxel shrugs
    off 5 m/s (33 kPa) and turns to dust at 20 m/s (520 kPa, above its yield). A
    contact strikes if its voxels were apart at the step's start (by more than
    :data:`TOUCHING` x the smaller voxel's edge; half (N, 3) m: the voxels' contact box
    half extents); voxels touching already push: a wall's layers,
    freed by the wave and pressed together by it, do not strike each other (their
    approach, the wave's push over one step, p dt / (rho L), is dt's, not an
    impact's). A voxel whose yield the pressure exceeds, and its ``crush`` (N,) Pa
    (a voxel that is the material's rubble already is pulverized only by a crushing
    impact, whatever the blast left of its yield), is marked in marks.destroyed (its
    body in marks.dirty). hits (H, 4) receives the points and
    approach speeds (m/s, for dust). Returns how many rows struck. rows:
    :class:`~blastvox.simulate.contact.ground.ContactRows`; density (N,): voxels' kg/m^3;
    resting: contacts.resting (B,)."""
    voxel_density, voxel_yield, voxel_alive = density, voxels.yield_pa, voxels.alive
    resolved = 0
    for r in range(count):
        vn = rows.approach[r]
        if rows.impulse[r] <= 0.0:
            continue
        if -vn < params.rest_speed:
            resting[rows.body[r, 0]] = True
            resting[rows.body[r, 1]] = True
        if vn >= 0.0 or rows.gap[r] <= _touching_gap(half, rows.voxel[r, 0],
                                                               rows.voxel[r, 1]):
            continue
        for side in range(2):
            v = rows.voxel[r, side]
            pressure = 0.5 * voxel_density[v] * vn * vn
            if pressure > voxel_yield[v] and pressure > crush[v]:
                voxel_alive[v] = False
                marks.destroyed[v] = True
                marks.dirty[rows.body[r, side]] = True
            else:
                voxel_yield[v] = max(0.0, voxel_yield[v] - params.weakening * pressure)
        if resolved < hits.shape[0]:
            for a in range(3):
                hits[resolved, a] = rows.point[r, a]
            hits[resolved, 3] = -vn
        resolved += 1
    return resolved


#: How far (a fraction of the smaller voxel's edge) a piece may pass into the loaded
#: member it broke off before their contact holds again: if the member has not let go
#: by then, it stands and stops the piece. A founded brick wall's debris at dt 1/10,000 s
#: (the wave frees it over about 1.5 ms) is within 3 % of dt 1/4000 s's at 0.005, and a
#: standing wall's pressed pieces pass under 1 % of a voxel into it.
MEMBER_DEPTH = 0.005


@kernel
def mute_member_rows(rows, count, bodies, voxels, held_p, since, holds, half, depth) -> None:
    """While a wave passes, a piece that broke off in it does not collide with a fixed
    body that the wave is loading (one whose voxels hold its impulse, loads.held_p
    (N, 3) N s): they are parts of one member, which the wave moves together though
    its foundation still holds the rest (a wall bends out before its supports give
    way, and the part still held leaves with the impulse it took when its links
    fail: :func:`~blastvox.simulate.kernels.release_held`). Their rows get no corners
    (rows.used = 0: no normal impulse, so no friction) until the piece is ``depth``
    of the smaller voxel's edge into the member. Two pieces that both broke off in the
    current waves touch without friction (rows.grip = 0): the wave gave the parts of
    one member different speeds and spins, and their friction locked a wall's pieces
    against those caught at a house's corners. Against an immovable body, a
    wall's first pieces to break free, pressed by the wave against the part still
    founded, gave their momentum to the ground, more the finer the step (a founded
    brick wall's debris: 9,030 N s at dt 1/240 s, 2,388 at 1/10,000). Once the waves
    have passed, contacts hold again and the soft push-out separates what overlaps.
    since: the step the current waves began loading; holds (B,) bool: work."""
    body = voxels.body
    holds[:] = False
    for v in range(body.shape[0]):
        if held_p[v, 0] != 0.0 or held_p[v, 1] != 0.0 or held_p[v, 2] != 0.0:
            holds[body[v]] = True
    for r in range(count):
        a, b = rows.body[r, 0], rows.body[r, 1]
        if a < 0 or b < 0:
            continue
        if bodies.fixed[a] == bodies.fixed[b]:
            if not bodies.fixed[a] and bodies.born[a] >= since and bodies.born[b] >= since:
                rows.grip[r] = 0.0
            continue
        fixed, free = (a, b) if bodies.fixed[a] else (b, a)
        if holds[fixed] and bodies.born[free] >= since and \
                rows.gap[r] > -depth * _edge(half, rows.voxel[r, 0], rows.voxel[r, 1]):
            rows.used[r] = 0


@kernel
def damp_resting(resting, body_mass, body_inv_inertia, body_rot, body_lin, body_ang,
                 body_radius, n_bodies, decay, limit) -> None:
    """Resting-contact damping between fragments (as the ground's, Martins 2001 §5.2).

    Bodies flagged in ``resting`` (B,) (a gentle contact this step) that move
    slower than ``limit`` (m/s, centre speed and rim speed) lose the fraction
    1 - ``decay`` of their momenta; the flags are cleared. Only ever removes
    energy, and lets piles settle and sleep instead of jittering. Called every
    step with contacts: it takes the arrays it reads (see :func:`body_rotations`).
    """
    for b in range(n_bodies):
        if not resting[b]:
            continue
        resting[b] = False
        speed = math.sqrt(body_lin[b, 0] ** 2 + body_lin[b, 1] ** 2 + body_lin[b, 2] ** 2) \
            / body_mass[b]
        wx, wy, wz = angular_velocity(body_rot[b], body_inv_inertia[b], body_ang[b])
        spin = math.sqrt(wx * wx + wy * wy + wz * wz) * body_radius[b]
        if speed > limit or spin > limit:
            continue
        for a in range(3):
            body_lin[b, a] *= decay
            body_ang[b, a] *= decay


def begin_contacts(state) -> None:
    """Per-step contact bookkeeping: no voxel destroyed or body dirty yet, and last
    step's support flags become this step's, the next ones starting empty."""
    state.marks.destroyed[:] = False
    state.marks.dirty[:state.n_bodies] = False
    c = state.contacts  # swap the two flag arrays (the constructor: _replace is ~10x slower)
    state.contacts = Contacts(c.resting, c.supported_next, c.supported, c.hits, c.points,
                              c.vertex_stamp, c.memory)
    c.supported[:] = False


def collide_phase(model, state, settings, dt: float) -> int:
    """Phase: contacts between fragments and, with a ground, with the ground, solved
    together at velocity level; then resting-contact damping.

    Reads the bodies' poses and momenta and the boundary; writes momenta, poses
    (where bodies interpenetrate), asleep, voxels' yield and alive (impacts),
    marks.destroyed and dirty, the contact flags, memory and hits. Returns how
    many of this step's contacts are in contacts.hits (for dust); a caller splits
    bodies when marks.destroyed has any. ``settings``: the run's SimSettings. The
    ground phase then has nothing left to do
    (:func:`~blastvox.simulate.contact.ground.ground_phase`).
    """
    s = settings
    boundary = boundary_of(model, state)
    begin_contacts(state)
    memory = state.contacts.memory
    if memory is None:
        v = model.voxels
        memory = new_memory(state, voxel_size(v.contact_radius),
                            *voxel_boxes(v.vertices, v.corners, v.contact_radius))
    reach = model.max_contact_radius  # half the largest voxel: the motion limit
    params = CollideParams(dt=dt, wake_speed=s.sleep_speed,
                           rest_speed=rest_speed(s, dt),
                           weakening=s.weakening,
                           cell=2.0 * float(memory.radius.max(initial=0.0)) + reach,
                           reach=reach, slop=SLOP * memory.size)
    static, rest = _static(model, state, params.cell), _rest_grid(model, state, params.cell)
    count = collide_bodies(model.voxels, state.voxels, state.bodies, params, boundary, static,
                           rest, memory)
    if count > len(memory.rows.key):
        memory = grow_rows(state, count, 0)
        collide_bodies(model.voxels, state.voxels, state.bodies, params, boundary, static, rest,
                       memory)
    ground = model.ground_height if s.ground else None
    end = count if ground is None else ground_rows(model, state, s, dt, ground, count)
    memory = state.contacts.memory
    if state.holding:  # a wave is passing: a member's parts move together
        mute_member_rows(memory.rows, count, state.bodies, state.voxels, state.loads.held_p,
                         state.hold_since, _holds(state), memory.half, MEMBER_DEPTH)
    solve_contacts(state.bodies, memory, end, solver_params(memory, s, dt, model.up),
                   state.loads)
    memory.rows.grip[:count] = 1.0
    state.caches.fragment_rows = (int(count), int(end))
    c = state.contacts
    resolved = contact_effects(memory.rows, count, model.voxels.density, state.voxels,
                               state.marks, c.resting, c.hits, params, memory.half,
                               model.strength.shatter_pa)
    if ground is not None:
        settle_on_ground(model, state, s, dt, count, end)
    state.counters.collisions += int(resolved)
    b = state.bodies
    # without gravity nothing rests on anything: no pile to settle, momentum is conserved
    decay = math.exp(-s.rest_damping * dt) if s.gravity > 0.0 else 1.0
    damp_resting(state.contacts.resting, b.mass, b.inv_inertia, b.rot, b.lin, b.ang, b.radius,
                 state.n_bodies, decay, 4.0 * s.sleep_speed)
    return min(int(resolved), len(state.contacts.hits))


def _holds(state) -> np.ndarray:
    """Work array (B,) of :func:`mute_member_rows`, kept in state.caches."""
    caches = state.caches
    if caches.holds is None:
        caches.holds = np.zeros(len(state.bodies.mass), dtype=bool)
    return caches.holds


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
