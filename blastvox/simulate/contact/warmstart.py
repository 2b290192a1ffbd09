"""What contacts carry from sub-step to sub-step and from step to step (Catto 2005's
warm start): :func:`recall` gives a step's rows last step's impulses, :func:`apply_carried`
applies them again at each sub-step, :func:`remember` keeps them."""

from __future__ import annotations

import math

import numpy as np

from blastvox.jit import helper
from blastvox.simulate.contact.pairs import bucket, hash_buckets
from blastvox.simulate.integrate import RW_ACC, apply_at, push_corner, turn_by


@helper
def recall(memory, count, rw, friction) -> None:
    """Give each row the impulses (per sub-step) its contact carried last step
    (memory.keys, carried): the normal shared equally by its corners (their own solve
    shares it out), friction and twist taken onto its current directions and within
    its current limits."""
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


@helper
def apply_carried(rows, ends, bw, rw, total, rs) -> None:
    """Apply each of rows rs' accumulated impulses (a sub-step's: the warm start of the
    next sub-step) to its bodies, and count them in total."""
    frame = rows.frame
    for r in rs:
        for j in range(7):
            total[r, j] += rw[r, RW_ACC + j]
        for side in range(2):
            e = ends[r, side]
            if e < 0:
                continue
            sgn = 1.0 if side == 1 else -1.0
            f1, f2 = rw[r, RW_ACC + 4], rw[r, RW_ACC + 5]
            if f1 != 0.0 or f2 != 0.0:
                apply_at(e, sgn, f1 * frame[r, 1, 0] + f2 * frame[r, 2, 0],
                         f1 * frame[r, 1, 1] + f2 * frame[r, 2, 1],
                         f1 * frame[r, 1, 2] + f2 * frame[r, 2, 2], r, side, bw, rw)
            tw = sgn * rw[r, RW_ACC + 6]
            if tw != 0.0:
                turn_by(e, tw * frame[r, 0, 0], tw * frame[r, 0, 1], tw * frame[r, 0, 2], bw)
            for i in range(rows.used[r]):
                if rw[r, RW_ACC + i] != 0.0:
                    push_corner(e, sgn * rw[r, RW_ACC + i], r, i, side, frame, bw, rw)


@helper
def remember(memory, count, rw, total, bounce) -> None:
    """Keep the impulses (per sub-step) of the rows that carried load (not bounces) for
    the next step, and each row's normal impulse over the step in rows.impulse, its
    friction in rows.friction."""
    rows, keys, carried = memory.rows, memory.keys, memory.carried
    p = 0
    for r in range(count):
        normal = 0.0
        last = 0.0
        for i in range(rows.used[r]):
            normal += total[r, i]
            last += rw[r, RW_ACC + i]
        rows.impulse[r] = normal
        for a in range(3):
            rows.friction[r, a] = (total[r, 4] * rows.frame[r, 1, a]
                                   + total[r, 5] * rows.frame[r, 2, a])
        if bounce[r] or last <= 0.0:
            continue
        sign = -1.0 if rows.voxel[r, 0] > rows.voxel[r, 1] else 1.0
        keys[p] = rows.key[r]
        carried[p, 0] = last
        for a in range(3):
            carried[p, 1 + a] = sign * (rw[r, RW_ACC + 4] * rows.frame[r, 1, a]
                                        + rw[r, RW_ACC + 5] * rows.frame[r, 2, a])
            carried[p, 4 + a] = sign * rw[r, RW_ACC + 6] * rows.frame[r, 0, a]
        p += 1
    memory.count[0] = p


def mass_kept(mass_before: np.ndarray, bodies) -> np.ndarray:
    """(B,) the fraction of its mass before a split that each body has after it: a body
    that kept its slot against its own mass before (mass_before (K,) kg, the first K
    bodies'), one split off since against the body it came from (its first ancestor
    among them); 1 for founded bodies (they do not move) and bodies born whole."""
    count, known = int(bodies.count[0]), len(mass_before)
    origin = np.arange(count)
    late = origin >= known
    while late.any():  # new bodies: up their parents to one that existed before
        origin[late] = bodies.parent[origin[late]]
        late = origin >= known
    kept = np.ones(len(bodies.mass))
    was = mass_before[np.maximum(origin, 0)]
    judged = (origin >= 0) & ~bodies.fixed[:count] & (was > 0.0)
    kept[:count][judged] = np.minimum(1.0, bodies.mass[:count][judged] / was[judged])
    return kept


def lighten_carried(memory, voxel_body: np.ndarray, kept: np.ndarray) -> None:
    """Scale what contacts carry to the next step by what their bodies kept of their
    mass in a split (kept (B,), :func:`mass_kept`; the smaller of a pair's two).

    A carried impulse is the load a contact held for the bodies it joined: the weight
    of a roof on a wall top, say. A piece that split off may weigh a hundredth of
    that, and the whole impulse would throw it (a 9 kg piece of the house example's
    roof left at 22 m/s, 2.6 s in); a piece that burnt a voxel away carries almost
    what it did (its contacts starting cold every step pumped it up and down).
    voxel_body (N,): each voxel's body after the split (-1: none). The ground's rows
    (keys -1 - body) scale by their body's.
    """
    p = int(memory.count[0])
    if p == 0 or not (kept < 1.0).any():
        return
    keys, n = memory.keys[:p], len(voxel_body)
    pair = keys >= 0
    body_kept = np.append(kept, 1.0)  # voxel_body -1 and a ground row's -1: 1
    first = voxel_body[np.where(pair, keys // n, 0)]
    second = voxel_body[np.where(pair, keys % n, 0)]
    ground = np.where(pair, -1, -1 - keys)
    scale = np.where(pair, np.minimum(body_kept[first], body_kept[second]), body_kept[ground])
    memory.carried[:p] *= scale[:, None]
