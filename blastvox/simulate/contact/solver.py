"""The contact solver that the fragment and ground phases both feed
(:func:`solve_contacts`, on the :class:`~blastvox.simulate.contact.rows.ContactRows` they
gather).

The soft step (Catto, "Solver2D", 2024; Box2D v3's solver): the step is cut into
sub-steps, each one sweep over the contact rows with a soft push-out (an implicit
spring-damper, stable at any step), the bodies moved, and one rigid sweep (relax)
that takes the push-out's speed back out, so interpenetrating bodies are pushed
apart by moving them, never by giving them momentum. Normal impulses >= 0, a
face's corners solved together; Coulomb friction and twisting friction at the
patch centre; warm started from the impulses the same contacts carried the
sub-step before; a restitution pass after the sub-steps. Islands of bodies that
touch are solved on their own, on every core, and a large island in parts side by
side (:func:`_solve_islands`, :mod:`~blastvox.simulate.contact.partition`); the
sweeps themselves are :mod:`~blastvox.simulate.contact.sweep`'s.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from blastvox.geometry import exact, quaternion_nb
from blastvox.jit import helper, kernel, parallel_kernel
from blastvox.simulate.contact.islands import islands
from blastvox.simulate.contact.partition import PARTS, cut_island
from blastvox.simulate.contact.restitution import restitution
from blastvox.simulate.contact.rows import ContactRows
from blastvox.simulate.contact.sweep import (
    island_substeps,
    kinetic_energy,
    move_bodies,
    push_speed,
    share_loads,
    soft_sweep,
    undo_solve,
    withhold_loads,
)
from blastvox.simulate.contact.warmstart import apply_carried, recall, remember
from blastvox.simulate.integrate import (
    RW_CA,
    RW_CB,
    RW_EFF,
    RW_K,
    RW_KN,
    RW_TARGET,
    RW_WIDTH,
    corner_speed,
    moving,
)

#: Natural frequency (Hz) and damping ratio of the soft push-out of contacts between
#: moving bodies (twice the frequency against immovable ones), Box2D v3's defaults:
#: an overdamped spring that removes a penetration over a few tens of milliseconds
#: whatever the step. The frequency is capped at a quarter of the sub-step rate.
CONTACT_HERTZ = 120.0
CONTACT_DAMPING = 10.0
#: The fastest a soft push-out moves bodies apart, m/s (Box2D v3's contactSpeed).
PUSH_SPEED = 1.0
#: Contacts only remove kinetic energy (their targets stop, or bounce with restitution
#: <= 1): every sweep is a descent. The warm start is not: in a jammed pile (a piece
#: wedged between others, contacts pushing from opposite sides) the impulses carried
#: from step to step can ratchet up while cancelling, until an unconverged solve lets
#: them loose (a sweep found 2.3 MJ given to a broken wall's pieces in one step, pieces
#: leaving at 90 m/s). A solve that ends with more kinetic energy than this fraction
#: above what it started with is done again without the warm start.
ENERGY_SLACK = 1e-6
#: ... and more than the island's mass would have at this speed (m/s) plus its fastest
#: push-out: what the rigid sweeps leave of a push-out is not a warm start's pump.
ENERGY_SPEED = 1e-3


@helper
def _prepare_row(r, rows, body_pos, ends, bw, rw) -> None:
    """Lever arms, effective masses and the corners' coupling matrix of row r (see
    :mod:`~blastvox.simulate.integrate`'s layout of rw)."""
    point, frame, body, corners, used = rows.point, rows.frame, rows.body, rows.corners, \
        rows.used[r]
    nx, ny, nz = frame[r, 0, 0], frame[r, 0, 1], frame[r, 0, 2]
    rw[r, :] = 0.0
    for side in range(2):
        e = ends[r, side]
        if e < 0:
            continue
        b = body[r, side]
        rx, ry, rz = (point[r, 0] - body_pos[b, 0], point[r, 1] - body_pos[b, 1],
                      point[r, 2] - body_pos[b, 2])
        rw[r, 3 * side], rw[r, 3 * side + 1], rw[r, 3 * side + 2] = rx, ry, rz
        for j in range(3):  # friction along t1, t2 at the centre, twist about n
            dx, dy, dz = frame[r, (j + 1) % 3, 0], frame[r, (j + 1) % 3, 1], \
                frame[r, (j + 1) % 3, 2]
            if j < 2:
                dx, dy, dz = ry * dz - rz * dy, rz * dx - rx * dz, rx * dy - ry * dx
                rw[r, RW_K + j] += bw[e, 12]
            rw[r, RW_K + j] += _quadratic(bw, e, dx, dy, dz, dx, dy, dz)
        o = RW_CA if side == 0 else RW_CB
        for i in range(used):
            qx, qy, qz = (corners[r, i, 0] - body_pos[b, 0], corners[r, i, 1] - body_pos[b, 1],
                          corners[r, i, 2] - body_pos[b, 2])
            rw[r, o + 3 * i] = qy * nz - qz * ny
            rw[r, o + 3 * i + 1] = qz * nx - qx * nz
            rw[r, o + 3 * i + 2] = qx * ny - qy * nx
        for i in range(used):
            for j in range(i, used):
                rw[r, RW_KN + i * (7 - i) // 2 + j] += bw[e, 12] + _quadratic(
                    bw, e, rw[r, o + 3 * i], rw[r, o + 3 * i + 1], rw[r, o + 3 * i + 2],
                    rw[r, o + 3 * j], rw[r, o + 3 * j + 1], rw[r, o + 3 * j + 2])
    for j in range(3):
        rw[r, RW_EFF + j] = 1.0 / rw[r, RW_K + j] if rw[r, RW_K + j] > 0.0 else 0.0


@helper
def _quadratic(bw, e, ux, uy, uz, vx, vy, vz) -> float:
    """u . I^-1 v with the world inverse inertia of the body of solve index e."""
    return (ux * (bw[e, 13] * vx + bw[e, 14] * vy + bw[e, 15] * vz)
            + uy * (bw[e, 16] * vx + bw[e, 17] * vy + bw[e, 18] * vz)
            + uz * (bw[e, 19] * vx + bw[e, 20] * vy + bw[e, 21] * vz))


def solve_contacts(bodies, memory, count: int, params, loads) -> None:
    """Solve the first ``count`` rows of memory.rows (see the module docstring).

    Reads the rows, the bodies' poses and momenta; writes momenta (lin, ang), and
    poses (pos, quat, rot) by what the sub-steps moved them beyond the final velocity
    (see :func:`_place`). Also writes rows.approach and rows.impulse (the step's
    total), and what memory carries to the next step. Bodies that do not move
    (fixed, asleep) and the ground are immovable. loads: the step's blast impulses
    (loads.impulse, loads.angular: N s, N m s, (B, 3)), which the engine has added to
    the momenta with the step's gravity: the sub-steps hand both out evenly, so a push
    that friction holds over the step is held at every sub-step.

    Islands (bodies that touch, through moving bodies) are solved on their own, on
    every core: no island shares a body with another, so the bytes are the same for
    any thread count.
    """
    ends, ids, bw, rw, order, coef, groups = _begin(bodies, memory, count, params, loads)
    n = bw.shape[0]
    moved = np.zeros((n, 6))
    total = np.zeros((count, 7))
    bounce = np.zeros(count, dtype=np.bool_)
    restarts = np.zeros(len(groups[4]) - 1, dtype=np.int64)
    masses = (ids, bodies.mass, bodies.rot, bodies.inertia)
    scalars = (params.dt, float(params.substeps), params.rest_speed)
    weight = float(exact.norm(params.gravity))
    up = -params.gravity / weight if weight > 0.0 else np.zeros(3)
    _solve_islands(tuple(memory.rows), (ends, bw, rw, moved, total, bounce), groups, masses,
                   coef, scalars, restarts, (bodies.pos, up))
    _finish(bodies, memory, count, (ids, bw, rw, moved, total, bounce), params.substeps,
            int(restarts.sum()), params.dt)


@kernel
def _begin(bodies, memory, count, params, loads):
    """The solve's set-up: each row's bodies as solve indices (ends (count, 2), -1: does
    not move), the moving bodies (ids), their bw and the rows' rw (see integrate's
    layout), the rows' approach (rows.approach; each corner's in rw's RW_TARGET
    columns), the carried impulses (:mod:`~blastvox.simulate.contact.warmstart`), the
    support order, the sub-steps' coefficients and the islands
    (:func:`~blastvox.simulate.contact.islands.islands`)."""
    rows, local = memory.rows, memory.local
    ends = np.full((count, 2), -1, dtype=np.int64)
    ids = np.empty(2 * count, dtype=np.int64)
    n = 0
    for r in range(count):
        for side in range(2):
            b = rows.body[r, side]
            if b < 0 or not moving(b, bodies.live, bodies.fixed, bodies.dust, bodies.asleep):
                continue
            if local[b] < 0:
                local[b] = n
                ids[n] = b
                n += 1
            ends[r, side] = local[b]
    bw = _solve_bodies(bodies, ids, n, loads, params)
    rw = np.zeros((count, RW_WIDTH))
    deepest = 0.0
    for r in range(count):
        _prepare_row(r, rows, bodies.pos, ends, bw, rw)
        deepest = max(deepest, -rows.gap[r])
        rows.approach[r] = np.inf
        for i in range(rows.used[r]):  # the approach, for restitution and impact effects
            vn = corner_speed(r, i, ends, rows.frame, bw, rw)
            rows.approach[r] = min(rows.approach[r], vn)
            rw[r, RW_TARGET + i] = vn
    memory.deepest[0] = max(memory.deepest[0], deepest)
    recall(memory, count, rw, params.friction)
    order = _support_order(ends, n, count)
    return ends, ids[:n], bw, rw, order, _coefficients(params), islands(ends, n, order,
                                                                         params.threads)


@parallel_kernel
def _solve_islands(row_fields, work, groups, masses, coef, scalars, restarts, space):
    """The islands: each bin of islands on its own thread, then the large islands (the
    last bin) one by one, each cut in parts that every thread sweeps
    (:mod:`~blastvox.simulate.contact.partition`). Per island: the sub-steps, the energy
    check (solved again without the warm start if it gained energy, see ENERGY_SLACK)
    and the restitution pass. row_fields: the ContactRows as a tuple; work: (ends, bw,
    rw, moved, total, bounce); groups: the islands
    (:func:`~blastvox.simulate.contact.islands.islands`); masses: (ids, mass, rot,
    inertia) of the bodies; scalars: (dt, sub-steps, rest_speed); restarts (bins,):
    counts the islands solved again; space: (pos (B, 3) m, the bodies' positions; up
    (3,), zero in space)."""
    ends, bw, rw, moved, total, bounce = work
    row_start, island_rows, body_start, members, bin_start, bin_islands = groups
    rest_speed = scalars[2]
    for t in nb.prange(len(bin_start) - 2):
        rows = ContactRows(*row_fields)
        scratch = np.zeros(12)
        for j in range(bin_start[t], bin_start[t + 1]):
            k = bin_islands[j]
            rs = island_rows[row_start[k]:row_start[k + 1]]
            es = members[body_start[k]:body_start[k + 1]]
            before = kinetic_energy(bw, 6, es, masses)
            island_substeps(rows, ends, bw, rw, moved, total, rs, es, coef, scratch)
            if gained_energy(rows, ends, bw, rs, es, masses, coef, before):
                # the warm start pumped energy in (see ENERGY_SLACK): again from no impulse
                undo_solve(bw, rw, moved, total, rs, es)
                island_substeps(rows, ends, bw, rw, moved, total, rs, es, coef, scratch)
                restarts[t] += 1
            restitution(rows, ends, bw, rw, total, rs, rest_speed, bounce)
    rows = ContactRows(*row_fields)
    scratch = np.zeros((PARTS + 1, 12))
    for j in range(bin_start[-2], bin_start[-1]):
        k = bin_islands[j]
        rs = island_rows[row_start[k]:row_start[k + 1]]
        es = members[body_start[k]:body_start[k + 1]]
        part_start, part_rows = cut_island(ends, rs, es, masses[0], space[0], space[1])
        seam = part_rows[part_start[PARTS]:]
        before = kinetic_energy(bw, 6, es, masses)
        for attempt in range(2):
            withhold_loads(bw, es)
            for _ in range(int(coef[10])):
                share_loads(bw, es, coef)
                apply_carried(rows, ends, bw, rw, total, seam)
                # push-out: the seam, the parts, the seam; relax: the seam, the parts
                # (see partition's docstring)
                soft_sweep(rows, ends, bw, rw, moved, total, seam, coef, True,
                           scratch[PARTS])
                for p in nb.prange(PARTS):
                    part_sweep(row_fields, ends, bw, rw, moved, total,
                               part_rows[part_start[p]:part_start[p + 1]], coef, True,
                               scratch[p])
                soft_sweep(rows, ends, bw, rw, moved, total, seam, coef, True,
                           scratch[PARTS])
                move_bodies(bw, moved, es, coef)
                soft_sweep(rows, ends, bw, rw, moved, total, seam, coef, False,
                           scratch[PARTS])
                for p in nb.prange(PARTS):
                    part_sweep(row_fields, ends, bw, rw, moved, total,
                               part_rows[part_start[p]:part_start[p + 1]], coef, False,
                               scratch[p])
            if attempt == 1 or not gained_energy(rows, ends, bw, rs, es, masses, coef,
                                                 before):
                break
            undo_solve(bw, rw, moved, total, rs, es)  # as for the bins' islands
            restarts[-1] += 1
        restitution(rows, ends, bw, rw, total, rs, rest_speed, bounce)


@helper
def part_sweep(row_fields, ends, bw, rw, moved, total, rs, coef, push, scratch) -> None:
    """One part's sweep of a cut island, on its own thread (see :func:`_solve_islands`):
    the push-out sweep after the part's carried impulses (push), or the relax sweep.
    row_fields: the ContactRows as a tuple (a parallel loop is handed arrays, not the
    named tuple)."""
    rows = ContactRows(*row_fields)
    if push:
        apply_carried(rows, ends, bw, rw, total, rs)
    soft_sweep(rows, ends, bw, rw, moved, total, rs, coef, push, scratch)


@helper
def gained_energy(rows, ends, bw, rs, es, masses, coef, before) -> bool:
    """Did the solve of an island (rows rs, bodies es) leave it with more kinetic energy
    than ``before`` (J) and what its fastest push-out may add (see ENERGY_SLACK)?"""
    heft = 0.0
    for e in es:
        heft += masses[1][masses[0][e]]
    speed = ENERGY_SPEED + push_speed(rows, ends, rs, coef)
    return kinetic_energy(bw, 0, es, masses) > before * (1.0 + ENERGY_SLACK) \
        + 0.5 * heft * speed * speed


@kernel
def _finish(bodies, memory, count, work, substeps, restarts, dt) -> None:
    """After the islands: the stats, what memory carries to the next step, the bodies'
    poses (:func:`_place`) and momenta. work: (ids, bw, rw, moved, total, bounce)."""
    ids, bw, rw, moved, total, bounce = work
    n = ids.shape[0]
    memory.stats[0] += 1
    memory.stats[1] += substeps
    memory.stats[3] += restarts
    remember(memory, count, rw, total, bounce)
    _place(bodies, ids, n, bw, moved, dt)
    local = memory.local
    for e in range(n):  # momenta: m dv and I dw (I = R I_rest R^T, the world inertia)
        b = ids[e]
        rot, inertia = bodies.rot[b], bodies.inertia[b]
        dx, dy, dz = bw[e, 3] - bw[e, 9], bw[e, 4] - bw[e, 10], bw[e, 5] - bw[e, 11]
        ux = rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz
        uy = rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz
        uz = rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz
        for a in range(3):
            bodies.lin[b, a] += bodies.mass[b] * (bw[e, a] - bw[e, 6 + a])
            la = inertia[a, 0] * ux + inertia[a, 1] * uy + inertia[a, 2] * uz
            bodies.ang[b, 0] += rot[0, a] * la
            bodies.ang[b, 1] += rot[1, a] * la
            bodies.ang[b, 2] += rot[2, a] * la
        local[b] = -1


@helper
def _solve_bodies(bodies, ids, n, loads, params):
    """bw (n, 30) of the solve's moving bodies ids[:n] (see integrate's layout):
    velocities now and before, 1 / mass, world inverse inertia, the step's change of
    velocities by the blast's loads and gravity."""
    bw = np.zeros((n, 30))
    for e in range(n):
        b = ids[e]
        bw[e, 12] = 1.0 / bodies.mass[b]
        _world_inverse(bodies.rot[b], bodies.inv_inertia[b], bw[e, 13:22])
        ang = bodies.ang[b]
        for a in range(3):
            bw[e, a] = bodies.lin[b, a] * bw[e, 12]
            bw[e, 3 + a] = (bw[e, 13 + 3 * a] * ang[0] + bw[e, 14 + 3 * a] * ang[1]
                            + bw[e, 15 + 3 * a] * ang[2])
        for j in range(6):  # loops, not a slice copy: numba compiles a slice copy's
            # shape-mismatch message (strings, seconds)
            bw[e, 6 + j] = bw[e, j]
        lx, ly, lz = loads.angular[b, 0], loads.angular[b, 1], loads.angular[b, 2]
        for a in range(3):
            bw[e, 24 + a] = loads.impulse[b, a] * bw[e, 12] + params.gravity[a] * params.dt
            bw[e, 27 + a] = (bw[e, 13 + 3 * a] * lx + bw[e, 14 + 3 * a] * ly
                             + bw[e, 15 + 3 * a] * lz)
    return bw


@helper
def _soft(hertz, zeta, h):
    """Bias rate (1/s), mass scale and impulse scale of a soft constraint of natural
    frequency ``hertz`` and damping ratio ``zeta`` over a sub-step h (s) (Catto, "Solver2D"
    2024; Box2D v3's b2MakeSoft): an implicit spring-damper, stable at any h."""
    omega = 2.0 * math.pi * hertz
    a1 = 2.0 * zeta + h * omega
    a2 = h * omega * a1
    a3 = 1.0 / (1.0 + a2)
    return omega / a1, a2 * a3, a3


@helper
def _coefficients(params):
    """(11,) the sub-step solve's scalars: h (s), slop (m), the largest push-out speed
    (m/s), the soft terms of contacts between moving bodies and with immovable ones
    (bias rate, mass scale, impulse scale each), friction mu, the sub-steps."""
    h = params.dt / params.substeps
    hertz = min(CONTACT_HERTZ, 0.25 / h)
    coef = np.empty(11)
    coef[0], coef[1], coef[2] = h, params.slop, PUSH_SPEED
    coef[3], coef[4], coef[5] = _soft(hertz, CONTACT_DAMPING, h)
    coef[6], coef[7], coef[8] = _soft(2.0 * hertz, CONTACT_DAMPING, h)
    coef[9] = params.friction
    coef[10] = params.substeps
    return coef


@helper
def _place(bodies, ids, n, bw, moved, dt) -> None:
    """Move each solved body by what its sub-steps moved it (moved: displacement, m, and
    rotation vector, rad) less what the engine's position half-step will move it at its
    final velocity: the soft push-out moves bodies, never gives them momentum."""
    for e in range(n):
        b = ids[e]
        for a in range(3):
            bodies.pos[b, a] += moved[e, a] - bw[e, a] * dt
        wx, wy, wz = (moved[e, 3] / dt - bw[e, 3], moved[e, 4] / dt - bw[e, 4],
                      moved[e, 5] / dt - bw[e, 5])
        if wx != 0.0 or wy != 0.0 or wz != 0.0:
            quaternion_nb.integrate(bodies.quat[b], wx, wy, wz, dt)
            quaternion_nb.matrix_into(bodies.quat[b], bodies.rot[b])


@helper
def _support_order(ends, n, count):
    """Rows (count,) ordered by how many contacts their bodies are from something that
    does not move (the ground, a fixed or a sleeping body): a breadth-first search of
    the contact graph from its supports (Erleben's contact graph layers; rows of
    unsupported bodies last). ends (count, 2): the rows' solve indices of bodies a, b
    (-1: does not move); n: how many bodies move. Linear time: counting sorts."""
    offsets = np.zeros(n + 1, dtype=np.int64)  # each body's rows, CSR
    for r in range(count):
        for side in range(2):
            if ends[r, side] >= 0:
                offsets[ends[r, side] + 1] += 1
    for e in range(n):
        offsets[e + 1] += offsets[e]
    fill = offsets[:-1].copy()
    adjacent = np.empty(offsets[n], dtype=np.int64)
    for r in range(count):
        for side in range(2):
            e = ends[r, side]
            if e >= 0:
                adjacent[fill[e]] = r
                fill[e] += 1
    level = np.full(n, -1, dtype=np.int64)
    queue = np.empty(n, dtype=np.int64)
    tail = 0
    for r in range(count):  # the supported bodies: level 0
        ea, eb = ends[r, 0], ends[r, 1]
        e = eb if ea < 0 else (ea if eb < 0 else -1)
        if e >= 0 and level[e] < 0:
            level[e] = 0
            queue[tail] = e
            tail += 1
    head = 0
    while head < tail:
        e = queue[head]
        head += 1
        for k in range(offsets[e], offsets[e + 1]):
            r = adjacent[k]
            other = ends[r, 1] if ends[r, 0] == e else ends[r, 0]
            if other >= 0 and level[other] < 0:
                level[other] = level[e] + 1
                queue[tail] = other
                tail += 1
    deepest = 0
    for e in range(n):
        deepest = max(deepest, level[e])
    key = np.empty(count, dtype=np.int64)
    for r in range(count):  # a row's layer: its lower body's; unsupported last
        ea, eb = ends[r, 0], ends[r, 1]
        la = level[ea] if ea >= 0 and level[ea] >= 0 else deepest + 1
        lb = level[eb] if eb >= 0 and level[eb] >= 0 else deepest + 1
        key[r] = 0 if ea < 0 or eb < 0 else min(la, lb)
    start = np.zeros(deepest + 3, dtype=np.int64)
    for r in range(count):
        start[key[r] + 1] += 1
    for j in range(deepest + 2):
        start[j + 1] += start[j]
    order = np.empty(count, dtype=np.int64)
    for r in range(count):
        order[start[key[r]]] = r
        start[key[r]] += 1
    return order


@helper
def _world_inverse(rot, inv, out) -> None:
    """out (9,) = R I^-1 R^T row by row, the world inverse inertia (1/(kg m^2))."""
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                for m in range(3):
                    s += rot[i, k] * inv[k, m] * rot[j, m]
            out[3 * i + j] = s
