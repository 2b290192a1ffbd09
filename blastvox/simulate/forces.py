"""Blast impulse on free bodies at the corners of exposed voxel faces.

Martins 2001 §4.3: F = p(t) A R/|R| at voxel vertices, torque r x F, summed
per body over boundary voxels. We apply it face by face: an exposed face with
outward vector area a (m^2) that faces the charge has projected area
A = |a| cos(theta) = -a . R_hat on the shock front; a quarter of it acts at
each of the face's corners, where the overpressure is evaluated. Summed over a
convex voxel this is exactly the voxel's projected area (s^2 to sqrt(3) s^2 for
a cube), the papers' "area projected onto the shock front" without their
constant-area approximation. Conform voxels use each face's area centroid.

Nothing here samples the pressure at an instant: each point receives the
exact integral of the overpressure over the step (closed form, see
:mod:`blastvox.simulate.wave`), so a shock passing between two steps is never
missed and the momentum converges as dt shrinks.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.geometry.transforms_nb import rotate_into, to_world_into
from blastvox.geometry.voxel_faces import FACE_CORNERS
from blastvox.jit import helper, kernel
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.kernels import bodies_in_shell, wake_on_impulse
from blastvox.simulate.state import Front
from blastvox.simulate.wave import point_impulse


@helper
def _apply(point, weight_area, vec_area, c, t0, t1, front, pivot, out_p, out_l, b):
    """Add the impulse at one point for one charge of ``front`` to row b of the
    accumulators, the angular part about ``pivot`` (3,) m."""
    charge_pos = front.position
    rx = point[0] - charge_pos[c, 0]
    ry = point[1] - charge_pos[c, 1]
    rz = point[2] - charge_pos[c, 2]
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    if r <= 0.0:
        return
    j = point_impulse(front.table, r, front.time[c], front.scale[c], t0, t1)
    _push((point[0], point[1], point[2]), j, (rx / r, ry / r, rz / r), weight_area, vec_area,
          pivot, out_p, out_l, b)


@helper
def _push(p, j, u, weight_area, vec_area, pivot, out_p, out_l, b):
    """Add impulse j (Pa s) along the unit radius u = (ux, uy, uz) at point p = (px, py,
    pz) (m) through a face of vector area ``vec_area`` x ``weight_area`` (its share at
    this point), the angular part about ``pivot``. Tuples of scalars, not row views:
    this runs for every exposed corner."""
    px, py, pz = p
    ux, uy, uz = u
    body_pos_b = pivot
    norm = math.sqrt(vec_area[0] ** 2 + vec_area[1] ** 2 + vec_area[2] ** 2)
    if norm <= 0.0:
        return
    facing = -(vec_area[0] * ux + vec_area[1] * uy + vec_area[2] * uz)
    if facing <= 0.0:
        return
    if j == 0.0:
        return
    mag = j * facing * weight_area
    fx, fy, fz = mag * ux, mag * uy, mag * uz
    out_p[b, 0] += fx
    out_p[b, 1] += fy
    out_p[b, 2] += fz
    dx = px - body_pos_b[0]
    dy = py - body_pos_b[1]
    dz = pz - body_pos_b[2]
    out_l[b, 0] += dy * fz - dz * fy
    out_l[b, 1] += dz * fx - dx * fz
    out_l[b, 2] += dx * fy - dy * fx


@helper
def _corner(vertex, slot, c, bodies, b, vertices, charge_pos, corner_point, corner_u) -> bool:
    """World position and unit radius of a voxel corner of body b for charge c (False at
    the charge's centre, where there is no direction). Indices, not row views: this
    runs for every exposed corner, and a view costs two reference counts."""
    body_rot, body_pos, body_com = bodies.rot, bodies.pos, bodies.com
    x = vertices[vertex, 0] - body_com[b, 0]
    y = vertices[vertex, 1] - body_com[b, 1]
    z = vertices[vertex, 2] - body_com[b, 2]
    for a in range(3):  # as _to_world
        corner_point[slot, a] = (body_pos[b, a] + body_rot[b, a, 0] * x + body_rot[b, a, 1] * y
                                 + body_rot[b, a, 2] * z)
    rx = corner_point[slot, 0] - charge_pos[c, 0]
    ry = corner_point[slot, 1] - charge_pos[c, 1]
    rz = corner_point[slot, 2] - charge_pos[c, 2]
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    if r <= 0.0:
        return False
    corner_u[slot, 0], corner_u[slot, 1], corner_u[slot, 2] = rx / r, ry / r, rz / r
    corner_u[slot, 3] = r
    return True


@kernel
def blast_impulses(front, reach_in, t0, t1, boundary, geometry, voxels, bodies, active,
                   loads) -> None:
    """Accumulate the blast impulse (N s) and angular impulse (N m s) of [t0, t1] per body.

    Into loads.impulse and loads.angular (B, 3). boundary (M,): the voxels with an
    exposed face (the others take no pressure), each body's in voxel order.
    front.outer (C,): shock radius at t1 (m); reach_in (C,): radius behind which the
    whole wave (positive and negative phase) has passed by t0. Points outside
    that shell, and bodies not flagged in ``active`` (B,), are skipped without
    evaluating the blast model.

    A fixed body takes no momentum, but its voxels keep what the wave gave them
    in held_p (N, 3) (N s) and held_l (N, 3) (N m s, about the voxel's centroid):
    a piece that breaks free later in the same wave gets it (see
    :func:`blastvox.simulate.kernels.release_held`), so a piece's momentum does
    not depend on how many steps the front took to cross it before its links
    broke (without this, small steps lost the part of the wave that arrived
    while the piece was still held, and the momentum did not converge in dt).
    """
    charge_pos, charge_time, charge_scale, table = (front.position, front.time, front.scale,
                                                    front.table)
    reach_out = front.outer
    vertices, voxel_vertices, voxel_centroid = (geometry.vertices, geometry.corners,
                                                geometry.centroid)
    voxel_radius, conform_slot = geometry.radius, geometry.conform_slot
    conform_area, conform_centroid = geometry.conform_area, geometry.conform_centroid
    voxel_body, voxel_alive, voxel_link_mask = voxels.body, voxels.alive, voxels.link_mask
    body_com, body_pos, body_rot = bodies.com, bodies.pos, bodies.rot
    body_fixed, body_live, body_dust = bodies.fixed, bodies.live, bodies.dust
    out_p, out_l, held_p, held_l = loads.impulse, loads.angular, loads.held_p, loads.held_l
    n_charges = charge_pos.shape[0]
    point = np.empty(3)
    area = np.empty(3)
    rest_area = np.empty(3)
    centre = np.empty(3)
    # a cube's 8 corners serve its 6 faces: each corner's impulse is evaluated once
    corner_point = np.empty((8, 3))
    corner_u = np.empty((8, 4))  # unit radius and distance (m)
    corner_j = np.empty(8)
    corner_state = np.zeros(8, dtype=np.int64)  # 0 unknown, 1 placed, 2 impulse known, -1 at R=0
    for k in range(boundary.shape[0]):
        v = boundary[k]
        if not voxel_alive[v]:
            continue
        b = voxel_body[v]
        if not active[b] or body_dust[b] or not body_live[b]:
            continue
        exposed = (~voxel_link_mask[v]) & 0x3F
        slot = conform_slot[v]
        if exposed == 0 and slot < 0:
            continue
        rot = body_rot[b]
        to_world_into(rot, body_pos[b], body_com[b], voxel_centroid[v], centre)
        # a free body sums about its centre of mass, a fixed one's voxels each keep theirs
        acc_p, acc_l, index, pivot = out_p, out_l, b, body_pos[b]
        if body_fixed[b]:
            acc_p, acc_l, index, pivot = held_p, held_l, v, centre
        for c in range(n_charges):
            if reach_out[c] <= 0.0:
                continue
            d = math.sqrt((centre[0] - charge_pos[c, 0]) ** 2 + (centre[1] - charge_pos[c, 1]) ** 2
                          + (centre[2] - charge_pos[c, 2]) ** 2)
            if d - voxel_radius[v] > reach_out[c] or d + voxel_radius[v] < reach_in[c]:
                continue
            if slot >= 0:
                for f in range(7):
                    if f < 6 and not (exposed >> f) & 1:
                        continue
                    rotate_into(rot, conform_area[slot, f], area)
                    to_world_into(rot, body_pos[b], body_com[b], conform_centroid[slot, f], point)
                    _apply(point, 1.0, area, c, t0, t1, front, pivot, acc_p, acc_l, index)
                continue
            corner_state[:] = 0
            for f in range(6):
                if not (exposed >> f) & 1:
                    continue
                q0 = voxel_vertices[v, FACE_CORNERS[f, 0]]
                q1 = voxel_vertices[v, FACE_CORNERS[f, 1]]
                q2 = voxel_vertices[v, FACE_CORNERS[f, 2]]
                q3 = voxel_vertices[v, FACE_CORNERS[f, 3]]
                # vector area of the quad = half the cross product of its diagonals
                d1x = vertices[q2, 0] - vertices[q0, 0]
                d1y = vertices[q2, 1] - vertices[q0, 1]
                d1z = vertices[q2, 2] - vertices[q0, 2]
                d2x = vertices[q3, 0] - vertices[q1, 0]
                d2y = vertices[q3, 1] - vertices[q1, 1]
                d2z = vertices[q3, 2] - vertices[q1, 2]
                rest_area[0] = 0.5 * (d1y * d2z - d1z * d2y)
                rest_area[1] = 0.5 * (d1z * d2x - d1x * d2z)
                rest_area[2] = 0.5 * (d1x * d2y - d1y * d2x)
                rotate_into(rot, rest_area, area)
                for k in range(4):
                    q = FACE_CORNERS[f, k]
                    if corner_state[q] == 0:
                        placed = _corner(voxel_vertices[v, q], q, c, bodies, b, vertices,
                                         charge_pos, corner_point, corner_u)
                        corner_state[q] = 1 if placed else -1
                    if corner_state[q] < 0:
                        continue
                    ux, uy, uz = corner_u[q, 0], corner_u[q, 1], corner_u[q, 2]
                    if -(area[0] * ux + area[1] * uy + area[2] * uz) <= 0.0:
                        continue  # faces away: no need for the (costly) impulse
                    if corner_state[q] == 1:
                        corner_j[q] = point_impulse(table, corner_u[q, 3], charge_time[c],
                                                    charge_scale[c], t0, t1)
                        corner_state[q] = 2
                    _push((corner_point[q, 0], corner_point[q, 1], corner_point[q, 2]),
                          corner_j[q], (ux, uy, uz), 0.25, area, pivot, acc_p, acc_l, index)


def blast_phase(model, state, charges, t0: float, t1: float, front_out: np.ndarray) -> None:
    """Phase: this step's blast impulse on every body the waves still load.

    Reads the bodies' poses and the boundary; writes loads.impulse and
    loads.angular (zeroed first; (B, 3)), the voxels' held impulses while a wave
    loads fixed bodies (cleared once every wave has passed), marks.active and
    wakes pushed sleepers. charges: the run's
    :class:`~blastvox.simulate.wave.Charges`; front_out (C,): front radii at t1, m.
    """
    bodies, loads = state.bodies, state.loads
    n = state.n_bodies
    loads.impulse[:n] = 0.0
    loads.angular[:n] = 0.0
    reach_in = charges.tail_radius(t0)
    if not bodies_in_shell(bodies.pos, bodies.radius, bodies.live, n, charges.position,
                           reach_in, front_out, state.marks.active):
        if state.holding:  # every wave has passed: what held voxels took is spent
            loads.held_p[:] = 0.0
            loads.held_l[:] = 0.0
            state.holding = False
        return
    front = Front(charges.position, charges.time, charges.scale, charges.table, reach_in,
                  front_out)
    blast_impulses(front, reach_in, t0, t1, boundary_of(model, state)[1], model.voxels,
                   state.voxels, bodies, state.marks.active, loads)
    state.holding = True
    wake_on_impulse(loads.impulse, loads.angular, bodies.asleep, n)
