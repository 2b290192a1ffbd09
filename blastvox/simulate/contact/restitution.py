"""The contact solve's restitution pass (:func:`restitution`): after the sub-steps,
impacts bounce."""

from __future__ import annotations

import numpy as np

from blastvox.jit import helper
from blastvox.simulate.integrate import (
    CORNER_SWEEPS,
    CORNER_TOLERANCE,
    RW_ACC,
    RW_KN,
    RW_TARGET,
    corner_speed,
    push_corner,
)

#: Sweeps at most of the restitution pass, which stops once no bounce changes a
#: corner's normal velocity by more than SOLVED_SPEED (m/s).
RESTITUTION_SWEEPS = 8
SOLVED_SPEED = 1e-3


@helper
def restitution(rows, ends, bw, rw, total, rs, rest_speed, bounce) -> None:
    """After the sub-steps: the corners that came in faster than rest_speed (m/s) and
    were stopped (took an impulse) leave at restitution times their approach speed
    (Box2D v3's restitution pass), over the island's rows rs, a row's corners solved
    together (so a face lands flat), in sweeps until no bounce changes by more than
    SOLVED_SPEED (a piece that lands on two others at once bounces once, not twice).
    Sets bounce (count,) bool of the rows that bounced."""
    hit = np.zeros(4, dtype=np.bool_)
    b = np.zeros(8)  # the corners' residuals, then their impulses
    for r in rs:
        for i in range(rows.used[r]):
            bounce[r] |= rw[r, RW_TARGET + i] <= -rest_speed and total[r, i] > 0.0
    for _ in range(RESTITUTION_SWEEPS):
        largest = 0.0
        for r in rs:
            if bounce[r] and rows.restitution[r] != 0.0:
                largest = max(largest, _bounce_row(r, rows, ends, bw, rw, total, rest_speed,
                                                   hit, b))
        if largest <= SOLVED_SPEED:
            return


@helper
def _bounce_row(r, rows, ends, bw, rw, total, rest_speed, hit, b) -> float:
    """One restitution update of row r (see :func:`restitution`); returns the largest
    change of a corner's normal velocity, m/s. hit (4,), b (8,): scratch."""
    used = rows.used[r]
    for i in range(used):
        hit[i] = rw[r, RW_TARGET + i] <= -rest_speed and total[r, i] > 0.0
        b[4 + i] = 0.0
        b[i] = -(corner_speed(r, i, ends, rows.frame, bw, rw)
                 + rows.restitution[r] * rw[r, RW_TARGET + i]) if hit[i] else 0.0
    for _ in range(CORNER_SWEEPS):
        change = 0.0
        for i in range(used):
            kii = rw[r, RW_KN + i * (7 - i) // 2 + i]
            if not hit[i] or kii <= 0.0:
                continue
            res = b[i]
            for j in range(used):
                if hit[j]:
                    res -= rw[r, RW_KN + (i * (7 - i) // 2 + j if i <= j
                                          else j * (7 - j) // 2 + i)] * b[4 + j]
            new = max(rw[r, RW_ACC + i] + b[4 + i] + res / kii, 0.0) - rw[r, RW_ACC + i]
            change = max(change, abs(new - b[4 + i]) * kii)
            b[4 + i] = new
        if change <= CORNER_TOLERANCE:
            break
    largest = 0.0
    for i in range(used):
        d = b[4 + i]
        if d == 0.0:
            continue
        largest = max(largest, abs(d) * rw[r, RW_KN + i * (7 - i) // 2 + i])
        rw[r, RW_ACC + i] += d
        total[r, i] += d
        for side in range(2):
            e = ends[r, side]
            if e >= 0:
                push_corner(e, d if side == 1 else -d, r, i, side, rows.frame, bw, rw)
    return largest
