"""Kernels shared by the step: small bookkeeping (rotations, link masks, sleep, the
blast's held impulses). The contact solver that the fragment and ground phases both
feed is :mod:`blastvox.simulate.contact.solver`.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.geometry.quaternion_nb import matrix_into
from blastvox.jit import helper, kernel
from blastvox.simulate.integrate import (
    angular_velocity,
    moving,
)


@kernel
def body_rotations(body_quat, body_live, n_bodies, out) -> None:
    """Rotation matrices ``out`` (B, 3, 3) of the first n_bodies live bodies' quaternions
    (B, 4): pass ``bodies.quat, bodies.live, state.n_bodies, bodies.rot``.

    This and the other per-step bookkeeping kernels below take the few body arrays
    they read rather than the Bodies container: a step calls them every time, and
    numba types a NamedTuple argument field by field on each call from Python
    (a few tenths of a microsecond per field), most of their cost on a small shot.
    """
    for b in range(n_bodies):
        if body_live[b]:
            matrix_into(body_quat[b], out[b])


@kernel
def link_masks(geometry, links, voxels) -> None:
    """Bit f of voxels.link_mask[v] set iff an alive link leaves voxel v across face f.

    geometry: the model's :class:`~blastvox.simulate.model.LinkGeometry`."""
    link_voxels, link_face = geometry.voxels, geometry.face
    link_alive, voxel_link_mask = links.alive, voxels.link_mask
    voxel_link_mask[:] = 0
    for link in range(link_voxels.shape[0]):
        if link_alive[link]:
            f = link_face[link]
            voxel_link_mask[link_voxels[link, 0]] |= np.uint8(1 << f)
            voxel_link_mask[link_voxels[link, 1]] |= np.uint8(1 << (f - 1))


@kernel
def link_alive_counts(offsets, link_ids, link_alive) -> np.ndarray:
    """Number of alive links per voxel (N,)."""
    n = offsets.shape[0] - 1
    out = np.zeros(n, dtype=np.int64)
    for v in range(n):
        for k in range(offsets[v], offsets[v + 1]):
            if link_alive[link_ids[k]]:
                out[v] += 1
    return out


@kernel
def bodies_in_shell(body_pos, body_radius, body_live, n_bodies, charge_pos, inner, outer,
                    out) -> bool:
    """Flag in ``out`` (B,) the live bodies whose bounding sphere (centre body_pos (B, 3),
    radius body_radius (B,), m) meets a charge's shell (inner, outer] (C,) m about
    charge_pos (C, 3).

    Returns whether any body does. Kernels then skip every voxel and link of
    unflagged bodies, so a step costs nothing once the waves have passed.
    """
    found = False
    for b in range(n_bodies):
        out[b] = False
        if not body_live[b]:
            continue
        for c in range(charge_pos.shape[0]):
            if outer[c] <= 0.0:
                continue
            d = math.sqrt((body_pos[b, 0] - charge_pos[c, 0]) ** 2
                          + (body_pos[b, 1] - charge_pos[c, 1]) ** 2
                          + (body_pos[b, 2] - charge_pos[c, 2]) ** 2)
            if d - body_radius[b] <= outer[c] and d + body_radius[b] > inner[c]:
                out[b] = True
                found = True
                break
    return found


@kernel
def body_radii(geometry, voxels, bodies) -> None:
    """bodies.radius: a sphere (m) about each body's centre of mass holding all its voxels."""
    voxel_body, voxel_centroid, voxel_radius = voxels.body, geometry.centroid, geometry.radius
    body_com, body_radius, n_bodies = bodies.com, bodies.radius, bodies.count[0]
    for b in range(n_bodies):
        body_radius[b] = 0.0
    for v in range(voxel_body.shape[0]):
        b = voxel_body[v]
        d = math.sqrt((voxel_centroid[v, 0] - body_com[b, 0]) ** 2
                      + (voxel_centroid[v, 1] - body_com[b, 1]) ** 2
                      + (voxel_centroid[v, 2] - body_com[b, 2]) ** 2) + voxel_radius[v]
        if d > body_radius[b]:
            body_radius[b] = d


@kernel
def any_moving(body_live, body_fixed, body_dust, body_asleep, n_bodies) -> bool:
    """Is any of the first n_bodies bodies free to move (live, not fixed, not dust, awake)?"""
    for b in range(n_bodies):
        if moving(b, body_live, body_fixed, body_dust, body_asleep):
            return True
    return False


@kernel
def wake_on_impulse(impulse, angular, body_asleep, n_bodies) -> None:
    """A sleeping body that the blast pushes (impulse, angular (B, 3)) wakes up."""
    for b in range(n_bodies):
        if body_asleep[b] and (impulse[b, 0] != 0.0 or impulse[b, 1] != 0.0
                               or impulse[b, 2] != 0.0 or angular[b, 0] != 0.0
                               or angular[b, 1] != 0.0 or angular[b, 2] != 0.0):
            body_asleep[b] = False


@kernel
def settle(bodies, sleep_speed, still_steps, balanced) -> None:
    """Put to sleep bodies that have stayed slower than ``sleep_speed`` (m/s, at their
    rim) for ``still_steps`` steps in a row and stand balanced (balanced (B,) bool,
    :func:`~blastvox.simulate.contact.balance.balance`): debris resting on other debris
    or on a structure (the ground contact clamps balanced bodies sooner). A body held
    up by friction alone, wedged or leaning, stays awake: it may still slide or tip
    (issue 34)."""
    body_mass, body_inv_inertia, body_rot = bodies.mass, bodies.inv_inertia, bodies.rot
    body_lin, body_ang, body_radius = bodies.lin, bodies.ang, bodies.radius
    body_fixed = bodies.fixed
    body_live, body_dust, body_asleep = bodies.live, bodies.dust, bodies.asleep
    body_still, n_bodies = bodies.still, bodies.count[0]
    for b in range(n_bodies):
        if not body_live[b] or body_fixed[b] or body_dust[b] or body_asleep[b]:
            body_still[b] = 0
            continue
        m = body_mass[b]
        speed = math.sqrt(body_lin[b, 0] ** 2 + body_lin[b, 1] ** 2 + body_lin[b, 2] ** 2) / m
        wx, wy, wz = angular_velocity(body_rot[b], body_inv_inertia[b], body_ang[b])
        spin = math.sqrt(wx * wx + wy * wy + wz * wz) * body_radius[b]
        if speed < sleep_speed and spin < sleep_speed:
            body_still[b] += 1
            if body_still[b] >= still_steps and balanced[b]:
                body_asleep[b] = True
                body_still[b] = 0
                for a in range(3):
                    body_lin[b, a] = 0.0
                    body_ang[b, a] = 0.0
        else:
            body_still[b] = 0


@kernel
def damage_levels(offsets, link_alive_count, voxel_yield, initial_yield, voxel_damage,
                  voxel_alive, out) -> None:
    """Per-voxel damage 0..1 quantised to 0..255 into ``out`` (N,) uint8.

    Damage is the largest of: the fraction of the voxel's links broken, the
    fraction of its yield worn away, and Davison-Stevens damage / 6 (six
    links' worth); 1 for a destroyed voxel. Rounded half to even.
    """
    for v in range(out.shape[0]):
        if not voxel_alive[v]:
            out[v] = 255
            continue
        total = offsets[v + 1] - offsets[v]
        damage = (total - link_alive_count[v]) / total if total > 0 else 0.0
        y0 = initial_yield[v]
        if math.isfinite(y0) and y0 > 0.0:
            damage = max(damage, 1.0 - voxel_yield[v] / y0)
        damage = min(max(damage, voxel_damage[v] / 6.0, 0.0), 1.0)
        out[v] = np.uint8(np.rint(damage * 255.0))


@helper
def hold(loads, v) -> int:
    """Voxel v's row in the held impulses (:class:`~blastvox.simulate.state.Loads`), a
    new one (zero) if it holds none yet: the caller made room
    (:func:`~blastvox.simulate.state.hold_room`)."""
    row = np.int64(loads.held_slot[v])
    if row < 0:
        row = loads.held_count[0]
        loads.held_count[0] += 1
        loads.held_slot[v] = row
        loads.held_voxel[row] = v
    return row


@kernel
def release_held(geometry, voxels, bodies, loads) -> None:
    """Give each freed piece the blast impulse its voxels took while they were held.

    loads.held_p, held_l: impulse (N s) and angular impulse about the voxel
    centroid (N m s) a voxel took while its body was fixed (see
    :func:`blastvox.simulate.forces.blast_impulses`), by row
    (:class:`~blastvox.simulate.state.Loads`). A voxel whose body is now free (split
    off, or its foundation let go) hands them to that body, about its centre of mass,
    and is cleared; voxel by voxel, in order.
    """
    voxel_body, voxel_centroid, slot = voxels.body, geometry.centroid, loads.held_slot
    held_p, held_l = loads.held_p, loads.held_l
    body_fixed, body_live, body_com = bodies.fixed, bodies.live, bodies.com
    body_rot, body_lin, body_ang = bodies.rot, bodies.lin, bodies.ang
    for v in range(voxel_body.shape[0]):
        s = slot[v]
        if s < 0:
            continue
        if held_p[s, 0] == 0.0 and held_p[s, 1] == 0.0 and held_p[s, 2] == 0.0 \
                and held_l[s, 0] == 0.0 and held_l[s, 1] == 0.0 and held_l[s, 2] == 0.0:
            continue
        b = voxel_body[v]
        if body_fixed[b] or not body_live[b]:
            continue
        if not voxels.alive[v] and not bodies.dust[b]:
            continue  # a dusted voxel's impulse waits for the split to give it its dust body
        rot = body_rot[b]
        x = voxel_centroid[v, 0] - body_com[b, 0]
        y = voxel_centroid[v, 1] - body_com[b, 1]
        z = voxel_centroid[v, 2] - body_com[b, 2]
        rx = rot[0, 0] * x + rot[0, 1] * y + rot[0, 2] * z
        ry = rot[1, 0] * x + rot[1, 1] * y + rot[1, 2] * z
        rz = rot[2, 0] * x + rot[2, 1] * y + rot[2, 2] * z
        px, py, pz = held_p[s, 0], held_p[s, 1], held_p[s, 2]
        body_lin[b, 0] += px
        body_lin[b, 1] += py
        body_lin[b, 2] += pz
        body_ang[b, 0] += ry * pz - rz * py + held_l[s, 0]
        body_ang[b, 1] += rz * px - rx * pz + held_l[s, 1]
        body_ang[b, 2] += rx * py - ry * px + held_l[s, 2]
        for a in range(3):
            held_p[s, a] = 0.0
            held_l[s, a] = 0.0

