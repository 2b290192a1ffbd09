"""Fracture: links and voxels that the shock front crosses during a step.

The overpressure at a point peaks when the shock arrives (Friedlander decays
from there, and its negative phase is smaller in magnitude), so each wave is
judged at each link midpoint and voxel centre exactly once: in the step whose
interval contains its arrival. The front's radius at the step's start and end
bounds a shell; only points inside it are tested, so no voxel is skipped
whatever the step, and the cost is one distance per alive link per charge.

Yield model (Mazarak 1999 §3.3, Martins 2001 §4.2):
- a link breaks if the peak overpressure exceeds its yield limit reduced by the
  orientation factor, Y (1 - k |R_hat . l_hat|): links parallel to the wave's
  radius are weaker; otherwise its yield drops by ``weakening`` x peak, so later
  waves find it damaged (persistent across charges);
- a voxel turns to dust if the peak at its centre exceeds its voxel yield, else
  its yield drops the same way;
- a foundation voxel's foundation yield is diminished by the peak; at zero or
  below it stops being a foundation.

Damage model (Davison & Stevens, Mazarak 1999 §2.2, §3.3): see
:func:`fracture_damage`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from blastvox.blast.face_load import face_load_nb, face_params_at
from blastvox.geometry.transforms_nb import to_world_into
from blastvox.jit import helper, kernel, parallel_kernel
from blastvox.simulate.arrivals import arrivals, crossing, order_free, wave_order
from blastvox.simulate.clearing import exposure_of
from blastvox.simulate.criteria import (
    REFERENCE_THICKNESS,
    crushes,
    oriented_yield,
    pi_exceeded,
)
from blastvox.simulate.diffraction import Detour
from blastvox.simulate.kernels import hold, release_held
from blastvox.simulate.members import MEMBER_NORMALS, edge_on, effective_thickness
from blastvox.simulate.model import link_factor
from blastvox.simulate.shell import mark_in_shell
from blastvox.simulate.shielding import Occupancy, remove_voxel, sight_line
from blastvox.simulate.state import Exposure, Front, WaveViews, hold_room
from blastvox.simulate.topology import refresh_fixed
from blastvox.simulate.wave import exceedance_integral, peak_overpressure


class FractureParams(NamedTuple):
    """orientation: k of the orientation factor (0..1); weakening: fraction of a
    peak that wears a link's or voxel's yield; damage_b, damage_c: the
    Davison-Stevens B (-) and C (1/(Pa s)); pressure_impulse: judge by the
    pressure-impulse criterion on the face load (else the papers' incident peak);
    judge_links: links break by the wave's load (else by the damage model)."""

    orientation: float
    weakening: float
    damage_b: float
    damage_c: float
    pressure_impulse: bool
    judge_links: bool


#: A neighbour is in front of a voxel (between it and the charge) when the line from the
#: voxel to it is within 45 degrees of the line to the charge.
FRONT_COSINE = math.sqrt(0.5)


@helper
def element_view(front, c, r, centre, exposure, b, member, speed, normal):
    """(peak overpressure Pa, positive impulse Pa s, depth m, blocked, thickness m,
    squeezed, cosine) that the wave of charge c puts on the element holding the point
    ``centre`` (3,) m (in solid, at r m from the charge, in body b): the face load
    (:func:`blastvox.blast.face_load.face_load_nb`) of the surface the line from the
    point to the charge leaves the element through, at that surface's angle of
    incidence, or the diffracted load if solid shields the element (blocked); depth:
    the point's depth below that surface (half a grid cell when it is not in the
    grid); thickness: the member's (``member`` m, :mod:`blastvox.simulate.members`)
    that resists this load, at most ``speed`` (m/s) x its positive phase; squeezed:
    the line runs along the member (normal (3,), its unit normal in the world) and
    leaves it through an edge (:func:`~blastvox.simulate.members.edge_on`): its
    faces take the wave at grazing incidence (what wears it and its foundation),
    and it is not bent; cosine: of the angle of incidence on that surface (0 squeezed)."""
    grid = exposure.grid
    px, py, pz = centre[0], centre[1], centre[2]
    qx, qy, qz = front.position[c, 0], front.position[c, 1], front.position[c, 2]
    blocked, axis, depth = sight_line(grid, px, py, pz, qx, qy, qz, True)
    cos_a = 1.0
    if axis >= 0 and r > 0.0:
        cos_a = abs((qx - px) if axis == 0 else ((qy - py) if axis == 1 else (qz - pz))) / r
    if axis < 0:
        depth = 0.5 * grid.cell[0]
    (ps, _, td, bb, imp, pr, ir, q, u, _, _,
     _) = face_params_at(front.table, front.burst[c], r, front.scale[c])
    squeezed = edge_on(normal, axis, depth, member)
    if squeezed:  # its faces see the wave sweep along them, at grazing incidence
        cos_a = 0.0
    i_pos, p_peak = face_load_nb((ps, td, bb, imp, pr, ir, q, u), cos_a, not blocked,
                                 exposure.clearing[b, c, 0], exposure.clearing[b, c, 1])
    return (p_peak, i_pos, depth, blocked, effective_thickness(member, speed, td), squeezed,
            cos_a)


@helper
def _member_normal(body_rot, b, normals, axis, out) -> None:
    """out (3,): the unit normal ``normals[axis]`` of a voxel's member, turned with its
    body b."""
    for a in range(3):
        out[a] = (body_rot[b, a, 0] * normals[axis, 0] + body_rot[b, a, 1] * normals[axis, 1]
                  + body_rot[b, a, 2] * normals[axis, 2])


class AheadViews(NamedTuple):
    """Element views of the voxels a step's fronts cross, worked out before the step
    judges them (:func:`views_ahead`), (K, C) for the K voxels of its ``order``:
    known, the front crosses the voxel this step (then the rest is its
    :func:`element_view`): peak Pa, impulse Pa s, depth m, blocked, thickness m,
    squeezed, cosine."""

    known: np.ndarray
    peak: np.ndarray
    impulse: np.ndarray
    depth: np.ndarray
    blocked: np.ndarray
    thickness: np.ndarray
    squeezed: np.ndarray
    cosine: np.ndarray


#: Voxels per task of :func:`_views_ahead`'s parallel loop (each voxel's view is its own:
#: any split gives the same bytes).
AHEAD_CHUNK = 256


def views_ahead(front: Front, geometry, members: tuple, bodies, voxel_body: np.ndarray,
                exposure: Exposure, order: np.ndarray, ahead: AheadViews) -> None:
    """Fill ``ahead`` (an :class:`AheadViews` (K, C)) with the element view of every
    voxel of ``order`` (K,) for every charge whose front crosses it this step, on every
    core: the line of sight through the shielding grid is most of a wave's cost, and
    each voxel's is its own. :func:`fracture_wave` takes them, as it would work them
    out, until a voxel turns to dust and leaves the grid this step. members: the
    model's (thickness (N,) m, wave_speed (M,) m/s, material (N,), MEMBER_NORMALS (D, 3),
    member_axis (N,)); bodies: the
    state's Bodies (pos, rot, com read)."""
    # numba's parallel loops take arrays, not structs of arrays: the structs go in
    # as their fields and are built again inside
    _views_ahead(tuple(front), tuple(exposure.grid), tuple(exposure)[1:5],
                 tuple(exposure.detour), geometry.centroid, members,
                 (bodies.pos, bodies.rot, bodies.com), voxel_body, order, tuple(ahead))


@parallel_kernel
def _views_ahead(front_fields, grid_fields, exposure_fields, detour_fields, centroid, members,
                 poses, voxel_body, order, ahead_fields):
    """:func:`views_ahead`'s loop, each voxel of ``order`` on its own (see there); the
    structs come as tuples of their fields, unpacked before the loop."""
    position, time, scale, table, burst, inner, outer = front_fields
    origin, cell, dims, count, member, vertices, corners, slot, box_lo, box_hi = grid_fields
    clearing, gas, sight, reach = exposure_fields
    d_origin, d_cell, d_dims, d_extra, d_most, d_voxel = detour_fields
    thickness, speed, material, normals, member_axis = members
    body_pos, body_rot, body_com = poses
    known, peak, impulse, depth, blocked, thick, squeezed, cosine = ahead_fields
    n_chunks = (len(order) + AHEAD_CHUNK - 1) // AHEAD_CHUNK
    for chunk in nb.prange(n_chunks):  # the structs and scratch once per chunk, not voxel
        front = Front(position, time, scale, table, burst, inner, outer)
        exposure = Exposure(Occupancy(origin, cell, dims, count, member, vertices, corners,
                                      slot, box_lo, box_hi), clearing, gas, sight, reach,
                            Detour(d_origin, d_cell, d_dims, d_extra, d_most, d_voxel))
        centre = np.empty(3)
        normal = np.empty(3)
        for i in range(chunk * AHEAD_CHUNK, min((chunk + 1) * AHEAD_CHUNK, len(order))):
            v = order[i]
            b = voxel_body[v]
            to_world_into(body_rot[b], body_pos[b], body_com[b], centroid[v], centre)
            for c in range(position.shape[0]):
                r = crossing(centre, position, inner, outer, c)
                known[i, c] = r >= 0.0
                if r < 0.0:
                    continue
                for a in range(3):  # the member's normal, turned with its body
                    normal[a] = (body_rot[b, a, 0] * normals[member_axis[v], 0]
                                 + body_rot[b, a, 1] * normals[member_axis[v], 1]
                                 + body_rot[b, a, 2] * normals[member_axis[v], 2])
                (peak[i, c], impulse[i, c], depth[i, c], blocked[i, c], thick[i, c],
                 squeezed[i, c], cosine[i, c]) = element_view(
                     front, c, r, centre, exposure, b, thickness[v], speed[material[v]],
                     normal)


def no_views_ahead(n_charges: int) -> AheadViews:
    """An empty :class:`AheadViews` (the damage and papers' models need none)."""
    empty = np.zeros((0, n_charges))
    flag = np.zeros((0, n_charges), dtype=bool)
    return AheadViews(flag, empty, empty, empty, flag, empty, flag, empty)


@kernel
def fracture_wave(front, params, parts, run_state, order, rows, exposure, views, ahead):
    """Judge each voxel a front crosses this step, then the links it is the second end
    of to be judged, once per wave: dust, break or weaken them; wear foundations.

    order (K,) int64: the voxels a front crosses this step, the only ones tested, in
    order of the wave's arrival (:func:`~blastvox.simulate.arrivals.wave_order`),
    or of their index when that gives the same bytes
    (:func:`~blastvox.simulate.arrivals.order_free`); rows (K,) int64: each one's row
    of ``ahead``. parts: the model's
    (VoxelGeometry, LinkGeometry, Strength, members); run_state: the state's
    (Links, Voxels, Bodies, Marks, Loads). Each (voxel, charge)
    is judged once in a run, when that charge's front crosses it: its element view
    (:func:`element_view`, one line of sight) is kept in ``views``
    (a :class:`~blastvox.simulate.state.WaveViews`), and a link is judged when the
    second of its two ends is, on the geometric mean of their views (peak and impulse:
    the value at the midpoint of a power-law decay) and
    the thinner of their members (members: the model's (thickness (N,) m,
    wave_speed (M,) m/s of each material, material (N,), MEMBER_NORMALS (D, 3),
    member_axis (N,): each voxel's row of it, the unit normal of its member)); a link
    with an end squeezed between the faces of a member the wave sweeps along
    (:func:`element_view`) is not bent by it, only worn. With params.judge_links False
    (the damage model) only voxels are judged. The cost is one line of sight per voxel
    and wave and O(1) per link (there were two per link and step, one of them through
    all the solid behind the link). The lines of sight are worked out ahead, on every core
    (:func:`views_ahead`, ``ahead``); once a voxel turns to dust this step, the views
    after it are worked out here again, as it changed the grid.

    A voxel dusted under pressure-impulse fracture leaves the shielding grid at
    once, so the points behind it see the gap (the same whatever the step). In every
    fracture model a dusted voxel leaves with the net impulse of the wave on its face
    towards the charge (its element view's, :func:`element_view`, whatever the model
    judged it by) in loads.held_p (N s, replacing what it held; handed to its dust
    body by the split, which starts it at its body's velocity at its place): dust
    carries the momentum its voxel had and that of the wave that destroyed it. That
    impulse goes through the face once: the dust's neighbours mark the face they
    shared with it in loads.shadow (the blast no longer loads it), and a voxel dusted
    behind dust of the current waves shares, by mass, the impulse the dust in front
    of it still holds (none if that has left: each layer of a crater took the whole
    impulse again, and a wall pulverized in four layers left with four times the
    momentum of one in two).

    Returns (foundation voxels that let go, links broken). marks.destroyed (N,)
    marks dusted voxels, marks.crossed (N,) every voxel a front crossed this step
    (for dust cues), marks.broken (L,) the links broken, marks.dirty (B,) their
    bodies.
    """
    geometry, link_geometry, strength, (thickness, speed, material, normals,
                                        member_axis) = parts
    links, voxels, bodies, marks, loads = run_state
    charge_pos, charge_scale, table = front.position, front.scale, front.table
    front_in, front_out, weakening = front.inner, front.outer, params.weakening
    voxel_centroid = geometry.centroid
    voxel_alive, voxel_yield, voxel_body = voxels.alive, voxels.yield_pa, voxels.body
    voxel_foundation, voxel_foundation_yield = voxels.foundation, voxels.foundation_pa
    body_pos, body_rot, body_com = bodies.pos, bodies.rot, bodies.com
    destroyed, dirty, crossed = marks.destroyed, marks.dirty, marks.crossed
    link_voxels, link_midpoint = link_geometry.voxels, link_geometry.midpoint
    link_direction = link_geometry.direction
    released = 0
    broken = 0
    n_charges = charge_pos.shape[0]
    centre = np.empty(3)
    normal = np.empty(3)
    gap = False  # a voxel turned to dust and left the grid: views ahead are stale
    for i in range(len(order)):
        v = order[i]
        b = voxel_body[v]
        to_world_into(body_rot[b], body_pos[b], body_com[b], voxel_centroid[v], centre)
        cx, cy, cz = centre[0], centre[1], centre[2]
        for c in range(n_charges):
            r = crossing(centre, charge_pos, front_in, front_out, c)
            if r < 0.0:
                continue
            if params.pressure_impulse:
                if gap:  # dust opened the grid this step: the view ahead is stale
                    _member_normal(body_rot, b, normals, member_axis[v], normal)
                    peak, imp, depth, blocked, thick, squeezed, cos_a = element_view(
                        front, c, r, centre, exposure, b, thickness[v], speed[material[v]],
                        normal)
                else:
                    j = rows[i]
                    peak, imp, depth = ahead.peak[j, c], ahead.impulse[j, c], ahead.depth[j, c]
                    blocked, thick = ahead.blocked[j, c], ahead.thickness[j, c]
                    squeezed, cos_a = ahead.squeezed[j, c], ahead.cosine[j, c]
                # pulverizing starts at the loaded surface: a deeper voxel is reached once
                # those in front of it have gone (in order of arrival)
                i0 = strength.voxel_impulse[strength.material[v]] * thick / REFERENCE_THICKNESS
                surface = depth <= 2.0 * geometry.contact_radius[v]
                breaks = surface and pi_exceeded(
                    peak, imp, voxel_yield[v], i0, strength.pi_shape[strength.material[v]])
                crushed = surface and not blocked and crushes(
                    front, c, r - depth, cos_a, exposure, b, strength, strength.material[v],
                    thick)
            else:
                peak = peak_overpressure(table[front.burst[c]], r, charge_scale[c])
                imp, blocked, thick, i0, squeezed = 0.0, False, thickness[v], 0.0, False
                breaks, crushed = peak > voxel_yield[v], False
            views.known[v, c] = True
            views.peak[v, c], views.impulse[v, c] = peak, imp
            views.blocked[v, c], views.thickness[v, c] = blocked, thick
            views.squeezed[v, c] = squeezed
            crossed[v] = True
            if breaks and not crushed and params.pressure_impulse and (
                    strength.shatter_pa[v] > 0.0) and not (
                    pi_exceeded(peak, imp, strength.shatter_pa[v], i0,
                                strength.pi_shape[strength.material[v]])):
                # failed, not crushed: a voxel as large as the material's rubble comes off
                # whole (the split frees it with the impulse its body held for it)
                broken += _shatter(v, geometry, links, marks, b)
                break
            if breaks or crushed:
                voxel_alive[v] = False
                destroyed[v] = True
                dirty[b] = True
                if params.pressure_impulse:
                    remove_voxel(exposure.grid, geometry, v)
                    gap = True
                else:  # judged on the incident peak: the wave's load on its face all the same
                    _member_normal(body_rot, b, normals, member_axis[v], normal)
                    imp = element_view(front, c, r, centre, exposure, b, thickness[v],
                                       speed[material[v]], normal)[1]
                i_neg = face_params_at(front.table, front.burst[c], r, front.scale[c])[10]
                area = (2.0 * geometry.contact_radius[v]) ** 2
                row = hold(loads, v)
                for a in range(3):  # a voxel centred on the charge: pushed evenly
                    loads.held_p[row, a] = (imp - i_neg) * area * (
                        centre[a] - charge_pos[c, a]) / r if r > 0.0 else 0.0
                    loads.held_l[row, a] = 0.0
                _dust_once(v, geometry, link_geometry, voxels.alive, loads, body_rot[b],
                           cx - charge_pos[c, 0], cy - charge_pos[c, 1], cz - charge_pos[c, 2])
                break
            voxel_yield[v] = max(0.0, voxel_yield[v] - weakening * peak)
            if voxel_foundation[v]:
                voxel_foundation_yield[v] -= peak
                if voxel_foundation_yield[v] <= 0.0:
                    voxel_foundation[v] = False
                    released += 1
            if not params.judge_links:
                continue
            # the links whose other end this wave has judged: inline, as calls that take
            # the model's structs cost each array two reference counts per call
            for k in range(geometry.link_offsets[v], geometry.link_offsets[v + 1]):
                link = geometry.link_ids[k]
                if not links.alive[link]:
                    continue
                w = link_voxels[link, 1] if link_voxels[link, 0] == v else link_voxels[link, 0]
                if not voxel_alive[w] or not views.known[w, c]:
                    continue
                x = link_midpoint[link, 0] - body_com[b, 0]
                y = link_midpoint[link, 1] - body_com[b, 1]
                z = link_midpoint[link, 2] - body_com[b, 2]
                dx = (body_pos[b, 0] + body_rot[b, 0, 0] * x + body_rot[b, 0, 1] * y
                      + body_rot[b, 0, 2] * z - charge_pos[c, 0])
                dy = (body_pos[b, 1] + body_rot[b, 1, 0] * x + body_rot[b, 1, 1] * y
                      + body_rot[b, 1, 2] * z - charge_pos[c, 1])
                dz = (body_pos[b, 2] + body_rot[b, 2, 0] * x + body_rot[b, 2, 1] * y
                      + body_rot[b, 2, 2] * z - charge_pos[c, 2])
                rm = math.sqrt(dx * dx + dy * dy + dz * dz)
                limit = oriented_yield(links.yield_pa[link], params.orientation, body_rot, b,
                                       link_direction, link, dx, dy, dz, rm)
                if params.pressure_impulse and (views.squeezed[v, c] or views.squeezed[w, c]):
                    # squeezed between its faces' pressures, not bent: only worn
                    peak, breaks = math.sqrt(views.peak[v, c] * views.peak[w, c]), False
                elif params.pressure_impulse:
                    peak = math.sqrt(views.peak[v, c] * views.peak[w, c])
                    imp = math.sqrt(views.impulse[v, c] * views.impulse[w, c])
                    gas = exposure.gas[c, 0]  # gas breaks walls, it does not pulverize them
                    if gas > 0.0 and not (views.blocked[v, c] and views.blocked[w, c]):
                        peak = max(peak, gas)
                        imp += gas * exposure.gas[c, 1]
                    owner = link_voxels[link, 0]
                    i0 = (strength.link_impulse[strength.material[owner]]
                          * link_factor(strength, link_voxels, link)
                          * min(views.thickness[v, c], views.thickness[w, c])
                          / REFERENCE_THICKNESS)
                    # a chunk of a material that crushes comes apart only as dust
                    breaks = not strength.inner[link] and pi_exceeded(
                        peak, imp, limit, i0, strength.pi_shape[strength.material[owner]])
                else:
                    peak = peak_overpressure(table[front.burst[c]], rm, charge_scale[c])
                    breaks = peak > limit
                if breaks:
                    links.alive[link] = False
                    marks.broken[link] = True
                    dirty[b] = True
                    broken += 1
                else:
                    links.yield_pa[link] = max(0.0, links.yield_pa[link] - weakening * peak)
    return released, broken


@helper
def _shatter(v, geometry, links, marks, b) -> int:
    """Break every alive link of voxel v (of body b), marked like the wave's breaks;
    returns how many."""
    count = 0
    for k in range(geometry.link_offsets[v], geometry.link_offsets[v + 1]):
        link = geometry.link_ids[k]
        if links.alive[link]:
            links.alive[link] = False
            marks.broken[link] = True
            count += 1
    if count:
        marks.dirty[b] = True
    return count


@helper
def _dust_once(v, geometry, links, voxel_alive, loads, rot, rx, ry, rz) -> None:
    """Voxel v just turned to dust, its wave's impulse in its row of loads.held_p; rot
    (3, 3): its body's rotation; (rx, ry, rz): from the charge to v, m, world. Marks
    the face each neighbour shared with v in loads.shadow; if a face of v towards the
    charge is shadowed (dust of the current waves in front of v), v takes no impulse
    of its own but a share, by mass, of what that dust still holds (see
    :func:`fracture_voxels`)."""
    offsets, ids, link_voxels, link_face = (geometry.link_offsets, geometry.link_ids,
                                            links.voxels, links.face)
    shadow, held, slot = loads.shadow, loads.held_p, loads.held_slot
    front = -1
    for k in range(offsets[v], offsets[v + 1]):
        link = ids[k]
        first = link_voxels[link, 0] == v
        w = link_voxels[link, 1] if first else link_voxels[link, 0]
        face_v = link_face[link] if first else link_face[link] - 1
        face_w = link_face[link] - 1 if first else link_face[link]
        shadow[w] |= np.uint8(1 << face_w)
        # w is in front of v if it lies towards the charge (within 45 degrees of the line
        # to it: not a neighbour beside v in the same layer)
        if not (shadow[v] >> face_v) & 1:
            continue
        cw, cv = geometry.centroid[w], geometry.centroid[v]
        dx, dy, dz = cw[0] - cv[0], cw[1] - cv[1], cw[2] - cv[2]  # rest frame
        along = ((rot[0, 0] * dx + rot[0, 1] * dy + rot[0, 2] * dz) * rx
                 + (rot[1, 0] * dx + rot[1, 1] * dy + rot[1, 2] * dz) * ry
                 + (rot[2, 0] * dx + rot[2, 1] * dy + rot[2, 2] * dz) * rz)
        if along < -FRONT_COSINE * math.sqrt((dx * dx + dy * dy + dz * dz)
                                             * (rx * rx + ry * ry + rz * rz)):
            front = w
    if front < 0:
        return
    own = slot[v]  # v holds a row: its dusting gave it one
    for a in range(3):
        held[own, a] = 0.0
    there = slot[front]
    if voxel_alive[front] or there < 0 or (held[there, 0] == 0.0 and held[there, 1] == 0.0
                                           and held[there, 2] == 0.0):
        return  # that dust has left with it
    mv, mf = geometry.mass[v], geometry.mass[front]
    for a in range(3):
        held[own, a] = held[there, a] * mv / (mv + mf)
        held[there, a] -= held[own, a]


@kernel
def fracture_damage(front, params, geometry, link_geometry, links, voxels, bodies,
                    marks) -> int:
    """Davison-Stevens compound damage accumulation (Mazarak 1999 eqs. 2.2, 3.2).

    When a wave reaches a voxel, its damage grows by
    dD = B D* [exp(C S) - 1] with D* = 6 (links a voxel can lose) and
    S = integral of <p(t) - Y> dt over the wave (Pa s), Y the mean yield of the
    voxel's alive links and <x> = (x + |x|)/2. floor(D) is the number of links
    the voxel should have lost; the weakest remaining ones (orientation-adjusted
    yield) break. Returns the number of links broken.
    """
    charge_pos, charge_scale, table = front.position, front.scale, front.table
    front_in, front_out = front.inner, front.outer
    damage_b, damage_c, orientation = params.damage_b, params.damage_c, params.orientation
    voxel_centroid, voxel_link_offsets, voxel_link_ids = (geometry.centroid,
                                                          geometry.link_offsets, geometry.link_ids)
    link_direction = link_geometry.direction
    voxel_alive, voxel_damage, voxel_body = voxels.alive, voxels.damage, voxels.body
    link_alive, link_yield = links.alive, links.yield_pa
    body_pos, body_rot, body_com = bodies.pos, bodies.rot, bodies.com
    active, broken, dirty = marks.active, marks.broken, marks.dirty
    count = 0
    centre = np.empty(3)
    for v in range(voxel_centroid.shape[0]):
        if not voxel_alive[v]:
            continue
        b = voxel_body[v]
        if not active[b]:
            continue
        to_world_into(body_rot[b], body_pos[b], body_com[b], voxel_centroid[v], centre)
        for c in range(charge_pos.shape[0]):
            r = crossing(centre, charge_pos, front_in, front_out, c)
            if r < 0.0:
                continue
            total = 0.0
            alive = 0
            for k in range(voxel_link_offsets[v], voxel_link_offsets[v + 1]):
                link = voxel_link_ids[k]
                if link_alive[link]:
                    total += link_yield[link]
                    alive += 1
            if alive == 0:
                continue
            s = exceedance_integral(table[front.burst[c]], r, charge_scale[c], total / alive)
            if s <= 0.0:
                continue
            before = math.floor(voxel_damage[v])
            voxel_damage[v] = min(6.0, voxel_damage[v] + damage_b * 6.0
                                  * (math.exp(min(damage_c * s, 50.0)) - 1.0))
            to_break = int(math.floor(voxel_damage[v]) - before)
            for _ in range(to_break):
                weakest = -1
                weakest_limit = np.inf
                for k in range(voxel_link_offsets[v], voxel_link_offsets[v + 1]):
                    link = voxel_link_ids[k]
                    if not link_alive[link]:
                        continue
                    limit = oriented_yield(link_yield[link], orientation, body_rot, b,
                                           link_direction, link, centre[0] - charge_pos[c, 0],
                                           centre[1] - charge_pos[c, 1],
                                           centre[2] - charge_pos[c, 2], r)
                    if limit < weakest_limit:
                        weakest_limit = limit
                        weakest = link
                if weakest < 0:
                    break
                link_alive[weakest] = False
                broken[weakest] = True
                dirty[b] = True
                count += 1
    return count


def fracture_phase(model, state, front, settings, gas: np.ndarray | None = None) -> None:
    """Phase: links and voxels the fronts cross this step break, dust or weaken.

    Reads the front (a :class:`~blastvox.simulate.state.Front`), the bodies'
    poses and marks.active; writes links (alive, yield), voxels (alive, yield,
    foundation, damage), marks (broken, destroyed, crossed, dirty; cleared
    first) and, when a foundation lets go, bodies.fixed and the held impulses.
    ``settings``: the run's SimSettings (fracture model and its constants); gas
    (C, 2): the charges' room gas pressures and vent times (see
    :class:`~blastvox.simulate.state.Exposure`).
    """
    marks, s = state.marks, settings
    marks.broken[:] = False
    marks.destroyed[:] = False
    marks.crossed[:] = False
    marks.dirty[:state.n_bodies] = False
    params = FractureParams(s.orientation_factor, s.weakening, s.damage_b, s.damage_c,
                            s.fracture == "pressure-impulse", s.fracture != "damage")
    exposure = exposure_of(model, state, front.position, marks.active, gas)
    candidate = _candidates(model, state, model.voxel_grid, state.scratch.voxel_owner,
                            state.scratch.voxel_candidate, front)
    ids, when = arrivals(front, model.voxels.centroid, state.voxels, state.bodies, candidate,
                          marks.active)
    members = (model.thickness, model.wave_speed, model.material, MEMBER_NORMALS,
               model.member_axis)
    parts = (model.voxels, model.links, model.strength, members)
    hold_room(state, len(ids))  # each voxel it dusts holds its impulse (new loads arrays)
    run_state = (state.links, state.voxels, state.bodies, marks, state.loads)
    ahead = no_views_ahead(len(front.position))
    if params.pressure_impulse and len(ids):
        k, c = len(ids), len(front.position)
        ahead = AheadViews(np.zeros((k, c), dtype=bool), np.empty((k, c)), np.empty((k, c)),
                           np.empty((k, c)), np.zeros((k, c), dtype=bool), np.empty((k, c)),
                           np.zeros((k, c), dtype=bool), np.empty((k, c)))
        views_ahead(front, model.voxels, members, state.bodies, state.voxels.body, exposure,
                    ids, ahead)
    order, rows = wave_order(ids, when, params.pressure_impulse and len(ids) > 0 and order_free(
        front, parts, run_state, ids, exposure, ahead))
    released, n = fracture_wave(front, params, parts, run_state, order, rows, exposure,
                                wave_views(state, len(front.position)), ahead)
    if marks.destroyed.any():
        state.holding = True  # the split hands the dust its impulse (release_held)
    if s.fracture == "damage":
        n = fracture_damage(front, params, model.voxels, model.links, state.links,
                            state.voxels, state.bodies, marks)
    if params.pressure_impulse and (n or marks.destroyed.any()):
        n += whole_interfaces(model, state)
    state.counters.broken_links += int(n)
    if released:
        refresh_fixed(state.voxels, state.bodies)
        if state.holding:
            release_held(model.voxels, state.voxels, state.bodies, state.loads)


def wave_views(state, n_charges: int):
    """The run's :class:`~blastvox.simulate.state.WaveViews` (N, C), made on first use
    and kept in state.caches."""
    caches = state.caches
    n = len(state.voxels.alive)
    if caches.views is None or caches.views.known.shape[1] != n_charges:
        caches.views = WaveViews(np.zeros((n, n_charges), dtype=bool), np.zeros((n, n_charges)),
                                 np.zeros((n, n_charges)), np.zeros((n, n_charges), dtype=bool),
                                 np.zeros((n, n_charges)), np.zeros((n, n_charges), dtype=bool))
    return caches.views


#: A crack that has run through this fraction of an interface between two chunks runs
#: through the rest of it (what is left carries the load the broken part shed).
INTERFACE_RUN = 0.5


def whole_interfaces(model, state) -> int:
    """Break the rest of every chunk interface (model.strength.interface) whose links
    the step broke (marks.broken) or cut with dust (marks.destroyed) up to
    :data:`INTERFACE_RUN` of them; returns how many links it broke (marked like the
    fracture's, their bodies dirty). Whether broken or dusted first, in one step or
    in several, the same interfaces run."""
    interface, marks, alive = model.strength.interface, state.marks, state.links.alive
    cut = marks.broken
    if marks.destroyed.any():  # links that died with dust cut an interface as well
        cut = cut | marks.destroyed[model.links.voxels].any(axis=1)
    hit = np.unique(interface[cut])
    hit = hit[hit >= 0]
    if not hit.size:
        return 0
    links = np.flatnonzero(np.isin(interface, hit))
    group = np.searchsorted(hit, interface[links])
    ends = model.links.voxels[links]  # a link of a voxel dusted this step is gone too
    still = alive[links] & state.voxels.alive[ends[:, 0]] & state.voxels.alive[ends[:, 1]]
    total = np.bincount(group, minlength=hit.size)
    standing = np.bincount(group, weights=still, minlength=hit.size)
    run = links[still & (standing[group] <= (1.0 - INTERFACE_RUN) * total[group])]
    if not run.size:
        return 0
    alive[run] = False
    marks.broken[run] = True
    marks.dirty[state.voxels.body[model.links.voxels[run, 0]]] = True
    return int(run.size)


def _candidates(model, state, grid, owner, out, front) -> np.ndarray:
    """Flag the grid's points that a front's shell can reach this step (see shell)."""
    out[:] = False
    mark_in_shell(grid, model.grid_cell, owner, state.voxels.body, state.marks.active,
                  state.bodies, front, out)
    return out
