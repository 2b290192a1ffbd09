"""The contact solver that the fragment and ground phases both feed
(:func:`solve_contacts`, on the :class:`~blastvox.simulate.contact.ground.ContactRows` they
gather).

Sequential impulses (Catto 2005; Bullet's and Box2D's solvers): projected
Gauss-Seidel sweeps over the contact rows of the step, normal impulses >= 0,
Coulomb friction within mu times the normal impulse, warm started from the
impulses the same contacts carried the step before (so a stack holds its weight
from the first sweep, however tall), and a separate position pass (split
impulses, Bullet's ``splitImpulse``) that pushes interpenetrating bodies apart by
moving them, never by giving them momentum. A sweep solves again only the rows
whose bodies other rows changed by enough to matter since (:func:`_announce`): in a
pile, the few contacts still converging do not keep every other contact of it busy.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.jit import helper, kernel
from blastvox.simulate.contact.pairs import bucket, hash_buckets
from blastvox.simulate.integrate import (
    RW_ACC,
    RW_CA,
    RW_CB,
    RW_EFF,
    RW_K,
    RW_KN,
    RW_SEEN,
    RW_TARGET,
    RW_WIDTH,
    apply_at,
    corner_speed,
    moving,
    push_corner,
    separate,
    turn_by,
)

#: The velocity sweeps stop once a sweep changes no contact point's normal velocity by
#: more than this, or after params.sweeps (the scene's ``contact_sweeps``).
SOLVED_SPEED = 1e-2  # m/s
#: A row's changes to a body's velocities (m/s, summed) before the body's other rows are
#: solved again: well below SOLVED_SPEED, so what they leave unsolved is too.
ANNOUNCE_SPEED = 3e-4  # m/s
#: Sweeps at most of the Gauss-Seidel solve of one pair's corners, in each velocity sweep.
CORNER_SWEEPS = 16
#: Contacts only remove kinetic energy (their targets stop, or bounce with restitution
#: <= 1): every sweep is a descent. The warm start is not: in a jammed pile (a piece
#: wedged between others, contacts pushing from opposite sides) the impulses carried
#: from step to step can ratchet up while cancelling, until an unconverged solve lets
#: them loose (a sweep found 2.3 MJ given to a broken wall's pieces in one step, pieces
#: leaving at 90 m/s). A solve that ends with more kinetic energy than this fraction
#: above what it started with is done again without the warm start.
ENERGY_SLACK = 1e-6


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


@helper
def _sweep_row(r, rows, ends, bw, rw, friction, b) -> float:
    """One Gauss-Seidel update of row r: friction at its centre (both tangents at once,
    kept within the circle of radius mu times the normal impulse) and twisting friction
    about n, then the normal impulses of its corners (>= 0), solved together for the
    pair: projected Gauss-Seidel on the corners' coupling matrix, to convergence
    (:data:`CORNER_SWEEPS` at most). Returns the largest change it made to a corner's
    normal velocity, m/s. b: (8,) scratch. Written out in
    full, with both bodies' velocities in locals: the solver's hot loop."""
    frame = rows.frame
    ea, eb = ends[r, 0], ends[r, 1]
    (avx, avy, avz, awx, awy, awz, ima,
     a0, a1, a2, a3, a4, a5, a6, a7, a8) = _body_locals(bw, ea)
    (bvx, bvy, bvz, bwx, bwy, bwz, imb,
     b0, b1, b2, b3, b4, b5, b6, b7, b8) = _body_locals(bw, eb)
    nx, ny, nz = frame[r, 0, 0], frame[r, 0, 1], frame[r, 0, 2]
    used = rows.used[r]
    friction *= rows.grip[r]
    normal = 0.0
    for i in range(used):
        normal += rw[r, RW_ACC + i]
    change = 0.0
    if normal != 0.0 or rw[r, RW_ACC + 4] != 0.0 or rw[r, RW_ACC + 5] != 0.0 \
            or rw[r, RW_ACC + 6] != 0.0:  # without load no friction
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
        if size > friction * normal:
            new1 *= friction * normal / size
            new2 *= friction * normal / size
        d1, d2 = new1 - old1, new2 - old2
        if d1 != 0.0 or d2 != 0.0:
            rw[r, RW_ACC + 4], rw[r, RW_ACC + 5] = new1, new2
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
            change = max(abs(d1) * rw[r, RW_K], abs(d2) * rw[r, RW_K + 1])
        arm = rows.arm[r]
        if arm > 0.0:  # twisting friction, the spin about n
            old = rw[r, RW_ACC + 6]
            lim = friction * normal * arm
            spin = (bwx - awx) * nx + (bwy - awy) * ny + (bwz - awz) * nz
            new = min(max(old - spin * rw[r, RW_EFF + 2], -lim), lim)
            d = new - old
            if d != 0.0:
                rw[r, RW_ACC + 6] = new
                awx -= d * (a0 * nx + a1 * ny + a2 * nz)
                awy -= d * (a3 * nx + a4 * ny + a5 * nz)
                awz -= d * (a6 * nx + a7 * ny + a8 * nz)
                bwx += d * (b0 * nx + b1 * ny + b2 * nz)
                bwy += d * (b3 * nx + b4 * ny + b5 * nz)
                bwz += d * (b6 * nx + b7 * ny + b8 * nz)
                change = max(change, abs(d) * rw[r, RW_K + 2] * arm)
    # the corners' normals, together: residuals b_i of their targets, then projected
    # Gauss-Seidel on delta with the coupling matrix K (the other bodies held)
    common = (bvx - avx) * nx + (bvy - avy) * ny + (bvz - avz) * nz
    for i in range(4, 8):  # b[:4] the residuals, b[4:] delta
        b[i] = 0.0
    for i in range(used):
        ca, cb = RW_CA + 3 * i, RW_CB + 3 * i
        vn = common + rw[r, cb] * bwx + rw[r, cb + 1] * bwy + rw[r, cb + 2] * bwz \
            - rw[r, ca] * awx - rw[r, ca + 1] * awy - rw[r, ca + 2] * awz
        b[i] = rw[r, RW_TARGET + i] - vn
    for _ in range(CORNER_SWEEPS):
        moved = 0.0
        for i in range(used):
            res = b[i]
            for j in range(used):
                res -= rw[r, RW_KN + (i * (7 - i) // 2 + j if i <= j
                                      else j * (7 - j) // 2 + i)] * b[4 + j]
            kii = rw[r, RW_KN + i * (7 - i) // 2 + i]
            if kii <= 0.0:
                continue
            new = max(rw[r, RW_ACC + i] + b[4 + i] + res / kii, 0.0) - rw[r, RW_ACC + i]
            moved = max(moved, abs(new - b[4 + i]) * kii)
            b[4 + i] = new
        if moved <= 1e-9 * SOLVED_SPEED or used == 1:
            break
    total = normal = 0.0  # normal: now the largest change of a corner's velocity
    cax = cay = caz = cbx = cby = cbz = 0.0
    for i in range(used):
        d = b[4 + i]
        if d == 0.0:
            continue
        rw[r, RW_ACC + i] += d
        total += d
        ca, cb = RW_CA + 3 * i, RW_CB + 3 * i
        cax, cay, caz = cax + d * rw[r, ca], cay + d * rw[r, ca + 1], caz + d * rw[r, ca + 2]
        cbx, cby, cbz = cbx + d * rw[r, cb], cby + d * rw[r, cb + 1], cbz + d * rw[r, cb + 2]
        normal = max(normal, abs(d) * rw[r, RW_KN + i * (7 - i) // 2 + i])
    if total != 0.0 or cax != 0.0 or cay != 0.0 or caz != 0.0:
        avx, avy, avz = avx - total * nx * ima, avy - total * ny * ima, avz - total * nz * ima
        awx -= a0 * cax + a1 * cay + a2 * caz
        awy -= a3 * cax + a4 * cay + a5 * caz
        awz -= a6 * cax + a7 * cay + a8 * caz
        bvx, bvy, bvz = bvx + total * nx * imb, bvy + total * ny * imb, bvz + total * nz * imb
        bwx += b0 * cbx + b1 * cby + b2 * cbz
        bwy += b3 * cbx + b4 * cby + b5 * cbz
        bwz += b6 * cbx + b7 * cby + b8 * cbz
    if change == 0.0 and normal == 0.0:
        return 0.0
    moved = max(change, normal)
    if ea >= 0:
        bw[ea, 0], bw[ea, 1], bw[ea, 2] = avx, avy, avz
        bw[ea, 3], bw[ea, 4], bw[ea, 5] = awx, awy, awz
        _announce(bw, ea, moved)
    if eb >= 0:
        bw[eb, 0], bw[eb, 1], bw[eb, 2] = bvx, bvy, bvz
        bw[eb, 3], bw[eb, 4], bw[eb, 5] = bwx, bwy, bwz
        _announce(bw, eb, moved)
    return normal


@helper
def _announce(bw, e, moved) -> None:
    """Count a change of body e's velocities (bw[e, 22], what makes a sweep solve its
    other rows again) once the changes since the last count add up to ANNOUNCE_SPEED
    (bw[e, 23], m/s): smaller ones are applied, but do not wake its neighbours."""
    bw[e, 23] += moved
    if bw[e, 23] > ANNOUNCE_SPEED:
        bw[e, 22] += 1.0
        bw[e, 23] = 0.0


@kernel
def solve_contacts(bodies, memory, count, params) -> None:
    """Solve the first ``count`` rows of memory.rows (see the module docstring).

    Reads the rows, the bodies' poses and momenta; writes momenta (lin, ang), and,
    where bodies interpenetrate beyond params.slop, positions and orientations
    (pos, quat, rot). Also writes rows.approach and rows.impulse, and what
    memory carries to the next step. Bodies that do not move (fixed, asleep) and
    the ground are immovable. A corner's target normal velocity: a bounce of
    restitution e (-e times the approach) for an impact (approach faster than
    params.rest_speed) that the contact stops within the step, else the gap beyond
    params.slop closed over the step (speculative contact: arrive, do not pass), or 0
    when touching (within the slop either way: a resting contact stays put, and the
    warm-started sweeps have nothing left to do).
    """
    rows, local = memory.rows, memory.local
    ends = np.full((count, 2), -1, dtype=np.int64)
    dt = params.dt
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
    bw = np.zeros((n, 24))
    for e in range(n):
        b = ids[e]
        bw[e, 12] = 1.0 / bodies.mass[b]
        _world_inverse(bodies.rot[b], bodies.inv_inertia[b], bw[e, 13:22])
        ang = bodies.ang[b]
        for a in range(3):
            bw[e, a] = bodies.lin[b, a] * bw[e, 12]
            bw[e, 3 + a] = (bw[e, 13 + 3 * a] * ang[0] + bw[e, 14 + 3 * a] * ang[1]
                            + bw[e, 15 + 3 * a] * ang[2])
        for j in range(6):  # not a slice copy (see integrate.separate)
            bw[e, 6 + j] = bw[e, j]
    rw = np.zeros((count, RW_WIDTH))
    bounce = np.zeros(count, dtype=np.bool_)
    deepest = 0.0
    for r in range(count):
        _prepare_row(r, rows, bodies.pos, ends, bw, rw)
        rw[r, RW_SEEN], rw[r, RW_SEEN + 1] = -1.0, -1.0
        deepest = max(deepest, -rows.gap[r])
        rows.approach[r] = np.inf
        for i in range(rows.used[r]):
            vn = corner_speed(r, i, ends, rows.frame, bw, rw)
            rows.approach[r] = min(rows.approach[r], vn)
            target = -max(rows.corner_gap[r, i] - params.slop, 0.0) / dt
            if -vn > params.rest_speed and vn < target:  # an impact that binds
                target = max(target, -rows.restitution[r] * vn)
                bounce[r] = True
            rw[r, RW_TARGET + i] = target
    memory.deepest[0] = max(memory.deepest[0], deepest)
    before = _kinetic_energy(bw, 6, ids, n, bodies)
    _warm_start(memory, count, ends, bw, rw, params.friction)
    scratch = np.empty(8)
    order = _support_order(ends, n, count)
    _sweeps(rows, ends, bw, rw, order, count, params, scratch, memory)
    if _kinetic_energy(bw, 0, ids, n, bodies) > before * (1.0 + ENERGY_SLACK):
        # the warm start pumped energy in (see ENERGY_SLACK): solve again from no impulse
        _restart(bw, rw, count, n)
        _sweeps(rows, ends, bw, rw, order, count, params, scratch, memory)
        memory.stats[3] += 1
    memory.stats[0] += 1
    _remember(memory, count, rw, bounce)
    if deepest > params.slop:
        separate(bodies, rows, count, ends, ids[:n], bw, rw, params)
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
def _sweeps(rows, ends, bw, rw, order, count, params, scratch, memory) -> None:
    """The velocity sweeps over the rows in ``order``, until no contact point's normal
    velocity changes by more than SOLVED_SPEED, or params.sweeps."""
    for sweep in range(params.sweeps):
        change = 0.0
        for q in range(count):
            # from the supports out, then back: a stack's weight and an impact on its
            # top each cross it in one sweep
            r = order[q] if sweep % 2 == 0 else order[count - 1 - q]
            ea, eb = ends[r, 0], ends[r, 1]
            seen_a = bw[ea, 22] if ea >= 0 else 0.0
            seen_b = bw[eb, 22] if eb >= 0 else 0.0
            if rw[r, RW_SEEN] == seen_a and rw[r, RW_SEEN + 1] == seen_b:
                continue
            change = max(change, _sweep_row(r, rows, ends, bw, rw, params.friction, scratch))
            rw[r, RW_SEEN] = bw[ea, 22] if ea >= 0 else 0.0
            rw[r, RW_SEEN + 1] = bw[eb, 22] if eb >= 0 else 0.0
        memory.stats[1] += 1
        if change <= SOLVED_SPEED:
            break
        if sweep == params.sweeps - 1:
            memory.stats[2] += 1


@helper
def _kinetic_energy(bw, col, ids, n, bodies) -> float:
    """Kinetic energy (J) of the solve's n moving bodies at the velocities in bw's
    columns col..col+5 (0: now, 6: before the solve): m v^2 / 2 + w . (R I R^T) w / 2."""
    total = 0.0
    for e in range(n):
        b = ids[e]
        rot, inertia = bodies.rot[b], bodies.inertia[b]
        vx, vy, vz = bw[e, col], bw[e, col + 1], bw[e, col + 2]
        total += 0.5 * bodies.mass[b] * (vx * vx + vy * vy + vz * vz)
        wx, wy, wz = bw[e, col + 3], bw[e, col + 4], bw[e, col + 5]
        ux = rot[0, 0] * wx + rot[1, 0] * wy + rot[2, 0] * wz  # R^T w: the rest frame
        uy = rot[0, 1] * wx + rot[1, 1] * wy + rot[2, 1] * wz
        uz = rot[0, 2] * wx + rot[1, 2] * wy + rot[2, 2] * wz
        total += 0.5 * (ux * (inertia[0, 0] * ux + inertia[0, 1] * uy + inertia[0, 2] * uz)
                        + uy * (inertia[1, 0] * ux + inertia[1, 1] * uy + inertia[1, 2] * uz)
                        + uz * (inertia[2, 0] * ux + inertia[2, 1] * uy + inertia[2, 2] * uz))
    return total


@helper
def _restart(bw, rw, count, n) -> None:
    """Undo a solve: the bodies' velocities as before it, no accumulated impulse, every
    row to be solved again."""
    for e in range(n):
        for j in range(6):
            bw[e, j] = bw[e, 6 + j]
        bw[e, 22] = 0.0
        bw[e, 23] = 0.0
    for r in range(count):
        for j in range(7):
            rw[r, RW_ACC + j] = 0.0
        rw[r, RW_SEEN], rw[r, RW_SEEN + 1] = -1.0, -1.0


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


@helper
def _warm_start(memory, count, ends, bw, rw, friction) -> None:
    """Give each row the impulses its contact carried last step (memory.keys, carried):
    the normal shared equally by its corners (their own solve shares it out), friction
    and twist taken onto its current directions and within its current limits; apply
    them."""
    rows, keys, carried, p = memory.rows, memory.keys, memory.carried, memory.count[0]
    if p == 0 or count == 0:
        return
    frame = rows.frame
    start, entries = hash_buckets(keys[:p])
    for r in range(count):
        key = rows.key[r]
        lo, hi = bucket(key, start)
        found = -1
        for s in range(lo, hi):
            if keys[entries[s]] == key:
                found = entries[s]
                break
        if found < 0:
            continue
        sign = -1.0 if rows.voxel[r, 0] > rows.voxel[r, 1] else 1.0
        used = rows.used[r]
        normal = carried[found, 0]
        mu = friction * rows.grip[r]
        for i in range(used):
            rw[r, RW_ACC + i] = normal / used
        for j in range(3):
            axis = (j + 1) % 3  # t1, t2, then n (twist)
            o = 1 if j < 2 else 4
            rw[r, RW_ACC + 4 + j] = sign * (carried[found, o] * frame[r, axis, 0]
                                            + carried[found, o + 1] * frame[r, axis, 1]
                                            + carried[found, o + 2] * frame[r, axis, 2])
        f1, f2 = rw[r, RW_ACC + 4], rw[r, RW_ACC + 5]
        size = math.sqrt(f1 * f1 + f2 * f2)
        if size > mu * normal:
            rw[r, RW_ACC + 4] *= mu * normal / size
            rw[r, RW_ACC + 5] *= mu * normal / size
        twist = mu * normal * rows.arm[r]
        rw[r, RW_ACC + 6] = min(max(rw[r, RW_ACC + 6], -twist), twist)
        for side in range(2):
            e = ends[r, side]
            if e < 0:
                continue
            sgn = 1.0 if side == 1 else -1.0
            px, py, pz = 0.0, 0.0, 0.0
            for a in range(3):
                d = rw[r, RW_ACC + 4] * frame[r, 1, a] + rw[r, RW_ACC + 5] * frame[r, 2, a]
                if a == 0:
                    px = d
                elif a == 1:
                    py = d
                else:
                    pz = d
            apply_at(e, sgn, px, py, pz, r, side, bw, rw)
            tw = sgn * rw[r, RW_ACC + 6]
            turn_by(e, tw * frame[r, 0, 0], tw * frame[r, 0, 1], tw * frame[r, 0, 2], bw)
            for i in range(used):
                push_corner(e, sgn * rw[r, RW_ACC + i], r, i, side, rows.frame, bw, rw)


@helper
def _remember(memory, count, rw, bounce) -> None:
    """Keep the impulses of the rows that carried load (not bounces) for the next step,
    and each row's normal impulse in rows.impulse, its friction in rows.friction."""
    rows, keys, carried = memory.rows, memory.keys, memory.carried
    p = 0
    for r in range(count):
        normal = 0.0
        for i in range(rows.used[r]):
            normal += rw[r, RW_ACC + i]
        rows.impulse[r] = normal
        for a in range(3):
            rows.friction[r, a] = (rw[r, RW_ACC + 4] * rows.frame[r, 1, a]
                                   + rw[r, RW_ACC + 5] * rows.frame[r, 2, a])
        if bounce[r] or normal <= 0.0:
            continue
        sign = -1.0 if rows.voxel[r, 0] > rows.voxel[r, 1] else 1.0
        keys[p] = rows.key[r]
        carried[p, 0] = normal
        for a in range(3):
            carried[p, 1 + a] = sign * (rw[r, RW_ACC + 4] * rows.frame[r, 1, a]
                                        + rw[r, RW_ACC + 5] * rows.frame[r, 2, a])
            carried[p, 4 + a] = sign * rw[r, RW_ACC + 6] * rows.frame[r, 0, a]
        p += 1
    memory.count[0] = p
