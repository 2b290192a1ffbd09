"""Blast impulse on free bodies over the exposed faces of their voxels.

Martins 2001 §4.3 pushes each boundary voxel along the radius from the charge
with the incident overpressure on its projected area. Here each exposed face
takes the load of :mod:`blastvox.blast.face_load` - reflected by its angle
of incidence and cleared by the piece's size when it faces the charge in
line of sight, the diffracted side-on load when it is turned away or
shadowed (:mod:`blastvox.simulate.shielding`), the negative phase on every
loaded face - and the pressure pushes along the face's inward normal,
F = -p A n. A quarter of a cube face's vector area acts at each of its
corners, where the wave is evaluated (its distance, angle and timing);
conform voxels use each face's area centroid.

Nothing here samples the pressure at an instant: each point receives the
exact integral of its load over the step (closed form), so a shock passing
between two steps is never missed, consecutive steps telescope to the face's
total and the momentum converges as dt shrinks.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.blast.face_load import face_load_nb, face_params_at, face_step_fractions_nb
from blastvox.geometry.transforms_nb import rotate_into, to_world_into
from blastvox.geometry.voxel_faces import FACE_CORNERS
from blastvox.jit import helper, kernel
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.clearing import exposure_of
from blastvox.simulate.diffraction import detour_at, voxel_detour
from blastvox.simulate.kernels import bodies_in_shell, hold, wake_on_impulse
from blastvox.simulate.model import CONFORM_FACES
from blastvox.simulate.shielding import grid_cell, ray_blocked
from blastvox.simulate.state import Front, clear_held, hold_room

_LIFT = 0.51  # a face's line of sight starts this many grid cells out of the face


@helper
def _push(px, py, pz, j, vec_area, weight, pivot, out_p, out_l, b):
    """Add the impulse of j (Pa s) on ``weight`` x the face of outward vector area
    ``vec_area`` (m^2), at point (px, py, pz) m: -j A n, the angular part about pivot."""
    fx = -j * weight * vec_area[0]
    fy = -j * weight * vec_area[1]
    fz = -j * weight * vec_area[2]
    out_p[b, 0] += fx
    out_p[b, 1] += fy
    out_p[b, 2] += fz
    dx = px - pivot[0]
    dy = py - pivot[1]
    dz = pz - pivot[2]
    out_l[b, 0] += dy * fz - dz * fy
    out_l[b, 1] += dz * fx - dx * fz
    out_l[b, 2] += dx * fy - dy * fx


@helper
def face_area_into(vertices, voxel_vertices, v, f, out) -> None:
    """Outward vector area (m^2, rest frame) of cube face f of voxel v into out (3,):
    half the cross product of the quad's diagonals."""
    q0 = voxel_vertices[v, FACE_CORNERS[f, 0]]
    q1 = voxel_vertices[v, FACE_CORNERS[f, 1]]
    q2 = voxel_vertices[v, FACE_CORNERS[f, 2]]
    q3 = voxel_vertices[v, FACE_CORNERS[f, 3]]
    d1x = vertices[q2, 0] - vertices[q0, 0]
    d1y = vertices[q2, 1] - vertices[q0, 1]
    d1z = vertices[q2, 2] - vertices[q0, 2]
    d2x = vertices[q3, 0] - vertices[q1, 0]
    d2y = vertices[q3, 1] - vertices[q1, 1]
    d2z = vertices[q3, 2] - vertices[q1, 2]
    out[0] = 0.5 * (d1y * d2z - d1z * d2y)
    out[1] = 0.5 * (d1z * d2x - d1x * d2z)
    out[2] = 0.5 * (d1x * d2y - d1y * d2x)


@helper
def _sight(grid, reach, point, area, charge_pos, c) -> int:
    """The line from a face (centre ``point``, outward vector area ``area``) to charge
    c: 1 clear of solid, 2 shadowed, 3 sealed off (the air just outside the face is
    none the wave reaches, ``reach`` (C, cells): a sealed room's inside, for a charge
    in the open); 0 for a face of no area. (It starts just outside the face: a face
    pressed against another piece is shadowed.)"""
    norm = math.sqrt(area[0] ** 2 + area[1] ** 2 + area[2] ** 2)
    if norm <= 0.0:
        return 2
    lift = _LIFT * grid.cell[0] / norm
    x, y, z = point[0] + lift * area[0], point[1] + lift * area[1], point[2] + lift * area[2]
    if not ray_blocked(grid, x, y, z, charge_pos[c, 0], charge_pos[c, 1], charge_pos[c, 2],
                       False):
        return 1
    q = grid_cell(grid, x, y, z)
    return 3 if q >= 0 and not reach[c, q] else 2


@helper
def _cached_sight(sight, v, c, f, exposure, point, area, charge_pos) -> int:
    """:func:`_sight` of face f of voxel v, cast once per wave (sight (N, C, CONFORM_FACES))."""
    known = sight[v, c, f]
    if known == 0:
        known = _sight(exposure.grid, exposure.reach, point, area, charge_pos, c)
        sight[v, c, f] = known
    return known


@helper
def _point_load(front, c, px, py, pz, t0, t1, out, extra):
    """The wave of charge c at point p: out[0] distance m, out[1:4] unit radius,
    out[4] positive step fraction, out[5] negative step fraction, out[6:15] ps, td, b,
    is, pr, ir, q, u, i_neg (see face_params_at). ``extra`` m: the wave's detour round
    solid to p (:mod:`blastvox.simulate.diffraction`): it arrives, and is as strong, as
    that much farther out. Returns False if the wave has not reached p by t1 or p is at
    the charge."""
    rx = px - front.position[c, 0]
    ry = py - front.position[c, 1]
    rz = pz - front.position[c, 2]
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    if r <= 0.0:
        return False
    (ps, ta, td, b, imp, pr, ir, q, u, p_neg, i_neg,
     td_neg) = face_params_at(front.table, front.burst[c], r + extra, front.scale[c])
    ta += front.time[c]
    if t1 <= ta:
        return False
    out[0], out[1], out[2], out[3] = r, rx / r, ry / r, rz / r
    out[4], out[5] = face_step_fractions_nb(t0, t1, ta, td, b, td_neg)
    out[6], out[7], out[8], out[9], out[10] = ps, td, b, imp, pr
    out[11], out[12], out[13], out[14] = ir, q, u, i_neg
    return True


@helper
def _face_detour(exposure, c, point, area) -> float:
    """The detour (m) of charge c's wave round solid to the air just outside the face
    (centre ``point``, outward vector area ``area``; :func:`detour_at`)."""
    norm = math.sqrt(area[0] ** 2 + area[1] ** 2 + area[2] ** 2)
    if norm <= 0.0:
        return 0.0
    lift = _LIFT * exposure.detour.cell / norm
    return detour_at(exposure.detour, c, point[0] + lift * area[0], point[1] + lift * area[1],
                     point[2] + lift * area[2])


@helper
def _face_impulse(load, area, direct, s_clear, g_clear) -> float:
    """Step impulse (Pa s) on a face of outward vector area ``area`` from the wave
    ``load`` (a :func:`_point_load` row)."""
    norm = math.sqrt(area[0] ** 2 + area[1] ** 2 + area[2] ** 2)
    if norm <= 0.0:
        return 0.0
    cos_a = -(area[0] * load[1] + area[1] * load[2] + area[2] * load[3]) / norm
    wave = (load[6], load[7], load[8], load[9], load[10], load[11], load[12], load[13])
    i_pos, _ = face_load_nb(wave, cos_a, direct, s_clear, g_clear)
    return i_pos * load[4] - load[14] * load[5]


@kernel
def blast_impulses(front, t0, t1, boundary, geometry, voxels, bodies, active, loads,
                   exposure) -> None:
    """Accumulate the blast impulse (N s) and angular impulse (N m s) of [t0, t1] per body.

    Into loads.impulse and loads.angular (B, 3). boundary (M,): the voxels with an
    exposed face (the others take no pressure), each body's in voxel order.
    front.outer (C,): shock radius at t1 (m); front.inner (C,): radius behind
    which the whole wave (positive and negative phase) has passed by t0.
    Points outside that shell, and bodies not flagged in ``active`` (B,), are
    skipped without evaluating the blast model. exposure: an
    :class:`~blastvox.simulate.state.Exposure` (shielding grid, clearing sizes,
    and the faces' lines of sight, each cast once per wave).

    A fixed body takes no momentum, but its voxels keep what the wave gave them
    in held_p (N s) and held_l (N m s, about the voxel's centroid), each its row
    (:class:`~blastvox.simulate.state.Loads`; room made for every boundary voxel):
    a piece that breaks free later in the same wave gets it (see
    :func:`blastvox.simulate.kernels.release_held`), so a piece's momentum does
    not depend on how many steps the front took to cross it before its links
    broke.
    """
    charge_pos, reach_in, reach_out = front.position, front.inner, front.outer
    vertices, voxel_vertices, voxel_centroid = (geometry.vertices, geometry.corners,
                                                geometry.centroid)
    voxel_radius, conform_slot = geometry.radius, geometry.conform_slot
    conform_area, conform_centroid = geometry.conform_area, geometry.conform_centroid
    voxel_body, voxel_alive, voxel_link_mask = voxels.body, voxels.alive, voxels.link_mask
    body_com, body_pos, body_rot = bodies.com, bodies.pos, bodies.rot
    body_fixed, body_live, body_dust = bodies.fixed, bodies.live, bodies.dust
    out_p, out_l, held_p, held_l = loads.impulse, loads.angular, loads.held_p, loads.held_l
    n_charges = charge_pos.shape[0]
    clearing, sight = exposure.clearing, exposure.sight
    point = np.empty(3)
    area = np.empty(3)
    rest_area = np.empty(3)
    centre = np.empty(3)
    # a cube's 8 corners serve its 6 faces: each corner's wave is evaluated once
    corner_point = np.empty((8, 3))
    corner_load = np.empty((8, 15))
    corner_state = np.zeros(8, dtype=np.int64)  # 0 unknown, 1 loaded, -1 no load
    shadow_load = np.empty(15)
    for k in range(boundary.shape[0]):
        v = boundary[k]
        if not voxel_alive[v]:
            continue
        b = voxel_body[v]
        if not active[b] or body_dust[b] or not body_live[b]:
            continue
        exposed = (~voxel_link_mask[v]) & ~loads.shadow[v] & 0x3F  # not behind dust
        slot = conform_slot[v]
        if exposed == 0 and slot < 0:
            continue
        rot = body_rot[b]
        to_world_into(rot, body_pos[b], body_com[b], voxel_centroid[v], centre)
        # a free body sums about its centre of mass, a fixed one's voxels each keep theirs
        acc_p, acc_l, index, pivot = out_p, out_l, b, body_pos[b]
        if body_fixed[b]:
            acc_p, acc_l, index, pivot = held_p, held_l, hold(loads, v), centre
        for c in range(n_charges):
            if reach_out[c] <= 0.0:
                continue
            d = math.sqrt((centre[0] - charge_pos[c, 0]) ** 2 + (centre[1] - charge_pos[c, 1]) ** 2
                          + (centre[2] - charge_pos[c, 2]) ** 2)
            if d - voxel_radius[v] > reach_out[c] or d + voxel_radius[v] + voxel_detour(
                    exposure.detour, c, v, centre[0], centre[1], centre[2]) < reach_in[c]:
                continue  # not reached yet, or passed (come round to its far faces too)
            s_clear, g_clear = clearing[b, c, 0], clearing[b, c, 1]
            if slot >= 0:
                for f in range(CONFORM_FACES):
                    if f < 6 and not (exposed >> f) & 1:
                        continue
                    face_area = conform_area[slot, f]
                    if face_area[0] == 0.0 and face_area[1] == 0.0 and face_area[2] == 0.0:
                        continue  # no such face (it would take exactly no load)
                    rotate_into(rot, conform_area[slot, f], area)
                    to_world_into(rot, body_pos[b], body_com[b], conform_centroid[slot, f], point)
                    seen = _cached_sight(sight, v, c, f, exposure, point, area, charge_pos)
                    if seen == 3:
                        continue  # sealed off from this wave
                    extra = 0.0 if seen == 1 else _face_detour(exposure, c, point, area)
                    if not _point_load(front, c, point[0], point[1], point[2], t0, t1,
                                       corner_load[0], extra):
                        continue
                    j = _face_impulse(corner_load[0], area, seen == 1, s_clear, g_clear)
                    _push(point[0], point[1], point[2], j, area, 1.0, pivot, acc_p, acc_l, index)
                continue
            corner_state[:] = 0
            for f in range(6):
                if not (exposed >> f) & 1:
                    continue
                face_area_into(vertices, voxel_vertices, v, f, rest_area)
                rotate_into(rot, rest_area, area)
                for a in range(3):
                    point[a] = 0.0
                loaded = False
                for n in range(4):
                    q = FACE_CORNERS[f, n]
                    if corner_state[q] == 0:
                        to_world_into(rot, body_pos[b], body_com[b],
                                      vertices[voxel_vertices[v, q]], corner_point[q])
                        placed = _point_load(front, c, corner_point[q, 0], corner_point[q, 1],
                                             corner_point[q, 2], t0, t1, corner_load[q], 0.0)
                        corner_state[q] = 1 if placed else -1
                    for a in range(3):
                        point[a] += 0.25 * corner_point[q, a]
                    loaded = loaded or corner_state[q] > 0
                if not loaded:
                    continue
                seen = _cached_sight(sight, v, c, f, exposure, point, area, charge_pos)
                if seen == 3:
                    continue  # sealed off from this wave
                direct = seen == 1
                extra = 0.0 if direct else _face_detour(exposure, c, point, area)
                # the wave that comes round (later, weaker) is the same at the four corners
                # of a face in its shadow: its centre's
                shadowed = extra > 0.0 and _point_load(front, c, point[0], point[1], point[2],
                                                       t0, t1, shadow_load, extra)
                if extra > 0.0 and not shadowed:
                    continue  # it has not come round to this face yet
                for n in range(4):
                    q = FACE_CORNERS[f, n]
                    if corner_state[q] < 0:
                        continue
                    load = shadow_load if shadowed else corner_load[q]
                    j = _face_impulse(load, area, direct, s_clear, g_clear)
                    _push(corner_point[q, 0], corner_point[q, 1], corner_point[q, 2], j, area,
                          0.25, pivot, acc_p, acc_l, index)


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
    # a shadowed face's wave comes round, later: a body is loaded until it has passed
    # the farthest way round too (each voxel's own way round: blast_impulses)
    shell_in = reach_in if state.caches.detour is None else reach_in - state.caches.detour.most
    if not bodies_in_shell(bodies.pos, bodies.radius, bodies.live, n, charges.position,
                           shell_in, front_out, state.marks.active):
        if state.holding:  # every wave has passed: what held voxels took is spent
            clear_held(loads)
            loads.shadow[:] = 0
            state.holding = False
        return
    front = Front(charges.position, charges.time, charges.scale, charges.table, charges.burst,
                  reach_in, front_out)
    exposure = exposure_of(model, state, charges.position, state.marks.active, None)
    boundary = boundary_of(model, state)[1]
    hold_room(state, len(boundary))  # a fixed body's boundary voxels may hold
    blast_impulses(front, t0, t1, boundary, model.voxels, state.voxels, bodies,
                   state.marks.active, state.loads, exposure)
    state.holding = True
    wake_on_impulse(loads.impulse, loads.angular, bodies.asleep, n)
