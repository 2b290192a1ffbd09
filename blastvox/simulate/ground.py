"""Ground contact (Martins 2001 §5.2).

Like fragment collisions (:mod:`blastvox.simulate.collide`), it acts at velocity
level between the velocity and position halves of the step, and never adds energy:
an impulse only removes approach velocity, or reflects it with a restitution
coefficient e <= 1.

Ground: an infinite-mass plane at the scene's ground height. Contact points are the
corners of a body's boundary voxels that are at or below the plane, or would reach
it this step (speculative contacts, so fast debris cannot tunnel and resting bodies
do not sink, without pushing positions around). Normal and tangential impulses are
solved together by a few projected Gauss-Seidel sweeps; the tangential part is
Coulomb friction, the "pseudo-friction" of the paper: it opposes the tangential
velocity and grows with the body's mass and speed up to mu times the normal impulse.
A body in resting contact loses a part of its momenta (damping); with three or more
contact points, small velocities and its centre of mass over the *exact convex hull*
of its contact points (the paper used their bounding rectangle to save time), it is
clamped to rest and sleeps until something wakes it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from blastvox.jit import kernel
from blastvox.simulate.bodies import apply_impulse, effective_inverse_mass, point_velocity
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.integrate import angular_velocity


class GroundParams(NamedTuple):
    """dt: step, s; ground: plane height (m) along axis up_axis (0, 1, 2); friction:
    Coulomb mu; rest_damping: 1/s decay of momenta in resting contact; sleep_speed:
    m/s below which a balanced body with >= 3 contacts is clamped to rest."""

    dt: float
    ground: float
    up_axis: int
    friction: float
    rest_damping: float
    sleep_speed: float


@kernel  # also called from Python, by balanced()
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


@kernel
def ground_contacts(geometry, offsets, members, bodies, contacts, params) -> int:
    """Resolve ground contacts of every moving body; returns the number of contact points.

    geometry: the model's VoxelGeometry; offsets, members: each body's boundary
    voxels (CSR, :func:`blastvox.simulate.boundary.boundary_lists`); params:
    :class:`GroundParams`. Voxel corners are the contact candidates; a voxel
    whose corners are all out of reach (its ``radius``, centroid to farthest
    corner) is skipped. contacts.points (K, 3) is scratch for one body's contact
    points (grows with the largest body). Bodies touching the plane are flagged
    in contacts.supported_next (B,) (see :func:`blastvox.simulate.collide.collide_bodies`).
    """
    dt, ground, up_axis = params.dt, params.ground, params.up_axis
    friction, rest_damping, sleep_speed = params.friction, params.rest_damping, params.sleep_speed
    vertices, voxel_vertices = geometry.vertices, geometry.corners
    voxel_centroid = geometry.centroid
    voxel_radius, voxel_restitution = geometry.radius, geometry.restitution
    vertex_stamp, contacts_out, supported_next = (contacts.vertex_stamp, contacts.points,
                                                  contacts.supported_next)
    body_mass, body_inv_inertia, body_radius = bodies.mass, bodies.inv_inertia, bodies.radius
    body_com, body_pos, body_rot = bodies.com, bodies.pos, bodies.rot
    body_lin, body_ang, body_fixed, body_live = bodies.lin, bodies.ang, bodies.fixed, bodies.live
    body_dust, body_asleep, n_bodies = bodies.dust, bodies.asleep, bodies.count[0]
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
            vel = point_velocity(b, contacts_out[i, 0], contacts_out[i, 1], contacts_out[i, 2],
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
                vel = point_velocity(b, px, py, pz, body_pos, body_lin, body_mass, omega)
                rx, ry, rz = px - body_pos[b, 0], py - body_pos[b, 1], pz - body_pos[b, 2]
                k_n = effective_inverse_mass(inv_m, rot, inv, rx, ry, rz, axes[0, 0],
                                              axes[0, 1], axes[0, 2])
                dj = (target[i] - vel[up_axis]) / k_n
                old = acc_n[i]
                acc_n[i] = max(old + dj, 0.0)
                dj = acc_n[i] - old
                apply_impulse(b, (dj * axes[0, 0], dj * axes[0, 1], dj * axes[0, 2]),
                              (px, py, pz), body_pos, body_lin, body_ang)
                # Coulomb friction on the two tangent axes, within mu * normal impulse
                omega = angular_velocity(rot, inv, body_ang[b])
                vel = point_velocity(b, px, py, pz, body_pos, body_lin, body_mass, omega)
                limit = friction * acc_n[i]
                for t in range(2):
                    axis = e1 if t == 0 else e2
                    tx, ty, tz = axes[t + 1, 0], axes[t + 1, 1], axes[t + 1, 2]
                    k_t = effective_inverse_mass(inv_m, rot, inv, rx, ry, rz, tx, ty, tz)
                    old_t = acc_t[i, t]
                    acc_t[i, t] = min(max(old_t - vel[axis] / k_t, -limit), limit)
                    dj = acc_t[i, t] - old_t
                    apply_impulse(b, (dj * tx, dj * ty, dj * tz), (px, py, pz), body_pos, body_lin,
                                  body_ang)
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


def ground_phase(model, state, settings, dt: float, ground: float) -> None:
    """Phase: ground-plane contacts of every moving body (see the module docstring).

    Reads the bodies' poses and the boundary; writes momenta, asleep and
    contacts.supported_next; counts contact points in the run's counters.
    ground: the plane's height along the model's up axis, m.
    """
    s = settings
    offsets, members = boundary_of(model, state)
    params = GroundParams(dt, ground, model.up_axis, s.friction, s.rest_damping,
                          s.sleep_speed)
    state.counters.ground_contacts += int(ground_contacts(
        model.voxels, offsets, members, state.bodies, state.contacts, params))
