"""Ground contact (Martins 2001 §5.2).

Like fragment collisions (:mod:`blastvox.simulate.contact.fragments`), it acts at velocity
level between the velocity and position halves of the step, and never adds energy:
an impulse only removes approach velocity, or reflects it with a restitution
coefficient e <= 1.

Ground: an infinite-mass plane at the scene's ground height. Contact points are the
corners of a body's boundary voxels that are at or below the plane, or would reach
it this step (speculative contacts, so fast debris cannot tunnel and resting bodies
do not sink, without pushing positions around). They are rows of the contact solver
(:func:`~blastvox.simulate.contact.solver.solve_contacts`), with the fragments' contacts when
fragments collide (:func:`~blastvox.simulate.contact.fragments.collide_phase` solves both, so a
stack's weight reaches the ground), alone otherwise: normal and tangential impulses
solved together by the soft step's sweeps; the tangential part is Coulomb
friction, the "pseudo-friction" of the paper: it opposes the tangential velocity and
grows with the body's mass and speed up to mu times the normal impulse.
A body in resting contact loses a part of its momenta (damping); with three or more
contact points, small velocities and its centre of mass over the *exact convex hull*
of its contact points (the paper used their bounding rectangle to save time), it is
clamped to rest and sleeps until something wakes it.

Also here, as every contact phase needs them: :class:`ContactRows`, the form both the
ground's and the fragments' contacts take for the solver, and :class:`ContactMemory`,
what they keep from step to step.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from blastvox.jit import helper, kernel
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.contact.rows import ContactRows
from blastvox.simulate.contact.solver import solve_contacts
from blastvox.simulate.integrate import angular_velocity
from blastvox.simulate.limits import voxel_size

#: Penetration (and gap) the contact solver leaves alone, and the most its position
#: pass moves a contact apart in a step, as fractions of the typical voxel.
SLOP = 1e-3
PUSH = 0.05


class ContactMemory(NamedTuple):
    """What contacts keep from step to step, and their scratch.

    rows: :class:`ContactRows`; keys (M,) int64 and carried (M, 7): the contacts of
    the last step that carried load, and their impulses (normal N s, then the
    friction impulse and the angular impulse as world vectors on body b, sign
    flipped when voxel a > voxel b so that a pair seen either way round agrees);
    count (1,) int64: how many; local (B,) int64: scratch, -1 for every body;
    half (N, 3) m: each voxel's contact box, half extents along its rest axes,
    centred on its centroid
    (:func:`blastvox.simulate.contact.fragments.voxel_boxes`); radius (N,) m: the box's
    half diagonal; deepest (1,) m: the deepest penetration any step has seen; stats
    (4,) int64: solves, sub-steps, unused, islands solved again
    without the warm start (see :data:`~blastvox.simulate.contact.solver.ENERGY_SLACK`);
    size: the
    model's typical voxel, m.
    """

    rows: ContactRows
    keys: np.ndarray
    carried: np.ndarray
    count: np.ndarray
    local: np.ndarray
    half: np.ndarray
    radius: np.ndarray
    deepest: np.ndarray
    stats: np.ndarray
    size: float


class SolverParams(NamedTuple):
    """dt: s; friction: Coulomb mu; rest_speed: m/s of approach below which a contact
    does not bounce; slop: m of penetration left alone; substeps: the solve's sub-steps;
    gravity (3,): m/s^2, what the step's velocities already hold of it; threads: how
    many the solve's islands are dealt to (numba's thread count: the bytes do not
    depend on it)."""

    dt: float
    friction: float
    rest_speed: float
    slop: float
    substeps: int
    gravity: np.ndarray
    threads: int


def empty_rows(capacity: int) -> ContactRows:
    """``capacity`` unused contact rows."""
    m = max(int(capacity), 16)
    return ContactRows(
        body=np.full((m, 2), -1, dtype=np.int64), voxel=np.full((m, 2), -1, dtype=np.int64),
        key=np.zeros(m, dtype=np.int64), frame=np.zeros((m, 3, 3)),
        corners=np.zeros((m, 4, 3)), corner_gap=np.zeros((m, 4)),
        used=np.zeros(m, dtype=np.int64), gap=np.zeros(m), point=np.zeros((m, 3)),
        arm=np.zeros(m), restitution=np.zeros(m),
        approach=np.zeros(m), impulse=np.zeros(m), friction=np.zeros((m, 3)),
        grip=np.ones(m))


def new_memory(state, size: float, half: np.ndarray, radius: np.ndarray) -> ContactMemory:
    """A run's :class:`ContactMemory`, stored in state.contacts.memory; size: the
    typical voxel (m); half, radius: the voxels' contact boxes (empty when fragments
    do not collide)."""
    m = 1024
    memory = ContactMemory(
        rows=empty_rows(m), keys=np.zeros(m, dtype=np.int64), carried=np.zeros((m, 7)),
        count=np.zeros(1, dtype=np.int64),
        local=np.full(len(state.bodies.mass), -1, dtype=np.int64), half=half, radius=radius,
        deepest=np.zeros(1), stats=np.zeros(4, dtype=np.int64), size=float(size))
    state.contacts = state.contacts._replace(memory=memory)
    return memory


def grow_rows(state, need: int, keep: int) -> ContactMemory:
    """Room for ``need`` contact rows (twice that), keeping the first ``keep`` rows and
    what is carried over."""
    memory = state.contacts.memory
    m = 2 * need
    rows = empty_rows(m)
    for new, old in zip(rows, memory.rows, strict=True):
        new[:keep] = old[:keep]
    keys = np.zeros(m, dtype=np.int64)
    carried = np.zeros((m, 7))
    p = int(memory.count[0])
    keys[:p] = memory.keys[:p]
    carried[:p] = memory.carried[:p]
    memory = memory._replace(rows=rows, keys=keys, carried=carried)
    state.contacts = state.contacts._replace(memory=memory)
    return memory


def rest_speed(settings, dt: float) -> float:
    """Approach (m/s) below which a contact rests rather than strikes, for a run's
    SimSettings and step dt (s): the sleep speed plus two steps of gravity."""
    return settings.sleep_speed + 2.0 * abs(settings.gravity) * dt


def solver_params(memory: ContactMemory, settings, dt: float, up: np.ndarray) -> SolverParams:
    """The contact solver's parameters for a run's SimSettings, step dt (s) and up
    (3,): the slop (:data:`SLOP`) of the typical voxel (memory.size, m)."""
    return SolverParams(dt=dt, friction=settings.friction,
                        rest_speed=rest_speed(settings, dt), slop=SLOP * memory.size,
                        substeps=int(settings.contact_substeps),
                        gravity=-settings.gravity * np.asarray(up, dtype=np.float64),
                        threads=nb.get_num_threads())


class GroundParams(NamedTuple):
    """dt: step, s; ground: plane height (m) along axis up_axis (0, 1, 2); friction:
    Coulomb mu; rest_damping: 1/s decay of momenta in resting contact; sleep_speed:
    m/s below which a balanced body with >= 3 contacts is clamped to rest."""

    dt: float
    ground: float
    up_axis: int
    friction: float
    rest_damping: float
    sleep_speed: float


@kernel  # also called from Python, by balanced()
def _hull_contains(px, py, count, qx, qy, tol) -> bool:
    """Is (qx, qy) inside the convex hull of the first ``count`` 2-D points (px, py)?

    Gift wrapping, O(count x hull vertices): contact sets have a handful of hull
    vertices, and it needs no sort (a sort kernel costs seconds of compilation).
    tol (m): how far outside an edge still counts as inside.
    """
    if count < 3:
        return False
    first = 0
    for i in range(1, count):
        if px[i] < px[first] or (px[i] == px[first] and py[i] < py[first]):
            first = i
    a = first
    edges = 0
    for _ in range(count):
        # next hull vertex b: no point right of a->b (ties: the farthest), so the
        # walk is counter-clockwise and inside is left of every edge
        b = 1 if a == 0 else 0
        for i in range(count):
            cross = (px[b] - px[a]) * (py[i] - py[a]) - (py[b] - py[a]) * (px[i] - px[a])
            if cross < 0.0 or (cross == 0.0 and (px[i] - px[a]) ** 2 + (py[i] - py[a]) ** 2
                               > (px[b] - px[a]) ** 2 + (py[b] - py[a]) ** 2):
                b = i
        ex, ey = px[b] - px[a], py[b] - py[a]
        length = math.sqrt(ex * ex + ey * ey)
        if length == 0.0 or ex * (qy - py[a]) - ey * (qx - px[a]) < -tol * length:
            return False
        edges += 1
        a = b
        if a == first:
            return edges >= 3
    return False  # no closed walk: degenerate input


def balanced(points: np.ndarray, centre: np.ndarray, tol: float = 0.0) -> bool:
    """Is ``centre`` (2,) over the convex hull of ground contact ``points`` (K, 2)?"""
    p = np.ascontiguousarray(points, dtype=np.float64)
    return bool(_hull_contains(p[:, 0].copy(), p[:, 1].copy(), len(p), float(centre[0]),
                               float(centre[1]), tol))


@kernel
def ground_contacts(geometry, offsets, members, bodies, contacts, params, memory,
                    start) -> int:
    """Contact rows (memory.rows from row ``start``) of every moving body with the ground:
    one a body, its corners on the plane (four at most, :func:`pick_four`).

    geometry: the model's VoxelGeometry; offsets, members: each body's boundary
    voxels (CSR, :func:`blastvox.simulate.boundary.boundary_lists`); params:
    :class:`GroundParams`. Voxel corners are the contact candidates, each listed
    once a body (contacts.vertex_stamp (V,)), into contacts.points (K, 3) as
    (coordinate along e1, along e2, height above the plane, m); a voxel whose corners
    are all out of reach (its ``radius``, centroid to farthest corner) is skipped. A
    row: bodies (-1, b), the plane's normal and axes, the corners and their heights,
    the restitution of the lowest one's voxel. Returns the row after the last; rows
    past the capacity are counted, not written (grow and call again).
    """
    dt, ground, up_axis = params.dt, params.ground, params.up_axis
    vertices, voxel_vertices = geometry.contact_vertices, geometry.contact_corners
    voxel_centroid = geometry.centroid
    voxel_radius, voxel_restitution = geometry.radius, geometry.restitution
    vertex_stamp, points = contacts.vertex_stamp, contacts.points
    body_mass, body_inv_inertia, body_radius = bodies.mass, bodies.inv_inertia, bodies.radius
    body_com, body_pos, body_rot = bodies.com, bodies.pos, bodies.rot
    body_lin, body_ang, body_fixed, body_live = bodies.lin, bodies.ang, bodies.fixed, bodies.live
    body_dust, body_asleep, n_bodies = bodies.dust, bodies.asleep, bodies.count[0]
    rows = memory.rows
    capacity = rows.key.shape[0]
    e1 = (up_axis + 1) % 3
    e2 = (up_axis + 2) % 3
    owner = np.empty(points.shape[0], dtype=np.int64)
    picks = np.empty(4, dtype=np.int64)
    count = start
    for b in range(n_bodies):
        if not body_live[b] or body_fixed[b] or body_dust[b] or body_asleep[b]:
            continue
        m = body_mass[b]
        speed = math.sqrt(body_lin[b, 0] ** 2 + body_lin[b, 1] ** 2 + body_lin[b, 2] ** 2) / m
        rot = body_rot[b]
        omega = angular_velocity(rot, body_inv_inertia[b], body_ang[b])
        spin = math.sqrt(omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2)
        reach = (speed + spin * body_radius[b]) * dt + 1e-6
        if body_pos[b, up_axis] - body_radius[b] > ground + reach:
            continue
        # contact candidates: boundary-voxel corners at or near the plane
        found = 0
        for k in range(offsets[b], offsets[b + 1]):
            v = members[k]
            x = voxel_centroid[v, 0] - body_com[b, 0]
            y = voxel_centroid[v, 1] - body_com[b, 1]
            z = voxel_centroid[v, 2] - body_com[b, 2]
            h = body_pos[b, up_axis] + rot[up_axis, 0] * x + rot[up_axis, 1] * y \
                + rot[up_axis, 2] * z - ground
            if h - voxel_radius[v] > reach:
                continue  # every corner out of reach
            for c in range(8):
                vid = voxel_vertices[v, c]
                if vertex_stamp[vid] == b:
                    continue
                vertex_stamp[vid] = b
                x = vertices[vid, 0] - body_com[b, 0]
                y = vertices[vid, 1] - body_com[b, 1]
                z = vertices[vid, 2] - body_com[b, 2]
                h = body_pos[b, up_axis] + rot[up_axis, 0] * x + rot[up_axis, 1] * y \
                    + rot[up_axis, 2] * z - ground
                if h > reach or found >= points.shape[0]:
                    continue
                points[found, 0] = body_pos[b, e1] + rot[e1, 0] * x + rot[e1, 1] * y \
                    + rot[e1, 2] * z
                points[found, 1] = body_pos[b, e2] + rot[e2, 0] * x + rot[e2, 1] * y \
                    + rot[e2, 2] * z
                points[found, 2] = h
                owner[found] = v
                found += 1
        # forget the stamps of this body so later steps see its vertices again
        for k in range(offsets[b], offsets[b + 1]):
            for c in range(8):
                vertex_stamp[voxel_vertices[members[k], c]] = -1
        if found == 0:
            continue
        if count < capacity:
            _ground_row(rows, count, b, points, found, picks, up_axis, ground)
            rows.voxel[count, 1] = owner[picks[0]]
            rows.restitution[count] = voxel_restitution[owner[picks[0]]]
        count += 1
    return count


@helper
def _ground_row(rows, r, b, points, found, picks, up_axis, ground) -> None:
    """Row r: body b on the ground at up to four of its corner candidates points[:found]
    ((e1, e2, height) m), the lowest first (picks[0])."""
    e1, e2 = (up_axis + 1) % 3, (up_axis + 2) % 3
    used = pick_four(points, found, picks)
    for a in range(3):
        for j in range(3):
            rows.frame[r, j, a] = 0.0
    rows.frame[r, 0, up_axis] = 1.0
    rows.frame[r, 1, e1] = 1.0
    rows.frame[r, 2, e2] = 1.0
    rows.body[r, 0], rows.body[r, 1] = -1, b
    rows.voxel[r, 0] = -1
    rows.key[r] = -1 - b
    rows.used[r] = used
    c1 = c2 = ch = 0.0
    gap = np.inf
    for i in range(used):
        p = picks[i]
        rows.corners[r, i, e1] = points[p, 0]
        rows.corners[r, i, e2] = points[p, 1]
        rows.corners[r, i, up_axis] = ground + points[p, 2]
        rows.corner_gap[r, i] = points[p, 2]
        c1, c2, ch = c1 + points[p, 0] / used, c2 + points[p, 1] / used, ch + points[p, 2] / used
        gap = min(gap, points[p, 2])
    spread = 0.0
    for i in range(used):
        spread += math.sqrt((points[picks[i], 0] - c1) ** 2 + (points[picks[i], 1] - c2) ** 2)
    rows.point[r, e1], rows.point[r, e2], rows.point[r, up_axis] = c1, c2, ground + ch
    rows.gap[r] = gap
    rows.arm[r] = 0.54 * spread / used


@helper
def pick_four(points, n, picks) -> int:
    """At most four of the points[:n] (rows (u, v, depth) m), into picks (4,): the
    deepest, the farthest from it, and those farthest on either side of the line
    through both (the manifold reduction of Bullet and Box2D). Returns how many."""
    first = 0
    for i in range(1, n):
        if points[i, 2] < points[first, 2]:
            first = i
    far, best = first, -1.0
    for i in range(n):
        d = (points[i, 0] - points[first, 0]) ** 2 + (points[i, 1] - points[first, 1]) ** 2
        if d > best:
            far, best = i, d
    ex, ey = points[far, 0] - points[first, 0], points[far, 1] - points[first, 1]
    left, right, most, least = first, first, 0.0, 0.0
    for i in range(n):
        side = ex * (points[i, 1] - points[first, 1]) - ey * (points[i, 0] - points[first, 0])
        if side > most:
            left, most = i, side
        if side < least:
            right, least = i, side
    used = 0
    for c in range(4):
        pick = first if c == 0 else (far if c == 1 else (left if c == 2 else right))
        seen = False
        for d in range(used):
            seen |= picks[d] == pick
        if not seen:
            picks[used] = pick
            used += 1
    return used


@kernel
def ground_rest(rows, start, end, bodies, supported_next, params) -> None:
    """Resting ground contact, after the solve, of the bodies of rows start:end (from
    :func:`ground_contacts`, a row a body): a body touching the plane (a corner within
    the sag of one step of gravity, or a hair of its size) is flagged in
    supported_next (B,); if slow it loses momenta at params.rest_damping (1/s); with
    three or more corners touching, none sunk deeper, speed and rim speed below
    params.sleep_speed and its centre of mass over their convex hull, it is clamped to
    rest and sleeps until something wakes it.
    """
    dt, up_axis = params.dt, params.up_axis
    e1 = (up_axis + 1) % 3
    e2 = (up_axis + 2) % 3
    sleep_speed = params.sleep_speed
    body_lin, body_ang, body_asleep = bodies.lin, bodies.ang, bodies.asleep
    px = np.empty(4)
    py = np.empty(4)
    for r in range(start, end):
        b = rows.body[r, 1]
        touch_tol = 1e-4 * max(1.0, bodies.radius[b]) + 9.81 * dt * dt
        touching = np.int64(0)  # not a literal 0: the callee would compile twice
        sunk = False  # deeper than touching: the position pass has yet to lift it
        for i in range(rows.used[r]):
            if rows.corner_gap[r, i] <= touch_tol:
                px[touching] = rows.corners[r, i, e1]
                py[touching] = rows.corners[r, i, e2]
                touching += 1
            sunk |= rows.corner_gap[r, i] < -touch_tol
        m = bodies.mass[b]
        omega = angular_velocity(bodies.rot[b], bodies.inv_inertia[b], body_ang[b])
        speed = math.sqrt(body_lin[b, 0] ** 2 + body_lin[b, 1] ** 2 + body_lin[b, 2] ** 2) / m
        spin = math.sqrt(omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2) * bodies.radius[b]
        if touching > 0:
            supported_next[b] = True
        if touching == 0 or speed > 4.0 * sleep_speed or spin > 4.0 * sleep_speed:
            continue
        decay = math.exp(-params.rest_damping * dt)
        for a in range(3):
            body_lin[b, a] *= decay
            body_ang[b, a] *= decay
        if touching >= 3 and speed < sleep_speed and spin < sleep_speed and not sunk:
            tol = 1e-9 * max(1.0, bodies.radius[b])
            if _hull_contains(px, py, touching, bodies.pos[b, e1], bodies.pos[b, e2], tol):
                for a in range(3):
                    body_lin[b, a] = 0.0
                    body_ang[b, a] = 0.0
                body_asleep[b] = True


def ground_rows(model, state, settings, dt: float, ground: float, start: int) -> int:
    """Gather the ground's contact rows after row ``start`` of the contact memory (made if
    need be), growing it if they do not fit; returns the row after the last and counts
    them in the run's counters. ground: the plane's height along the model's up axis, m.
    """
    offsets, members = boundary_of(model, state)
    _fit_points(state, offsets)
    memory = state.contacts.memory
    if memory is None:
        memory = new_memory(state, voxel_size(model.voxels.contact_radius), np.zeros((0, 3)),
                            np.zeros(0))
    params = _params(model, settings, dt, ground)
    end = ground_contacts(model.voxels, offsets, members, state.bodies, state.contacts, params,
                          memory, start)
    if end > len(memory.rows.key):
        memory = grow_rows(state, end, start)
        ground_contacts(model.voxels, offsets, members, state.bodies, state.contacts, params,
                        memory, start)
    state.counters.ground_contacts += int(memory.rows.used[start:end].sum())
    return end


def _fit_points(state, offsets: np.ndarray) -> None:
    """Grow the ground's corner scratch (contacts.points) to hold the corners of the
    largest body that can move (a founded one is never scanned: a million-voxel founded
    block would hold 11 MB of it for nothing)."""
    bodies, n = state.bodies, len(offsets) - 1  # the bodies the boundary lists
    movable = bodies.live[:n] & ~bodies.fixed[:n] & ~bodies.dust[:n]
    need = 8 * int(np.diff(offsets)[movable].max(initial=0)) + 8
    if need > len(state.contacts.points):
        state.contacts = state.contacts._replace(points=np.zeros((need, 3)))


def settle_on_ground(model, state, settings, dt: float, start: int, end: int) -> None:
    """:func:`ground_rest` for the ground's rows start:end, after the solve."""
    ground_rest(state.contacts.memory.rows, start, end, state.bodies,
                state.contacts.supported_next, _params(model, settings, dt, 0.0))


def _params(model, settings, dt: float, ground: float) -> GroundParams:
    s = settings
    return GroundParams(dt, ground, model.up_axis, s.friction, s.rest_damping, s.sleep_speed)


def ground_phase(model, state, settings, dt: float, ground: float) -> None:
    """Phase: ground-plane contacts of every moving body (see the module docstring).

    Reads the bodies' poses and the boundary; writes momenta, poses (where bodies
    sank into the plane), asleep and contacts.supported_next; counts contact points
    in the run's counters. ground: the plane's height along the model's up axis, m.
    With fragment collisions on, :func:`~blastvox.simulate.contact.fragments.collide_phase`
    has solved the ground with them and this does nothing.
    """
    if settings.collisions:
        return
    end = ground_rows(model, state, settings, dt, ground, 0)
    memory = state.contacts.memory
    solve_contacts(state.bodies, memory, end, solver_params(memory, settings, dt, model.up),
                   state.loads)
    settle_on_ground(model, state, settings, dt, 0, end)
