"""One island's sweeps of the soft step (see :mod:`~blastvox.simulate.contact.solver`):
:func:`island_substeps` runs an island's sub-steps, :func:`soft_sweep` one sweep over some
of its rows, :func:`soft_row` the update of one row (the solver's hot loop); with what
the solver checks after them (:func:`kinetic_energy`, :func:`push_speed`) and undoes
(:func:`undo_solve`)."""

from __future__ import annotations

import math

from blastvox.jit import helper
from blastvox.simulate.contact.warmstart import apply_carried
from blastvox.simulate.integrate import (
    CORNER_SWEEPS,
    CORNER_TOLERANCE,
    RW_ACC,
    RW_CA,
    RW_CB,
    RW_EFF,
    RW_KN,
)


@helper
def island_substeps(rows, ends, bw, rw, moved, total, rs, es, coef, scratch) -> None:
    """The soft step (Box2D v3's solver) of one island, rows rs (in support order) and
    moving bodies es: coef[10] sub-steps of h = coef[0], each: its share of
    the step's loads and gravity, the carried impulses applied again, one sweep with
    the soft push-out, the positions moved, one rigid sweep (relax) that takes the
    push-out's speed back out. moved (n, 6): displacement (m) and rotation vector (rad)
    of each body so far; total (count, 7): impulses (N s, N m s) applied so far;
    scratch (12,)."""
    withhold_loads(bw, es)
    for _ in range(int(coef[10])):
        share_loads(bw, es, coef)
        apply_carried(rows, ends, bw, rw, total, rs)
        soft_sweep(rows, ends, bw, rw, moved, total, rs, coef, True, scratch)
        move_bodies(bw, moved, es, coef)
        soft_sweep(rows, ends, bw, rw, moved, total, rs, coef, False, scratch)


@helper
def withhold_loads(bw, es) -> None:
    """Take the step's loads and gravity (bw's columns 24-29, which the engine gave the
    velocities whole) back out of bodies es: the sub-steps hand them out in shares."""
    for e in es:
        for a in range(6):
            bw[e, a] -= bw[e, 24 + a]


@helper
def share_loads(bw, es, coef) -> None:
    """One sub-step's share (1 / coef[10]) of the step's loads and gravity to bodies es."""
    share = 1.0 / coef[10]
    for e in es:
        for a in range(6):
            bw[e, a] += bw[e, 24 + a] * share


@helper
def move_bodies(bw, moved, es, coef) -> None:
    """Bodies es moved over a sub-step h = coef[0] at their velocities (moved, see
    :func:`island_substeps`)."""
    h = coef[0]
    for e in es:
        for a in range(6):
            moved[e, a] += bw[e, a] * h


@helper
def soft_sweep(rows, ends, bw, rw, moved, total, rs, coef, push, scratch) -> None:
    """One sweep of :func:`soft_row` over rows rs: in order with the soft push-out
    (push), else in reverse order, rigid (the relax sweep)."""
    count = rs.shape[0]
    for q in range(count):
        r = rs[q] if push else rs[count - 1 - q]
        soft_row(r, rows, ends, bw, rw, moved, total, coef, push, scratch)


@helper
def soft_row(r, rows, ends, bw, rw, moved, total, coef, push, scratch) -> None:
    """One sweep's update of row r: the normal impulses of its corners (>= 0), each
    against its separation now (the start's, plus what the sub-steps moved the bodies),
    speculative where apart, soft where deeper than the slop (push: the soft
    push-out; else rigid), then friction at the centre within mu times their sum
    (both tangents at once) and twisting friction about n. Written out in full, with
    both bodies' velocities in locals: the solver's hot loop."""
    frame = rows.frame
    ea, eb = ends[r, 0], ends[r, 1]
    (avx, avy, avz, awx, awy, awz, ima,
     a0, a1, a2, a3, a4, a5, a6, a7, a8) = body_locals(bw, ea)
    (bvx, bvy, bvz, bwx, bwy, bwz, imb,
     b0, b1, b2, b3, b4, b5, b6, b7, b8) = body_locals(bw, eb)
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
def body_locals(bw, e):
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
def push_speed(rows, ends, rs, coef) -> float:
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


@helper
def kinetic_energy(bw, col, es, masses) -> float:
    """Kinetic energy (J) of the solve's bodies es at the velocities in bw's columns
    col..col+5 (0: now, 6: before the solve): m v^2 / 2 + w . (R I R^T) w / 2. masses:
    (ids: the solve's bodies; mass, rot, inertia: every body's)."""
    ids, mass, rot_all, inertia_all = masses
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
def undo_solve(bw, rw, moved, total, rs, es) -> None:
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
