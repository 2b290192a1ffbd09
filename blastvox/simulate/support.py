"""Support: a free body held up by what is left of a structure carries its weight.

A piece that breaks off a structure and rests on, leans on or hangs from a
founded body, or lies on the ground, was a rigid body whatever its span: a slab
that lost its columns could rest on half its length, a freed half of a lintel
hang beside its pier (issue 34). Its links are solved under its weight on the
voxels that hold it up (:func:`support_phase`), with the stress solver of
founded bodies (:mod:`blastvox.simulate.stress`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from blastvox.geometry import exact
from blastvox.simulate.stress import EVENT_BAND, Stress, break_links, links_among, solve_body

#: A free body slower than this (m/s) is held up by what it touches: its weight is
#: judged on its supports (:func:`support_phase`).
RESTING_SPEED = 1.0
#: A free body sits on another where their contact pushes it up within 60 degrees.
SITS_COS = 0.5
#: A body judged standing on a set of supports is not judged again on the same set
#: unless it has tilted by more than this (rad) since: its levers have not changed.
SAME_TILT = math.radians(2.0)


def support_phase(model, state, stress: Stress, gravity: np.ndarray, rows, end: int,
                  ground: float | None) -> bool:
    """Phase: the weight of a free body held up by the ground or a founded body.

    A free body that broke off a structure and rests on, leans on or hangs from
    what is left of it (slower than :data:`RESTING_SPEED`) carries its weight to the
    voxels that touch a founded body in the step's contacts (rows, the first ``end``
    of the contact rows that pushed) or lie on the ground (at ``ground`` m along
    up, or None: no ground; the ground's rows name only a body's corners, so every
    voxel within 1.5 contact radii of the plane is a support of a body that touches
    it): they are its supports, and
    its links are solved as a founded body's (:func:`solve`, gravity (3,) m/s^2 in
    its rest frame). A slab that lost its columns and rests on half its span is a
    cantilever, and it breaks where beam theory breaks it; the links inside a chunk
    of a material that crushes never break (the smallest rubble). A body is judged
    again only when its live voxels, its contact voxels or whether it touches the
    ground change (stress.rested), and never again on a set of supporting voxels it
    stood on, tilted by no more than :data:`SAME_TILT`, since its voxels last changed
    (stress.judged: a pile's contacts come and go from step to step, and 95 % of the
    building pile's solves were repeats).

    Writes links.alive, marks.broken, marks.dirty and counters.broken_links.
    Returns whether any link broke (the caller splits)."""
    if end == 0 or not float(exact.dot(gravity, gravity)) > 0.0:
        return False
    bodies, voxels = state.bodies, state.voxels
    body, vox = rows.body[:end], rows.voxel[:end]
    # a contact that pushed, or touches: a solve leaves some resting contacts at no
    # impulse (another point took the load), and a support left out would make a
    # symmetric body asymmetric
    pushed = (rows.impulse[:end] > 0.0) | (rows.gap[:end] <= 0.0)
    held = (body < 0) | bodies.fixed[np.maximum(body, 0)]  # ground or founded, per side
    # or a slow free body it sits on: a row that pushes it up (within 60 degrees)
    up = -gravity / float(exact.norm(gravity))
    lift = exact.dot(rows.frame[:end, 0], up)  # the normal's push on side 1, along up
    slow_body = exact.norm(bodies.lin) <= RESTING_SPEED * bodies.mass
    under = [(body[:, 1 - k] >= 0) & slow_body[np.maximum(body[:, 1 - k], 0)]
             & ((lift if k == 1 else -lift) >= SITS_COS) for k in range(2)]
    ends = [pushed & (body[:, k] >= 0) & ~held[:, k] & (held[:, 1 - k] | under[k])
            for k in range(2)]
    owner = np.concatenate([body[ends[0], 0], body[ends[1], 1]])
    support = np.concatenate([vox[ends[0], 0], vox[ends[1], 1]])
    point = np.concatenate([rows.point[:end][ends[0]], rows.point[:end][ends[1]]])
    on_ground = np.concatenate([body[ends[0], 1] < 0, body[ends[1], 0] < 0])
    if not support.size:
        return False
    started = time.perf_counter()
    any_broken = False
    candidates = np.unique(owner)
    slow = (bodies.live[candidates] & ~bodies.dust[candidates] & ~bodies.fixed[candidates]
            & (np.linalg.norm(bodies.lin[candidates], axis=1)
               <= RESTING_SPEED * bodies.mass[candidates]))
    if not slow.any():
        return False
    count = np.bincount(voxels.body[voxels.alive], minlength=len(bodies.live))
    # what each rests on: its live voxels, its distinct contact voxels and whether it
    # is on the ground; a body is judged again only when that changes
    span = len(voxels.alive) + 1  # support -1 (none) is a distinct value too
    distinct = np.bincount(np.unique(owner * span + (support + 1)) // span,
                           minlength=len(bodies.live))
    grounded = np.zeros(len(bodies.live), dtype=bool)
    grounded[owner[on_ground]] = True
    order = np.argsort(owner, kind="stable")
    bounds = np.searchsorted(owner[order], np.append(candidates, np.iinfo(np.int64).max))
    at_rest = np.flatnonzero(slow)
    mine = candidates[at_rest]
    # as Python values at once: hundreds of pile pieces are looked up every step
    for i, b, key in zip(at_rest.tolist(), mine.tolist(),
                         zip(count[mine].tolist(), distinct[mine].tolist(),
                             grounded[mine].tolist(), strict=True), strict=True):
        if key[0] < 2 or stress.rested.get(b) == key:
            continue
        rows_of = order[bounds[i]:bounds[i + 1]]
        stress.rested[b] = key
        placed = ~on_ground[rows_of] & (support[rows_of] >= 0)
        under = support[rows_of][placed]
        members = lying = None
        if ground is not None and key[2]:
            members = np.flatnonzero(voxels.alive & (voxels.body == b))
            lying = _on_the_ground(model, bodies, b, members, ground)
        if not under.size and (lying is None or not lying.size):
            continue
        # a pile's contacts flicker: a support it stood on comes back
        signature = np.unique(under if lying is None
                              else np.concatenate([under, lying])).tobytes()
        down = _in_rest_frame(gravity, bodies.rot[b])
        if _stood_before(stress, b, signature, down):
            continue
        at = exact.vecmat(point[rows_of][placed] - bodies.pos[b], bodies.rot[b]) + bodies.com[b]
        if lying is not None:
            under = np.concatenate([under, lying])
            at = np.concatenate([at, model.voxels.centroid[lying]])
        if members is None:
            members = np.flatnonzero(voxels.alive & (voxels.body == b))
        if _supported(model, state, stress, b, members, under, at, gravity):
            any_broken = True
        else:
            stress.judged.setdefault(b, {}).setdefault(signature, []).append(down)
    stress.seconds += time.perf_counter() - started
    return any_broken


def _in_rest_frame(gravity: np.ndarray, rot: np.ndarray) -> tuple[float, float, float]:
    """gravity (3,) in the rest frame of a body turned by rot (3, 3): g R, in Python
    floats (the same IEEE operations, in the same order, as
    :func:`blastvox.geometry.exact.vecmat`; a pile asks it of hundreds of bodies a step)."""
    g0, g1, g2 = gravity.tolist()
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rot.tolist()
    return (g0 * r00 + g1 * r10 + g2 * r20, g0 * r01 + g1 * r11 + g2 * r21,
            g0 * r02 + g1 * r12 + g2 * r22)


def _stood_before(stress: Stress, b: int, signature: bytes, down) -> bool:
    """Whether body b stood on the supporting voxels ``signature`` (sorted, as bytes)
    with gravity ``down`` (3,) m/s^2 in its rest frame within :data:`SAME_TILT` rad of
    a direction it was judged under since its voxels last changed (Python floats: the
    same roundings as :mod:`blastvox.geometry.exact`'s products, without an array per
    direction)."""
    d0, d1, d2 = (float(x) for x in down)
    size = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    least = math.cos(SAME_TILT)
    for s0, s1, s2 in stress.judged.get(b, {}).get(signature, ()):
        cos = (s0 * d0 + s1 * d1 + s2 * d2) / (math.sqrt(s0 * s0 + s1 * s1 + s2 * s2) * size)
        if cos >= least:
            return True
    return False


def _on_the_ground(model, bodies, b: int, members: np.ndarray, ground: float) -> np.ndarray:
    """The voxels of body b (its ``members``) whose centroid is within 1.5 contact
    radii of the ground plane at ``ground`` m along up."""
    rest = model.voxels.centroid[members] - bodies.com[b]
    height = exact.dot(exact.matvec(bodies.rot[b], rest) + bodies.pos[b], model.up)
    return members[height - ground <= 1.5 * model.voxels.contact_radius[members]]


def _supported(model, state, stress: Stress, b: int, members: np.ndarray, under: np.ndarray,
               at: np.ndarray, gravity: np.ndarray) -> bool:
    """:func:`support_phase` of body b (its live voxels ``members``) resting on its
    voxels ``under`` (S,) at the points ``at`` (S, 3) m, rest frame."""
    links, ends = links_among(model, members)
    if not links.size or model.strength.inner[links].all():
        return False
    solution = solve_body(model, state, stress, members, links, ends,
                          np.isin(members, under), exact.vecmat(gravity, state.bodies.rot[b]),
                          bearing=(np.searchsorted(members, under), at))
    use = solution.stress[:, 3]
    between = ~model.strength.inner[links[solution.links]]  # a chunk never shatters
    if not (between & (use > 1.0)).any():
        return False
    worst = float(use[between].max())
    broken = links[solution.links[(use > 1.0) & between & (use >= EVENT_BAND * worst)]]
    stress.rested.pop(b, None)
    stress.judged.pop(b, None)
    break_links(state, stress, b, broken)
    return True

