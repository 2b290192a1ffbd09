"""Contacts: the ground plane (Martins 2001 §5.2) and fragment collisions (§5.1).

Both act at velocity level between the velocity and position halves of the
step, and never add energy: an impulse only removes approach velocity, or
reflects it with a restitution coefficient e <= 1.

Ground: an infinite-mass plane at the scene's ground height. Contact points are
the corners of a body's boundary voxels that are at or below the plane, or
would reach it this step (speculative contacts, so fast debris cannot tunnel
and resting bodies do not sink, without pushing positions around). Normal and
tangential impulses are solved together by a few projected Gauss-Seidel
sweeps; the tangential part is Coulomb friction, the "pseudo-friction" of the
paper: it opposes the tangential velocity and grows with the body's mass and
speed up to mu times the normal impulse. A body in resting contact loses a
part of its momenta (damping); with three or more contact points, small
velocities and its centre of mass over the *exact convex hull* of its contact
points (the paper used their bounding rectangle to save time), it is clamped
to rest and sleeps until something wakes it.

Fragments: bounding spheres of bodies (broad phase), then a spatial hash of
the boundary voxels of bodies whose spheres overlap, then voxel spheres of
radius (volume)^(1/3) / 2. Each touching, approaching voxel pair is resolved
once per step with an impulse along the centre line at its midpoint, with the
smaller restitution of the two voxels. Impacts weaken voxels; a voxel whose
strength runs out turns to dust.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from blastvox.jit import helper
from blastvox.simulate.integrate import angular_velocity, moving, world_tensor_times
from blastvox.simulate.shell import to_rest

_FACE_CORNERS = np.array(
    [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]],
    dtype=np.int64)


@nb.njit(cache=True)
def boundary_lists(voxel_body, voxel_alive, voxel_link_mask, conform_slot, n_bodies):
    """CSR (offsets (B+1,), voxels) of each body's alive boundary voxels, in voxel order."""
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


@helper
def _point_velocity(b, px, py, pz, body_pos, body_lin, body_mass, omega):
    rx, ry, rz = px - body_pos[b, 0], py - body_pos[b, 1], pz - body_pos[b, 2]
    m = body_mass[b]
    return (body_lin[b, 0] / m + omega[1] * rz - omega[2] * ry,
            body_lin[b, 1] / m + omega[2] * rx - omega[0] * rz,
            body_lin[b, 2] / m + omega[0] * ry - omega[1] * rx)


@helper
def _effective_inverse_mass(inv_mass, rot, inv, rx, ry, rz, nx, ny, nz):
    """1/m + n . ((I^-1 (r x n)) x r): inverse mass seen by an impulse along n at r."""
    cx, cy, cz = ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx
    ix, iy, iz = world_tensor_times(rot, inv, cx, cy, cz)
    tx, ty, tz = iy * rz - iz * ry, iz * rx - ix * rz, ix * ry - iy * rx
    return inv_mass + nx * tx + ny * ty + nz * tz


@helper
def _apply(b, jx, jy, jz, px, py, pz, body_pos, body_lin, body_ang):
    body_lin[b, 0] += jx
    body_lin[b, 1] += jy
    body_lin[b, 2] += jz
    rx, ry, rz = px - body_pos[b, 0], py - body_pos[b, 1], pz - body_pos[b, 2]
    body_ang[b, 0] += ry * jz - rz * jy
    body_ang[b, 1] += rz * jx - rx * jz
    body_ang[b, 2] += rx * jy - ry * jx


@nb.njit(cache=True)  # also called from Python, by balanced()
def _hull_contains(px, py, count, qx, qy, tol) -> bool:
    """Is (qx, qy) inside the convex hull of the first ``count`` 2-D points (px, py)?

    Gift wrapping, O(count x hull vertices): contact sets have a handful of hull
    vertices, and it needs no sort (a sort kernel costs seconds of compilation).
    tol (m): how far outside an edge still counts as inside.
    """
    if count < 3:
        return False
    first = 0
    for i in range(1, count):
        if px[i] < px[first] or (px[i] == px[first] and py[i] < py[first]):
            first = i
    a = first
    edges = 0
    for _ in range(count):
        # next hull vertex b: no point right of a->b (ties: the farthest), so the
        # walk is counter-clockwise and inside is left of every edge
        b = 1 if a == 0 else 0
        for i in range(count):
            cross = (px[b] - px[a]) * (py[i] - py[a]) - (py[b] - py[a]) * (px[i] - px[a])
            if cross < 0.0 or (cross == 0.0 and (px[i] - px[a]) ** 2 + (py[i] - py[a]) ** 2
                               > (px[b] - px[a]) ** 2 + (py[b] - py[a]) ** 2):
                b = i
        ex, ey = px[b] - px[a], py[b] - py[a]
        length = math.sqrt(ex * ex + ey * ey)
        if length == 0.0 or ex * (qy - py[a]) - ey * (qx - px[a]) < -tol * length:
            return False
        edges += 1
        a = b
        if a == first:
            return edges >= 3
    return False  # no closed walk: degenerate input


def balanced(points: np.ndarray, centre: np.ndarray, tol: float = 0.0) -> bool:
    """Is ``centre`` (2,) over the convex hull of ground contact ``points`` (K, 2)?"""
    p = np.ascontiguousarray(points, dtype=np.float64)
    return bool(_hull_contains(p[:, 0].copy(), p[:, 1].copy(), len(p), float(centre[0]),
                               float(centre[1]), tol))


@nb.njit(cache=True)
def ground_contacts(dt, ground, up_axis, friction, rest_damping, sleep_speed, vertices,
                    voxel_vertices, voxel_centroid, voxel_radius, voxel_restitution, offsets,
                    members, vertex_stamp,
                    body_mass, body_inv_inertia, body_radius, body_com, body_pos, body_rot,
                    body_lin, body_ang, body_fixed, body_live, body_dust, body_asleep, n_bodies,
                    contacts_out, supported_next) -> int:
    """Resolve ground contacts of every moving body; returns the number of contact points.

    ground: plane height (m) along axis ``up_axis`` (0, 1, 2); friction: Coulomb
    mu; rest_damping: 1/s decay of momenta in resting contact; sleep_speed: m/s
    below which a balanced body with >= 3 contacts is clamped to rest.
    contacts_out (K, 3): scratch for contact points (grows with the largest body).
    voxel_radius (N,): centroid-to-farthest-corner distance (m), to skip voxels whose
    corners are all out of reach. Bodies touching the plane are flagged in
    ``supported_next`` (B,) (see :func:`collide_bodies`).
    """
    e1 = (up_axis + 1) % 3
    e2 = (up_axis + 2) % 3
    axes = np.zeros((3, 3))  # rows: the plane normal, then the tangents along e1 and e2
    axes[0, up_axis] = 1.0
    axes[1, e1] = 1.0
    axes[2, e2] = 1.0
    max_contacts = contacts_out.shape[0]
    acc_n = np.zeros(max_contacts)
    acc_t = np.zeros((max_contacts, 2))
    rest = np.zeros(max_contacts)
    total = 0
    for b in range(n_bodies):
        if not body_live[b] or body_fixed[b] or body_dust[b] or body_asleep[b]:
            continue
        m = body_mass[b]
        inv_m = 1.0 / m
        speed = math.sqrt(body_lin[b, 0] ** 2 + body_lin[b, 1] ** 2 + body_lin[b, 2] ** 2) / m
        rot = body_rot[b]
        inv = body_inv_inertia[b]
        omega = angular_velocity(rot, inv, body_ang[b])
        spin = math.sqrt(omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2)
        reach = (speed + spin * body_radius[b]) * dt + 1e-6
        if body_pos[b, up_axis] - body_radius[b] > ground + reach:
            continue
        # contact candidates: boundary-voxel corners at or near the plane
        count = 0
        for k in range(offsets[b], offsets[b + 1]):
            v = members[k]
            x = voxel_centroid[v, 0] - body_com[b, 0]
            y = voxel_centroid[v, 1] - body_com[b, 1]
            z = voxel_centroid[v, 2] - body_com[b, 2]
            h = body_pos[b, up_axis] + rot[up_axis, 0] * x + rot[up_axis, 1] * y \
                + rot[up_axis, 2] * z - ground
            if h - voxel_radius[v] > reach:
                continue  # every corner out of reach
            for c in range(8):
                vid = voxel_vertices[v, c]
                if vertex_stamp[vid] == b:
                    continue
                vertex_stamp[vid] = b
                x = vertices[vid, 0] - body_com[b, 0]
                y = vertices[vid, 1] - body_com[b, 1]
                z = vertices[vid, 2] - body_com[b, 2]
                h = body_pos[b, up_axis] + rot[up_axis, 0] * x + rot[up_axis, 1] * y \
                    + rot[up_axis, 2] * z - ground
                if h > reach or count >= max_contacts:
                    continue
                for a in range(3):
                    contacts_out[count, a] = body_pos[b, a] + rot[a, 0] * x + rot[a, 1] * y \
                        + rot[a, 2] * z
                rest[count] = voxel_restitution[v]
                acc_n[count] = 0.0
                acc_t[count, 0] = 0.0
                acc_t[count, 1] = 0.0
                count += 1
        # forget the stamps of this body so later steps see its vertices again
        for k in range(offsets[b], offsets[b + 1]):
            for c in range(8):
                vertex_stamp[voxel_vertices[members[k], c]] = -1
        if count == 0:
            continue
        total += count
        # approach speeds before the solve decide bounce vs rest
        target = np.zeros(count)
        for i in range(count):
            vel = _point_velocity(b, contacts_out[i, 0], contacts_out[i, 1], contacts_out[i, 2],
                                  body_pos, body_lin, body_mass, omega)
            vn = vel[up_axis]
            gap = contacts_out[i, up_axis] - ground
            if gap > 1e-9:
                target[i] = -gap / dt  # speculative: arrive, do not pass
            elif -vn > sleep_speed + 2.0 * 9.81 * dt:
                target[i] = -rest[i] * vn  # impact: bounce
            else:
                target[i] = 0.0
        for _ in range(8):
            for i in range(count):
                px, py, pz = contacts_out[i, 0], contacts_out[i, 1], contacts_out[i, 2]
                omega = angular_velocity(rot, inv, body_ang[b])
                vel = _point_velocity(b, px, py, pz, body_pos, body_lin, body_mass, omega)
                rx, ry, rz = px - body_pos[b, 0], py - body_pos[b, 1], pz - body_pos[b, 2]
                k_n = _effective_inverse_mass(inv_m, rot, inv, rx, ry, rz, axes[0, 0],
                                              axes[0, 1], axes[0, 2])
                dj = (target[i] - vel[up_axis]) / k_n
                old = acc_n[i]
                acc_n[i] = max(old + dj, 0.0)
                dj = acc_n[i] - old
                _apply(b, dj * axes[0, 0], dj * axes[0, 1], dj * axes[0, 2], px, py, pz,
                       body_pos, body_lin, body_ang)
                # Coulomb friction on the two tangent axes, within mu * normal impulse
                omega = angular_velocity(rot, inv, body_ang[b])
                vel = _point_velocity(b, px, py, pz, body_pos, body_lin, body_mass, omega)
                limit = friction * acc_n[i]
                for t in range(2):
                    axis = e1 if t == 0 else e2
                    tx, ty, tz = axes[t + 1, 0], axes[t + 1, 1], axes[t + 1, 2]
                    k_t = _effective_inverse_mass(inv_m, rot, inv, rx, ry, rz, tx, ty, tz)
                    old_t = acc_t[i, t]
                    acc_t[i, t] = min(max(old_t - vel[axis] / k_t, -limit), limit)
                    dj = acc_t[i, t] - old_t
                    _apply(b, dj * tx, dj * ty, dj * tz, px, py, pz, body_pos, body_lin, body_ang)
        # resting contact: damp, and clamp to rest when balanced on >= 3 points
        omega = angular_velocity(rot, inv, body_ang[b])
        speed = math.sqrt(body_lin[b, 0] ** 2 + body_lin[b, 1] ** 2 + body_lin[b, 2] ** 2) / m
        spin = math.sqrt(omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2) * body_radius[b]
        # touching: within the sag of one step of gravity, or a hair of the body's size
        touch_tol = 1e-4 * max(1.0, body_radius[b]) + 9.81 * dt * dt
        touching = np.int64(0)  # not a literal 0: the callee would compile twice
        for i in range(count):
            if contacts_out[i, up_axis] - ground <= touch_tol:
                touching += 1
        if touching > 0:
            supported_next[b] = True
        if touching == 0 or speed > 4.0 * sleep_speed or spin > 4.0 * sleep_speed:
            continue
        decay = math.exp(-rest_damping * dt)
        for a in range(3):
            body_lin[b, a] *= decay
            body_ang[b, a] *= decay
        if touching >= 3 and speed < sleep_speed and spin < sleep_speed:
            px = np.empty(touching)
            py = np.empty(touching)
            j = 0
            for i in range(count):
                if contacts_out[i, up_axis] - ground <= touch_tol:
                    px[j] = contacts_out[i, e1]
                    py[j] = contacts_out[i, e2]
                    j += 1
            tol = 1e-9 * max(1.0, body_radius[b])
            if _hull_contains(px, py, touching, body_pos[b, e1], body_pos[b, e2], tol):
                for a in range(3):
                    body_lin[b, a] = 0.0
                    body_ang[b, a] = 0.0
                body_asleep[b] = True
    return total


@helper
def _cell(x, cell) -> int:
    return int(math.floor(x / cell)) + 1048576


@helper
def _key(i, j, k) -> int:
    """Hash key (>= 0) of integer cell (i, j, k)."""
    return (i * 2097152 + j) * 2097152 + k


@helper
def _slot(key, mask) -> int:
    """Table slot of a cell key: fold the three 21-bit fields, then a Fibonacci mix."""
    h = (key ^ (key >> 21) ^ (key >> 42)) * -7046029254386353131  # 0x9E3779B97F4A7C15
    return (h ^ (h >> 32)) & mask  # int64 arithmetic wraps


@helper
def hash_buckets(keys):
    """Counting sort of cell ``keys`` (M,) int64 into the buckets of a hash table.

    Returns (start (T+1,), entries (M,)): bucket s of the T-slot table (T a
    power of two, at least 2 M and 16) holds the indices entries[start[s]:
    start[s+1]] into ``keys``, in increasing order. Distinct keys can share a
    bucket, so a lookup compares keys (:func:`_bucket`). Linear time and no
    comparison sort, whose kernel would cost seconds of compilation.
    """
    n = keys.shape[0]
    size = 16
    while size < 2 * n:
        size *= 2
    mask = size - 1
    start = np.zeros(size + 1, dtype=np.int64)
    for i in range(n):
        start[_slot(keys[i], mask) + 1] += 1
    for s in range(size):
        start[s + 1] += start[s]
    fill = start[:-1].copy()
    entries = np.empty(n, dtype=np.int64)
    for i in range(n):
        s = _slot(keys[i], mask)
        entries[fill[s]] = i
        fill[s] += 1
    return start, entries


@helper
def _bucket(key, start):
    """(lo, hi): the range of ``key``'s bucket in a :func:`hash_buckets` table."""
    s = _slot(key, start.shape[0] - 2)
    return start[s], start[s + 1]


@nb.njit(cache=True)
def static_hash(voxel_centroid, voxel_body, offsets, members, body_com, body_pos, body_rot,
                body_live, body_dust, body_fixed, body_asleep, n_bodies, cell):
    """Spatial hash of the boundary voxels of bodies that do not move (fixed or asleep).

    Returns (voxels (S,), positions (S, 3), keys (S,), start): the voxels, their
    world centres and cell keys in bucket order, and the :func:`hash_buckets`
    offsets, so bucket s is the range start[s]:start[s+1] of the three arrays.
    Rebuilt only when the set of resting bodies changes.
    """
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
            keys[n] = _key(_cell(pos[n, 0], cell), _cell(pos[n, 1], cell),
                           _cell(pos[n, 2], cell))
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


@nb.njit(cache=True)
def rest_grid(voxel_centroid, voxel_body, members, cell):
    """Boundary voxels hashed by (body, cell of their rest centroid).

    Rest positions never change, so this is rebuilt only when the boundary does.
    Returns (slots (M,), keys (M,), start): boundary slots and their keys in
    bucket order, and the :func:`hash_buckets` offsets.
    """
    keys = np.empty(members.shape[0], dtype=np.int64)
    for k in range(members.shape[0]):
        v = members[k]
        keys[k] = _rest_key(voxel_body[v], _cell(voxel_centroid[v, 0], cell),
                            _cell(voxel_centroid[v, 1], cell), _cell(voxel_centroid[v, 2], cell))
    start, entries = hash_buckets(keys)
    return entries, keys[entries], start


@helper
def _mark_near_rest(b, o, reach, cell, voxel_centroid, members, body_com, body_pos, body_rot,
                    rest_slot, rest_keys, rest_start, world, near) -> int:
    """Mark b's boundary voxels within ``reach`` (m) of body o's centre, found through
    b's rest grid: o's centre is taken into b's rest frame. Returns how many."""
    cx, cy, cz = to_rest(body_rot[b], body_pos[b], body_com[b], body_pos[o, 0],
                         body_pos[o, 1], body_pos[o, 2])
    count = 0
    for i in range(_cell(cx - reach, cell), _cell(cx + reach, cell) + 1):
        for j in range(_cell(cy - reach, cell), _cell(cy + reach, cell) + 1):
            for k in range(_cell(cz - reach, cell), _cell(cz + reach, cell) + 1):
                key = _rest_key(b, i, j, k)
                lo, hi = _bucket(key, rest_start)
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
def _near_voxels(voxel_centroid, offsets, members, body_radius, body_com, body_pos, body_rot,
                 body_fixed, body_live, body_dust, body_asleep, n_bodies, cell, rest_slot,
                 rest_keys, rest_start, world, near):
    """Mark (in ``near``, by boundary slot) the voxels of moving bodies that may touch
    another body this step, with their world centres in ``world``; returns how many.

    Small bodies (<= SMALL_BODY boundary voxels) take part whole: the voxel hash
    is their broad phase. A bigger moving body takes part where it is within
    ``cell`` of the bounding sphere of a live body whose sphere its own meets:
    a scan of its voxels against a big neighbour, its rest grid (:func:`rest_grid`)
    around a small one, so a big block among thousands of chips stays cheap.
    """
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
                count += _mark_near_rest(b, o, reach, cell, voxel_centroid, members, body_com,
                                         body_pos, body_rot, rest_slot, rest_keys, rest_start,
                                         world, near)
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


@nb.njit(cache=True)
def collide_bodies(voxel_centroid, voxel_radius, voxel_restitution, voxel_yield, voxel_alive,
                   voxel_body, offsets, members, body_mass, body_inv_inertia, body_radius,
                   body_com, body_pos, body_rot, body_lin, body_ang, body_fixed, body_live,
                   body_dust, body_asleep, n_bodies, wake_speed, rest_speed, friction,
                   voxel_density, weakening, destroyed, dirty, resting, up, supported,
                   supported_next, hits_out, cell,
                   static_vox, static_pos, static_keys, static_start, rest_slot, rest_keys,
                   rest_start) -> int:
    """Find and resolve voxel-sphere contacts between different bodies, once each.

    voxel_radius (N,): collision radius (m), at most cell / 2. The boundary
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
    world = np.empty((members.shape[0], 3))  # world centres, by boundary slot
    near = np.zeros(members.shape[0], dtype=np.bool_)
    count = _near_voxels(voxel_centroid, offsets, members, body_radius, body_com, body_pos,
                         body_rot, body_fixed, body_live, body_dust, body_asleep, n_bodies, cell,
                         rest_slot, rest_keys, rest_start, world, near)
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
                ijk[n, a] = _cell(world[k, a], cell)
            keys[n] = _key(ijk[n, 0], ijk[n, 1], ijk[n, 2])
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
                    key = _key(ijk[i, 0] + dx, ijk[i, 1] + dy, ijk[i, 2] + dz)
                    # moving against moving: each pair once (lower voxel first)
                    lo, hi = _bucket(key, start)
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
                        resolved += _resolve_pair(
                            vi, vj, bi, bj, ci, cj, voxel_radius, voxel_restitution,
                            voxel_yield, voxel_alive, body_mass, body_inv_inertia, body_pos,
                            body_rot, body_lin, body_ang, body_fixed, body_asleep, wake_speed,
                            rest_speed, friction, voxel_density, weakening, destroyed, dirty,
                            resting, up, supported, supported_next, hits_out, resolved)
                    # moving against resting
                    lo, hi = _bucket(key, static_start)
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
                        resolved += _resolve_pair(
                            vi, vj, bi, bj, ci, cj, voxel_radius, voxel_restitution,
                            voxel_yield, voxel_alive, body_mass, body_inv_inertia, body_pos,
                            body_rot, body_lin, body_ang, body_fixed, body_asleep, wake_speed,
                            rest_speed, friction, voxel_density, weakening, destroyed, dirty,
                            resting, up, supported, supported_next, hits_out, resolved)
    return resolved


@helper
def _touching(ci, cj, reach) -> bool:
    """Do spheres at ci and cj (3,) with radii summing to ``reach`` (m) overlap?"""
    d2 = (cj[0] - ci[0]) ** 2 + (cj[1] - ci[1]) ** 2 + (cj[2] - ci[2]) ** 2
    return d2 < reach * reach


@helper
def _resolve_pair(vi, vj, bi, bj, ci, cj, voxel_radius, voxel_restitution, voxel_yield,
                  voxel_alive, body_mass, body_inv_inertia, body_pos, body_rot, body_lin,
                  body_ang, body_fixed, body_asleep, wake_speed, rest_speed, friction,
                  voxel_density, weakening, destroyed, dirty, resting, up, supported,
                  supported_next, hits_out, index) -> int:
    dx, dy, dz = cj[0] - ci[0], cj[1] - ci[1], cj[2] - ci[2]
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    reach = voxel_radius[vi] + voxel_radius[vj]
    if dist >= reach or dist <= 0.0:
        return 0
    nx, ny, nz = dx / dist, dy / dist, dz / dist
    px, py, pz = 0.5 * (ci[0] + cj[0]), 0.5 * (ci[1] + cj[1]), 0.5 * (ci[2] + cj[2])
    wi = angular_velocity(body_rot[bi], body_inv_inertia[bi], body_ang[bi])
    wj = angular_velocity(body_rot[bj], body_inv_inertia[bj], body_ang[bj])
    va = _point_velocity(bi, px, py, pz, body_pos, body_lin, body_mass, wi)
    vb = _point_velocity(bj, px, py, pz, body_pos, body_lin, body_mass, wj)
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
    k = _pair_inverse_mass(bi, bj, move_i, move_j, px, py, pz, nx, ny, nz, body_mass,
                           body_rot, body_inv_inertia, body_pos)
    if k <= 0.0:
        return 0
    # a contact slower than a few steps of gravity is resting, not an impact: no
    # bounce (restitution there would keep a pile hopping, as at the ground)
    e = 0.0 if gentle else min(voxel_restitution[vi], voxel_restitution[vj])
    j = -(1.0 + e) * vn / k
    _impulse_pair(bi, bj, j * nx, j * ny, j * nz, px, py, pz, body_pos, body_lin, body_ang,
                  move_i, move_j)
    # Coulomb friction: remove the sliding velocity at the contact, within mu * j
    wi = angular_velocity(body_rot[bi], body_inv_inertia[bi], body_ang[bi])
    wj = angular_velocity(body_rot[bj], body_inv_inertia[bj], body_ang[bj])
    va = _point_velocity(bi, px, py, pz, body_pos, body_lin, body_mass, wi)
    vb = _point_velocity(bj, px, py, pz, body_pos, body_lin, body_mass, wj)
    rx, ry, rz = vb[0] - va[0], vb[1] - va[1], vb[2] - va[2]
    rn = rx * nx + ry * ny + rz * nz
    tx, ty, tz = rx - rn * nx, ry - rn * ny, rz - rn * nz
    slide = math.sqrt(tx * tx + ty * ty + tz * tz)
    if slide > 1e-12 and friction > 0.0:
        tx, ty, tz = tx / slide, ty / slide, tz / slide
        k_t = _pair_inverse_mass(bi, bj, move_i, move_j, px, py, pz, tx, ty, tz, body_mass,
                                 body_rot, body_inv_inertia, body_pos)
        jt = min(slide / k_t, friction * j)
        _impulse_pair(bi, bj, -jt * tx, -jt * ty, -jt * tz, px, py, pz, body_pos, body_lin,
                      body_ang, move_i, move_j)
    _resist_rolling(bi, bj, j * 0.5 * reach, body_rot, body_inv_inertia, body_ang, move_i,
                    move_j)
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
def _pair_inverse_mass(bi, bj, move_i, move_j, px, py, pz, nx, ny, nz, body_mass, body_rot,
                       body_inv_inertia, body_pos) -> float:
    """Inverse mass (1/kg) the pair bi, bj shows an impulse along unit (nx, ny, nz) at
    point p: :func:`_effective_inverse_mass` summed over the bodies that move here."""
    k = 0.0
    for side in range(2):
        b = bi if side == 0 else bj
        if not (move_i if side == 0 else move_j):
            continue
        k += _effective_inverse_mass(1.0 / body_mass[b], body_rot[b], body_inv_inertia[b],
                                     px - body_pos[b, 0], py - body_pos[b, 1],
                                     pz - body_pos[b, 2], nx, ny, nz)
    return k


@helper
def _resist_rolling(bi, bj, limit, body_rot, body_inv_inertia, body_ang, move_i,
                    move_j) -> None:
    """Rolling resistance: remove the relative spin of bi and bj with an opposite pair of
    angular impulses, up to ``limit`` (N m s).

    The contact spheres stand in for voxels, and a voxel, unlike a sphere, does
    not roll: tipping a cube over an edge takes a couple of about its weight
    times half its edge. With limit = j x (half the contact distance), debris
    on a pile stops rolling instead of creeping down it forever. A couple
    changes no linear momentum and, being equal and opposite, no angular
    momentum either; it only removes relative rotation, so it never adds energy.
    """
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
def _impulse_pair(bi, bj, jx, jy, jz, px, py, pz, body_pos, body_lin, body_ang, move_i,
                  move_j) -> None:
    """Impulse (jx, jy, jz) (N s) on bj at point p, and its opposite on bi; a body that
    does not move here (fixed, asleep or holding a stack) takes none."""
    if move_i:
        _apply(bi, -jx, -jy, -jz, px, py, pz, body_pos, body_lin, body_ang)
    if move_j:
        _apply(bj, jx, jy, jz, px, py, pz, body_pos, body_lin, body_ang)
