"""Which bodies stand balanced on their contacts (:func:`balance`): only those rest (damped,
then asleep); one held up by friction alone, wedged or leaning, may still slide or
tip (issue 34)."""

from __future__ import annotations

import numpy as np

from blastvox.jit import helper, kernel
from blastvox.simulate.contact.ground import _hull_contains

#: A contact holds a body up when its normal on the body is within 60 degrees of up.
SUPPORT_COS = 0.5


@kernel
def balance(rows, end, bodies, up_axis, balanced) -> None:
    """balanced (B,) bool: whether each body's centre of mass stands (along the model's
    up axis, up_axis 0-2) within the convex hull of its contact points that held it up
    this step: the corners of rows 0..end that carried load, whose normal on the body
    points within 60 degrees of up (the ground, a floor, a piece below). A body wedged
    between others or leaning on a wall is held by friction: it is not balanced."""
    n = bodies.count[0]
    e1, e2 = (up_axis + 1) % 3, (up_axis + 2) % 3
    start = np.zeros(n + 1, dtype=np.int64)
    for r in range(end):
        for side in range(2):
            b = rows.body[r, side]
            if b >= 0 and _holds_up(rows, r, side, up_axis):
                start[b + 1] += rows.used[r]
    for b in range(n):
        start[b + 1] += start[b]
    px = np.empty(start[n])
    py = np.empty(start[n])
    fill = start[:-1].copy()
    for r in range(end):
        for side in range(2):
            b = rows.body[r, side]
            if b >= 0 and _holds_up(rows, r, side, up_axis):
                for i in range(rows.used[r]):
                    px[fill[b]] = rows.corners[r, i, e1]
                    py[fill[b]] = rows.corners[r, i, e2]
                    fill[b] += 1
    for b in range(n):
        count = start[b + 1] - start[b]
        balanced[b] = count > 0 and _hull_contains(
            px[start[b]:start[b + 1]], py[start[b]:start[b + 1]], count, bodies.pos[b, e1],
            bodies.pos[b, e2], 1e-9 * max(1.0, bodies.radius[b]))


@helper
def _holds_up(rows, r, side, up_axis) -> bool:
    """Did row r push its body on ``side`` (0: a, 1: b; the normal points from a to b)
    up, carrying load?"""
    up = rows.frame[r, 0, up_axis] if side == 1 else -rows.frame[r, 0, up_axis]
    return rows.impulse[r] > 0.0 and up >= SUPPORT_COS
