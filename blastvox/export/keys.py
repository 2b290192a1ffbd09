"""Keyframe reduction: which frames of each piece's animation an export keeps as keys.

A piece's transform is known at every frame; a reader interpolates between the keys
a file holds (USD and glTF LINEAR: translations linearly, rotations by slerp). A frame
is kept only where interpolating between the kept keys around it would miss the true
transform at some frame by more than the tolerance: ``key_tolerance_m`` (m) for a
translation, ``key_tolerance_deg`` (degrees) for a rotation (the angle of the rotation
between the interpolated and the true orientation). So a piece at rest before it breaks
and one lying still after it settles cost two keys, a steady spin costs two keys, and a
ballistic arc (which linear interpolation cannot follow: it misses by g (n dt)^2 / 8 over
n frames, 8.5 mm at 24 fps for a one-frame gap) keeps nearly every frame.

The choice is greedy and deterministic: from a key a, the span to a frame b is extended
while every frame between a and b is within tolerance of the interpolation of a and b;
where it fails, b - 1 becomes the next key. Keys hold the exact (already quantised)
values, so the file is exact at every key and within tolerance everywhere else; the
first live frame is always a key, and the last one unless it repeats the key before it
(readers hold the last key). Tolerances of 0 keep the ends of runs of
equal values only (:func:`blastvox.export.usd_specs.run_ends_pf`), the exact export.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.export.options import KEY_TOLERANCE_DEG, KEY_TOLERANCE_M
from blastvox.jit import helper, kernel

__all__ = ["KEY_TOLERANCE_DEG", "KEY_TOLERANCE_M", "reduce_keys"]


def reduce_keys(times: np.ndarray, position: np.ndarray | None, orientation: np.ndarray | None,
                live: np.ndarray, tolerance_m: float, tolerance_deg: float) -> np.ndarray:
    """(P, F) bool: the frames each piece keeps as keys.

    times (F,): the key times as the reader interpolates them (USD: frame index; glTF:
    seconds). position (P, F, 3) m or None (translation not checked); orientation
    (P, F, 4) unit quaternions, each key in the hemisphere of the previous one (any
    component order, the same at every frame), or None. live (P,): frames 0..live-1 of
    each piece are animated (later frames are not keyed). A frame is kept where the
    interpolation of the kept keys around it would miss a frame's translation by more
    than ``tolerance_m`` (m) or its rotation by more than ``tolerance_deg`` (degrees).
    Rotations are checked against slerp (the formats' rule) and against the normalised
    component-wise lerp (what Blender's quaternion F-curves do), and two keys of a span
    are never more than 180 degrees of quaternion apart (a dot product >= 0).
    """
    p_count, f_count = live.shape[0], len(times)
    pos = (np.zeros((p_count, f_count, 3)) if position is None
           else np.ascontiguousarray(position, dtype=np.float64))
    ori = (np.zeros((p_count, f_count, 4)) if orientation is None
           else np.ascontiguousarray(orientation, dtype=np.float64))
    keep = np.zeros((p_count, f_count), dtype=np.bool_)
    # cos of half the tolerance angle: |q_interp . q_true| below it misses by more (libm's
    # cosine: numpy's would round as the CPU it dispatched to, blastvox.geometry.fixed)
    half = math.radians(float(tolerance_deg)) / 2.0
    _reduce(np.ascontiguousarray(times, dtype=np.float64), pos, ori,
            np.minimum(np.asarray(live, dtype=np.int64), f_count), float(tolerance_m),
            math.cos(half) if orientation is not None else -2.0, keep)
    return keep


@kernel
def _reduce(times, pos, ori, live, tol_m, cos_half, keep):  # pragma: no cover - numba
    """Greedy key choice per piece (see :func:`reduce_keys`); fills ``keep`` (P, F)."""
    tol2 = tol_m * tol_m
    for p in range(pos.shape[0]):
        n = live[p]
        if n <= 0:
            continue
        keep[p, 0] = True
        keep[p, n - 1] = True
        a = 0
        b = 2
        flat = _same(pos, ori, p, 0, 1)  # frames a..b-1 equal: nothing to check inside
        while b < n:
            ok = True
            span = times[b] - times[a]
            if flat and _same(pos, ori, p, a, b):
                b += 1  # a piece lying still: O(1) a frame, not a check of every frame
                continue
            flat = False
            for k in range(a + 1, b):
                u = (times[k] - times[a]) / span if span > 0 else 0.0
                d2 = 0.0
                for c in range(3):
                    d = pos[p, a, c] + u * (pos[p, b, c] - pos[p, a, c]) - pos[p, k, c]
                    d2 += d * d
                if d2 > tol2:
                    ok = False
                    break
                if cos_half > -1.5 and _slerp_dot(ori, p, a, b, k, u) < cos_half:
                    ok = False
                    break
            if ok:
                b += 1
            else:
                keep[p, b - 1] = True
                a = b - 1
                b = a + 2
                flat = b - 1 < n and _same(pos, ori, p, a, b - 1)
        if n > 1 and a < n - 1 and _same(pos, ori, p, a, n - 1):
            keep[p, n - 1] = False  # a reader holds the last key: drop a repeat of it


@helper
def _same(pos, ori, p, i, j) -> bool:  # pragma: no cover - numba
    """Do frames i and j of piece p hold the same translation and rotation, bit for bit?"""
    for c in range(3):
        if pos[p, i, c] != pos[p, j, c]:
            return False
    for c in range(4):
        if ori[p, i, c] != ori[p, j, c]:
            return False
    return True


@helper
def _slerp_dot(ori, p, a, b, k, u):  # pragma: no cover - numba
    """The cosine of half the angle between ori[p, k] and the rotation interpolated
    between ori[p, a] and ori[p, b] at u, the smaller of slerp's and of the normalised
    lerp's; -1 if the two keys are more than 180 degrees of quaternion apart."""
    dot = 0.0
    for c in range(4):
        dot += ori[p, a, c] * ori[p, b, c]
    if dot < 0.0:
        return -1.0
    if dot > 1.0:
        dot = 1.0
    theta = np.arccos(dot)
    if theta < 1e-9:
        wa, wb = 1.0 - u, u
    else:
        s = np.sin(theta)
        wa, wb = np.sin((1.0 - u) * theta) / s, np.sin(u * theta) / s
    worst = 1.0
    for pass_ in range(2):
        if pass_ == 1:
            wa, wb = 1.0 - u, u
        norm = 0.0
        out = 0.0
        for c in range(4):
            q = wa * ori[p, a, c] + wb * ori[p, b, c]
            norm += q * q
            out += q * ori[p, k, c]
        norm = np.sqrt(norm)
        cos = abs(out) / norm if norm > 0 else 0.0
        if cos < worst:
            worst = cos
    return worst
