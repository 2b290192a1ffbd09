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
touch are solved on their own, on every core (:func:`_solve_islands`).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from blastvox.geometry import quaternion_nb
from blastvox.jit import helper, kernel, parallel_kernel
from blastvox.simulate.contact.islands import islands
from blastvox.simulate.contact.restitution import restitution
from blastvox.simulate.contact.rows import ContactRows
from blastvox.simulate.contact.warmstart import apply_carried, recall, remember
from blastvox.simulate.integrate import (
    CORNER_SWEEPS,
    CORNER_TOLERANCE,
    RW_ACC,
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


@helper
def _body_locals(bw, e):
    """A moving body's solve row (bw, see :func:`solve_contacts`) as 16 scalars: velocity
    (m/s), angular velocity (rad/s), 1 / mass (1/kg), world inverse inertia (row by
    row); all zero for e < 0 (a body that does not move)."""
    if e < 0:
        return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                0.0)
    return (bw[e, 0], bw[e, 1], bw[e, 2], bw[e, 3], bw[e, 4], bw[e, 5], bw[e, 12],
            bw[e, 13], bw[e, 14], bw[e, 15], bw[e, 16], bw[e, 17], bw[e, 18], bw[e, 19],
            bw[e, 20], bw[e, 21])


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
    _solve_islands(tuple(memory.rows), (ends, bw, rw, moved, total, bounce), groups, masses,
                   coef, scalars, restarts)
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
def _solve_islands(row_fields, work, groups, masses, coef, scalars, restarts):
    """Each bin of islands on its own thread: per island, the sub-steps, the energy check
    (solved again without the warm start if it gained energy, see ENERGY_SLACK) and the
    restitution pass. row_fields: the ContactRows as a tuple; work: (ends, bw, rw,
    moved, total, bounce); groups: the islands
    (:func:`~blastvox.simulate.contact.islands.islands`); masses: (ids, mass, rot,
    inertia) of the bodies; scalars: (dt, sub-steps, rest_speed); restarts (bins,):
    counts the islands solved again."""
    ends, bw, rw, moved, total, bounce = work
    row_start, island_rows, body_start, members, bin_start, bin_islands = groups
    ids, mass, rot, inertia = masses
    dt, substeps, rest_speed = scalars
    (body, voxel, key, frame, corners, corner_gap, used, gap, point, arm, bounciness,
     approach, impulse, friction, grip) = row_fields
    for t in nb.prange(len(bin_start) - 1):
        rows = ContactRows(body, voxel, key, frame, corners, corner_gap, used, gap, point,
                           arm, bounciness, approach, impulse, friction, grip)
        scratch = np.zeros(12)
        for j in range(bin_start[t], bin_start[t + 1]):
            k = bin_islands[j]
            rs = island_rows[row_start[k]:row_start[k + 1]]
            es = members[body_start[k]:body_start[k + 1]]
            before = _kinetic_energy(bw, 6, es, ids, mass, rot, inertia)
            _substeps(rows, ends, bw, rw, moved, total, rs, es, coef, scratch)
            heft = 0.0
            for e in es:
                heft += mass[ids[e]]
            speed = ENERGY_SPEED + _push_speed(rows, ends, rs, coef)
            if _kinetic_energy(bw, 0, es, ids, mass, rot, inertia) > before * (
                    1.0 + ENERGY_SLACK) + 0.5 * heft * speed * speed:
                # the warm start pumped energy in (see ENERGY_SLACK): again from no impulse
                _restart(bw, rw, moved, total, rs, es)
                _substeps(rows, ends, bw, rw, moved, total, rs, es, coef, scratch)
                restarts[t] += 1
            restitution(rows, ends, bw, rw, total, rs, rest_speed, bounce)


@helper
def _push_speed(rows, ends, rs, coef) -> float:
    """The fastest soft push-out (m/s) of rows rs at the step's start: what an island's
    bodies may still move apart at after the sub-steps' rigid sweeps."""
    fastest = 0.0
    for r in rs:
        o = 6 if ends[r, 0] < 0 or ends[r, 1] < 0 else 3
        for i in range(rows.used[r]):
            depth = -(rows.corner_gap[r, i] + coef[1])
            if depth > 0.0:
                fastest = max(fastest, min(coef[o + 1] * coef[o] * depth, coef[2]))
    return fastest


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
def _substeps(rows, ends, bw, rw, moved, total, rs, es, coef, scratch) -> None:
    """The soft step (Box2D v3's solver) of one island, rows rs (in support order) and
    moving bodies es: coef[10] sub-steps of h = coef[0], each: its share of
    the step's loads and gravity, the carried impulses applied again, one sweep with
    the soft push-out, the positions moved, one rigid sweep (relax) that takes the
    push-out's speed back out. moved (n, 6): displacement (m) and rotation vector (rad)
    of each body so far; total (count, 7): impulses (N s, N m s) applied so far;
    scratch (12,)."""
    h, substeps = coef[0], int(coef[10])
    share = 1.0 / substeps
    count = rs.shape[0]
    for e in es:  # the engine gave a whole step's loads: hand them out by sub-step
        for a in range(6):
            bw[e, a] -= bw[e, 24 + a]
    for _ in range(substeps):
        for e in es:
            for a in range(6):
                bw[e, a] += bw[e, 24 + a] * share
        apply_carried(rows, ends, bw, rw, total, rs)
        for q in range(count):
            _soft_row(rs[q], rows, ends, bw, rw, moved, total, coef, True, scratch)
        for e in es:
            for a in range(6):
                moved[e, a] += bw[e, a] * h
        for q in range(count):
            _soft_row(rs[count - 1 - q], rows, ends, bw, rw, moved, total, coef, False,
                      scratch)


@helper
def _soft_row(r, rows, ends, bw, rw, moved, total, coef, push, scratch) -> None:
    """One sweep's update of row r: the normal impulses of its corners (>= 0), each
    against its separation now (the start's, plus what the sub-steps moved the bodies),
    speculative where apart, soft where deeper than the slop (push: the soft
    push-out; else rigid), then friction at the centre within mu times their sum
    (both tangents at once) and twisting friction about n. Written out in full, with
    both bodies' velocities in locals: the solver's hot loop."""
    frame = rows.frame
    ea, eb = ends[r, 0], ends[r, 1]
    (avx, avy, avz, awx, awy, awz, ima,
     a0, a1, a2, a3, a4, a5, a6, a7, a8) = _body_locals(bw, ea)
    (bvx, bvy, bvz, bwx, bwy, bwz, imb,
     b0, b1, b2, b3, b4, b5, b6, b7, b8) = _body_locals(bw, eb)
    nx, ny, nz = frame[r, 0, 0], frame[r, 0, 1], frame[r, 0, 2]
    dpx = dpy = dpz = 0.0  # what the sub-steps moved b relative to a, and turned each
    tax = tay = taz = tbx = tby = tbz = 0.0
    if ea >= 0:
        dpx, dpy, dpz = -moved[ea, 0], -moved[ea, 1], -moved[ea, 2]
        tax, tay, taz = moved[ea, 3], moved[ea, 4], moved[ea, 5]
    if eb >= 0:
        dpx, dpy, dpz = dpx + moved[eb, 0], dpy + moved[eb, 1], dpz + moved[eb, 2]
        tbx, tby, tbz = moved[eb, 3], moved[eb, 4], moved[eb, 5]
    shift = dpx * nx + dpy * ny + dpz * nz
    o = 6 if ea < 0 or eb < 0 else 3  # against an immovable body: stiffer
    h, slop, rate, mass_scale = coef[0], coef[1], coef[o], coef[o + 1]
    # the corners together: M delta = -(ms vn + bias + is k lambda), lambda + delta >= 0,
    # M = ms K + is diag(k) (each corner's own soft terms; K the corners' coupling),
    # projected Gauss-Seidel to convergence: a face's corners push alike, no spin
    used = rows.used[r]
    common = (bvx - avx) * nx + (bvy - avy) * ny + (bvz - avz) * nz
    for i in range(used):
        ca, cb = RW_CA + 3 * i, RW_CB + 3 * i
        gap = rows.corner_gap[r, i] + shift \
            + tbx * rw[r, cb] + tby * rw[r, cb + 1] + tbz * rw[r, cb + 2] \
            - tax * rw[r, ca] - tay * rw[r, ca + 1] - taz * rw[r, ca + 2]
        bias, ms = 0.0, 1.0
        if gap > slop:
            bias = (gap - slop) / h  # speculative: arrive, do not pass
        elif push and gap < -slop:
            bias = max(mass_scale * rate * (gap + slop), -coef[2])
            ms = mass_scale
        vn = common + rw[r, cb] * bwx + rw[r, cb + 1] * bwy + rw[r, cb + 2] * bwz \
            - rw[r, ca] * awx - rw[r, ca + 1] * awy - rw[r, ca + 2] * awz
        kii = rw[r, RW_KN + i * (7 - i) // 2 + i]
        scratch[i] = -(ms * vn + bias + (1.0 - ms) * kii * rw[r, RW_ACC + i])
        scratch[8 + i] = ms
        scratch[4 + i] = 0.0
    for _ in range(CORNER_SWEEPS):
        change = 0.0
        for i in range(used):
            ms = scratch[8 + i]
            kii = rw[r, RW_KN + i * (7 - i) // 2 + i]
            if kii <= 0.0:
                continue
            res = scratch[i]
            for j in range(used):
                res -= ms * rw[r, RW_KN + (i * (7 - i) // 2 + j if i <= j
                                           else j * (7 - j) // 2 + i)] * scratch[4 + j]
            res -= (1.0 - ms) * kii * scratch[4 + i]
            new = max(rw[r, RW_ACC + i] + scratch[4 + i] + res / kii, 0.0) \
                - rw[r, RW_ACC + i]
            change = max(change, abs(new - scratch[4 + i]) * kii)
            scratch[4 + i] = new
        if change <= CORNER_TOLERANCE or used == 1:
            break
    normal = 0.0
    tot = 0.0
    cax = cay = caz = cbx = cby = cbz = 0.0
    for i in range(used):
        d = scratch[4 + i]
        normal += rw[r, RW_ACC + i] + d
        if d == 0.0:
            continue
        rw[r, RW_ACC + i] += d
        total[r, i] += d
        tot += d
        ca, cb = RW_CA + 3 * i, RW_CB + 3 * i
        cax, cay, caz = cax + d * rw[r, ca], cay + d * rw[r, ca + 1], caz + d * rw[r, ca + 2]
        cbx, cby, cbz = cbx + d * rw[r, cb], cby + d * rw[r, cb + 1], cbz + d * rw[r, cb + 2]
    if tot != 0.0 or cax != 0.0 or cay != 0.0 or caz != 0.0:
        avx, avy, avz = avx - tot * nx * ima, avy - tot * ny * ima, avz - tot * nz * ima
        awx -= a0 * cax + a1 * cay + a2 * caz
        awy -= a3 * cax + a4 * cay + a5 * caz
        awz -= a6 * cax + a7 * cay + a8 * caz
        bvx, bvy, bvz = bvx + tot * nx * imb, bvy + tot * ny * imb, bvz + tot * nz * imb
        bwx += b0 * cbx + b1 * cby + b2 * cbz
        bwy += b3 * cbx + b4 * cby + b5 * cbz
        bwz += b6 * cbx + b7 * cby + b8 * cbz
    limit = coef[9] * rows.grip[r] * normal
    if limit > 0.0 or rw[r, RW_ACC + 4] != 0.0 or rw[r, RW_ACC + 5] != 0.0 \
            or rw[r, RW_ACC + 6] != 0.0:
        rax, ray, raz, rbx, rby, rbz = (rw[r, 0], rw[r, 1], rw[r, 2], rw[r, 3], rw[r, 4],
                                        rw[r, 5])
        t1x, t1y, t1z = frame[r, 1, 0], frame[r, 1, 1], frame[r, 1, 2]
        t2x, t2y, t2z = frame[r, 2, 0], frame[r, 2, 1], frame[r, 2, 2]
        vx = bvx + bwy * rbz - bwz * rby - avx - awy * raz + awz * ray
        vy = bvy + bwz * rbx - bwx * rbz - avy - awz * rax + awx * raz
        vz = bvz + bwx * rby - bwy * rbx - avz - awx * ray + awy * rax
        old1, old2 = rw[r, RW_ACC + 4], rw[r, RW_ACC + 5]
        new1 = old1 - (vx * t1x + vy * t1y + vz * t1z) * rw[r, RW_EFF]
        new2 = old2 - (vx * t2x + vy * t2y + vz * t2z) * rw[r, RW_EFF + 1]
        size = math.sqrt(new1 * new1 + new2 * new2)
        if size > limit:
            scale = limit / size
            new1, new2 = new1 * scale, new2 * scale
        d1, d2 = new1 - old1, new2 - old2
        if d1 != 0.0 or d2 != 0.0:
            rw[r, RW_ACC + 4], rw[r, RW_ACC + 5] = new1, new2
            total[r, 4] += d1
            total[r, 5] += d2
            px, py, pz = d1 * t1x + d2 * t2x, d1 * t1y + d2 * t2y, d1 * t1z + d2 * t2z
            cx, cy, cz = ray * pz - raz * py, raz * px - rax * pz, rax * py - ray * px
            avx, avy, avz = avx - px * ima, avy - py * ima, avz - pz * ima
            awx -= a0 * cx + a1 * cy + a2 * cz
            awy -= a3 * cx + a4 * cy + a5 * cz
            awz -= a6 * cx + a7 * cy + a8 * cz
            cx, cy, cz = rby * pz - rbz * py, rbz * px - rbx * pz, rbx * py - rby * px
            bvx, bvy, bvz = bvx + px * imb, bvy + py * imb, bvz + pz * imb
            bwx += b0 * cx + b1 * cy + b2 * cz
            bwy += b3 * cx + b4 * cy + b5 * cz
            bwz += b6 * cx + b7 * cy + b8 * cz
        arm = rows.arm[r]
        if arm > 0.0:  # twisting friction, the spin about n
            old = rw[r, RW_ACC + 6]
            lim = limit * arm
            spin = (bwx - awx) * nx + (bwy - awy) * ny + (bwz - awz) * nz
            new = min(max(old - spin * rw[r, RW_EFF + 2], -lim), lim)
            d = new - old
            if d != 0.0:
                rw[r, RW_ACC + 6] = new
                total[r, 6] += d
                awx -= d * (a0 * nx + a1 * ny + a2 * nz)
                awy -= d * (a3 * nx + a4 * ny + a5 * nz)
                awz -= d * (a6 * nx + a7 * ny + a8 * nz)
                bwx += d * (b0 * nx + b1 * ny + b2 * nz)
                bwy += d * (b3 * nx + b4 * ny + b5 * nz)
                bwz += d * (b6 * nx + b7 * ny + b8 * nz)
    if ea >= 0:
        bw[ea, 0], bw[ea, 1], bw[ea, 2] = avx, avy, avz
        bw[ea, 3], bw[ea, 4], bw[ea, 5] = awx, awy, awz
    if eb >= 0:
        bw[eb, 0], bw[eb, 1], bw[eb, 2] = bvx, bvy, bvz
        bw[eb, 3], bw[eb, 4], bw[eb, 5] = bwx, bwy, bwz


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
def _kinetic_energy(bw, col, es, ids, mass, rot_all, inertia_all) -> float:
    """Kinetic energy (J) of the solve's bodies es at the velocities in bw's columns
    col..col+5 (0: now, 6: before the solve): m v^2 / 2 + w . (R I R^T) w / 2. ids:
    their bodies; mass, rot_all, inertia_all: every body's."""
    total = 0.0
    for e in es:
        b = ids[e]
        rot, inertia = rot_all[b], inertia_all[b]
        vx, vy, vz = bw[e, col], bw[e, col + 1], bw[e, col + 2]
        total += 0.5 * mass[b] * (vx * vx + vy * vy + vz * vz)
        wx, wy, wz = bw[e, col + 3], bw[e, col + 4], bw[e, col + 5]
        ux = rot[0, 0] * wx + rot[1, 0] * wy + rot[2, 0] * wz  # R^T w: the rest frame
        uy = rot[0, 1] * wx + rot[1, 1] * wy + rot[2, 1] * wz
        uz = rot[0, 2] * wx + rot[1, 2] * wy + rot[2, 2] * wz
        total += 0.5 * (ux * (inertia[0, 0] * ux + inertia[0, 1] * uy + inertia[0, 2] * uz)
                        + uy * (inertia[1, 0] * ux + inertia[1, 1] * uy + inertia[1, 2] * uz)
                        + uz * (inertia[2, 0] * ux + inertia[2, 1] * uy + inertia[2, 2] * uz))
    return total


@helper
def _restart(bw, rw, moved, total, rs, es) -> None:
    """Undo an island's solve: its bodies es' velocities and poses as before it, no
    impulse on its rows rs."""
    for e in es:
        for j in range(6):
            bw[e, j] = bw[e, 6 + j]
            moved[e, j] = 0.0
    for r in rs:
        for j in range(7):
            rw[r, RW_ACC + j] = 0.0
            total[r, j] = 0.0


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
