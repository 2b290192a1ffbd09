"""Fragment collisions (Martins 2001 §5.1), solved with the ground's contacts.

Broad phase: bounding spheres of bodies, then a spatial hash of the boundary
voxels of bodies whose spheres overlap (:func:`static_hash` keeps resting
bodies' voxels). Narrow phase: each voxel is a box
(:func:`~blastvox.simulate.model.voxel_boxes`), and two boxes of different bodies
that touch, or may touch within the step (speculative contacts), make one contact
row: the separating axis of least
penetration over the six face normals picks a reference face, the facing face
of the other box is clipped to it (as Bullet's and ODE's box-box tests do),
and the clipped points make a patch: a point at its centre, the separation of
its closest point, and its half extents. The normal impulse at the centre,
with moments about the two tangents bounded by the normal impulse times the
patch's half extents, is exactly what forces at the patch corners can do, so a
box rests on a face, tips over an edge and rolls on a corner. The rows, and
the ground's (:mod:`blastvox.simulate.contact.ground`), are solved together by
:func:`~blastvox.simulate.contact.solver.solve_contacts`: sequential impulses, warm
started, restitution the smaller of the two voxels', Coulomb friction,
penetration removed by moving bodies. Impacts weaken voxels; a voxel whose
strength runs out turns to dust.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from blastvox.jit import helper, kernel, parallel_kernel
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.contact.balance import balance
from blastvox.simulate.contact.boxes import box_contact
from blastvox.simulate.contact.broadphase import candidates
from blastvox.simulate.contact.ground import (
    SLOP,
    ground_rows,
    grow_rows,
    new_memory,
    rest_speed,
    settle_on_ground,
    solver_params,
)
from blastvox.simulate.contact.pairs import (
    rest_grid,
    static_hash,
)
from blastvox.simulate.contact.solver import solve_contacts
from blastvox.simulate.integrate import angular_velocity
from blastvox.simulate.limits import voxel_size
from blastvox.simulate.state import Contacts


class CollideParams(NamedTuple):
    """dt: step, s; wake_speed: m/s of approach that wakes a sleeping body (the sleep
    speed); rest_speed: m/s below which a contact is resting, not an impact;
    weakening: fraction of an impact's pressure taken off a voxel's yield; cell: hash
    cell, m (twice the largest box half diagonal, plus reach); reach: m, the most a
    contact looks ahead (half the largest voxel); slop: m, the solver's
    (:func:`~blastvox.simulate.contact.ground.solver_params`)."""

    dt: float
    wake_speed: float
    rest_speed: float
    weakening: float
    cell: float
    reach: float
    slop: float


def collide_bodies(geometry, voxels, bodies, params, boundary, static, rest, memory) -> int:
    """Contact rows (memory.rows, from row 0) of voxel boxes of different bodies, once each.

    boundary: (offsets, members) each body's boundary voxels; params:
    :class:`CollideParams`; static: :func:`static_hash`; rest: :func:`rest_grid`.
    The boundary voxels of moving bodies that may touch something
    (:func:`~blastvox.simulate.contact.pairs.near_voxels`) go into a spatial hash
    each step; voxels of bodies at rest (fixed or asleep) come from ``static``,
    so a big standing structure costs nothing per step. Pairs whose bounding
    spheres (memory.radius) may touch within the step are the candidates
    (:func:`~blastvox.simulate.contact.broadphase.candidates`, in hash order, on every
    core: the same for any thread count); their box tests
    (:func:`~blastvox.simulate.contact.boxes.box_contact`) run on every core
    (:func:`_box_tests`), and the contacts become rows in the candidates' order
    (:func:`_emit_rows`), so the rows are the same for any thread count. Returns the
    number of rows; rows past the capacity are counted, not written (grow and call
    again). When they fit, the sleeping
    bodies they strike wake (:func:`_wake_struck`).
    """
    pairs, centres, ahead = candidates(geometry, voxels, bodies, params, boundary, static,
                                       rest, memory)
    patches = np.empty((len(ahead), 32))
    hit = np.zeros(len(ahead), dtype=bool)
    if len(ahead):
        _box_tests(bodies.rot, memory.half, pairs, centres, ahead, patches, hit)
    return _emit_rows(geometry, bodies, params, memory, pairs, patches, hit)


#: Candidates per task of :func:`_box_tests`' parallel loop (each test is its own: any
#: split gives the same bytes).
BOX_CHUNK = 64


@parallel_kernel
def _box_tests(rot, half, pairs, centres, ahead, patches, hit) -> None:
    """The box test (:func:`~blastvox.simulate.contact.boxes.box_contact`) of every
    candidate (:func:`~blastvox.simulate.contact.broadphase.candidates`), each on its
    own: hit (C,) whether it touches, patches (C, 32) its patch."""
    n_chunks = (len(ahead) + BOX_CHUNK - 1) // BOX_CHUNK
    for chunk in nb.prange(n_chunks):  # scratch once a chunk: allocations serialize threads
        work = (np.empty((3, 3)), np.empty((3, 8, 3)), np.empty(32))
        pair = np.empty(8, dtype=np.int64)  # bodies and voxels, then the manifold's picks
        for c in range(chunk * BOX_CHUNK, min((chunk + 1) * BOX_CHUNK, len(ahead))):
            for k in range(4):
                pair[k] = pairs[c, k]
            hit[c] = box_contact(rot, half, pair, centres[c], ahead[c], work)
            if hit[c]:
                for k in range(32):
                    patches[c, k] = work[2][k]


@kernel
def _emit_rows(geometry, bodies, params, memory, pairs, patches, hit) -> int:
    """The candidates that touch as rows of memory.rows, in their order (see
    :func:`collide_bodies`); returns how many."""
    found = 0
    for c in range(len(hit)):
        if hit[c]:
            _emit(found, pairs[c, 1], pairs[c, 3], pairs[c, 0], pairs[c, 2], patches[c],
                  geometry.restitution, memory.rows)
            found += 1
    if found <= memory.rows.key.shape[0]:
        _wake_struck(memory.rows, found, bodies, params)
    return found


@helper
def _emit(r, vi, vj, bi, bj, patch, restitution, rows) -> None:
    """Write the contact that :func:`~blastvox.simulate.contact.boxes.box_contact` left in
    patch as row r of rows (unless r is past the capacity): bodies bi, bj, voxels vi, vj,
    the smaller restitution."""
    if r >= rows.key.shape[0]:
        return
    flip = 1.0 if patch[15] > 0.0 else -1.0  # the normal from a to b
    for a in range(3):
        rows.point[r, a] = patch[a]
        rows.frame[r, 0, a] = flip * patch[3 + a]
        rows.frame[r, 1, a] = patch[6 + a]
        rows.frame[r, 2, a] = patch[9 + a]
        for i in range(4):
            rows.corners[r, i, a] = patch[16 + 3 * i + a]
    for i in range(4):
        rows.corner_gap[r, i] = patch[28 + i]
    rows.gap[r], rows.arm[r], rows.used[r] = patch[12], patch[13], int(patch[14])
    rows.body[r, 0], rows.body[r, 1] = bi, bj
    rows.voxel[r, 0], rows.voxel[r, 1] = vi, vj
    rows.key[r] = min(vi, vj) * restitution.shape[0] + max(vi, vj)
    rows.restitution[r] = min(restitution[vi], restitution[vj])


@helper
def _wake_struck(rows, count, bodies, params) -> None:
    """Wake the sleeping bodies that the first ``count`` rows strike: approach faster
    than params.rest_speed (m/s), closing the gap (but params.slop) within the step,
    as the solver's bounces (:func:`~blastvox.simulate.contact.solver.solve_contacts`). A gentle
    touch does
    not wake (debris creeping at about the sleep speed woke its resting neighbours every
    step, and they fell asleep again the next, for ever); an asleep body is immovable."""
    for r in range(count):
        a, b = rows.body[r, 0], rows.body[r, 1]
        if not (bodies.asleep[a] or bodies.asleep[b]):
            continue
        vn = 0.0
        for side in range(2):
            o = a if side == 0 else b
            w = angular_velocity(bodies.rot[o], bodies.inv_inertia[o], bodies.ang[o])
            rx = rows.point[r, 0] - bodies.pos[o, 0]
            ry = rows.point[r, 1] - bodies.pos[o, 1]
            rz = rows.point[r, 2] - bodies.pos[o, 2]
            m = bodies.mass[o]
            u = (rows.frame[r, 0, 0] * (bodies.lin[o, 0] / m + w[1] * rz - w[2] * ry)
                 + rows.frame[r, 0, 1] * (bodies.lin[o, 1] / m + w[2] * rx - w[0] * rz)
                 + rows.frame[r, 0, 2] * (bodies.lin[o, 2] / m + w[0] * ry - w[1] * rx))
            vn += u if side == 1 else -u
        if -vn > params.rest_speed and vn * params.dt < params.slop - rows.gap[r]:
            bodies.asleep[a] = False
            bodies.asleep[b] = False


#: Voxels closer than this fraction of the smaller one's edge at a step's start touch:
#: a contact between them pushes and never strikes (the solver's slop; a lattice's
#: shared face is at 0, a gap closing within a step is far wider).
TOUCHING = 1e-3


@helper
def _edge(half, va, vb) -> float:
    """The smaller edge (m) of voxels va's and vb's contact boxes (half (N, 3) m)."""
    return 2.0 * min(half[va, 0], half[va, 1], half[va, 2], half[vb, 0], half[vb, 1],
                     half[vb, 2])


@helper
def _touching_gap(half, va, vb) -> float:
    """Gap (m) below which voxels va and vb touch (:data:`TOUCHING`)."""
    return TOUCHING * _edge(half, va, vb)


@kernel
def resting_flags(rows, count, rest_speed, resting) -> None:
    """Flag in ``resting`` (B,) both bodies of every solved fragment contact (the first
    ``count`` rows) that pushed and approached slower than ``rest_speed`` (m/s): they
    rest on each other (for :func:`damp_resting`)."""
    for r in range(count):
        if rows.impulse[r] > 0.0 and -rows.approach[r] < rest_speed:
            resting[rows.body[r, 0]] = True
            resting[rows.body[r, 1]] = True


@kernel
def contact_strikes(rows, count, density, voxels, marks, hits, weakening, half,
                    crush) -> int:
    """What the step's solved fragment contacts (the first ``count`` rows) struck: one
    that pushed, approached and whose voxels were apart
    at the step's start (by more than :data:`TOUCHING` x the smaller voxel's edge;
    half (N, 3) m: the voxels' contact box half extents) weakens both voxels by
    ``weakening`` x the impact pressure rho v_n^2 / 2 (Pa; rho the voxel's density in
    kg/m^3, v_n the approach speed): a stone voxel shrugs off 5 m/s (33 kPa) and turns
    to dust at 20 m/s (520 kPa, above its yield). Voxels touching already push: a
    wall's layers, freed by the wave and pressed together by it, do not strike each
    other (their approach, the wave's push over one step, p dt / (rho L), is dt's, not
    an impact's). A voxel whose yield the pressure exceeds, and its ``crush`` (N,) Pa
    (a voxel that is the material's rubble already is pulverized only by a crushing
    impact, whatever the blast left of its yield), is marked in marks.destroyed (its
    body in marks.dirty). hits (H, 4) receives the points and approach speeds (m/s,
    for dust). Returns how many rows struck. rows:
    :class:`~blastvox.simulate.contact.ground.ContactRows`; density (N,): voxels' kg/m^3."""
    voxel_density, voxel_yield, voxel_alive = density, voxels.yield_pa, voxels.alive
    resolved = 0
    for r in range(count):
        vn = rows.approach[r]
        if rows.impulse[r] <= 0.0 or vn >= 0.0:
            continue
        if rows.gap[r] <= _touching_gap(half, rows.voxel[r, 0], rows.voxel[r, 1]):
            continue
        for side in range(2):
            v = rows.voxel[r, side]
            pressure = 0.5 * voxel_density[v] * vn * vn
            if pressure > voxel_yield[v] and pressure > crush[v]:
                voxel_alive[v] = False
                marks.destroyed[v] = True
                marks.dirty[rows.body[r, side]] = True
            else:
                voxel_yield[v] = max(0.0, voxel_yield[v] - weakening * pressure)
        if resolved < hits.shape[0]:
            for a in range(3):
                hits[resolved, a] = rows.point[r, a]
            hits[resolved, 3] = -vn
        resolved += 1
    return resolved


#: How far (a fraction of the smaller voxel's edge) a piece may pass into the loaded
#: member it broke off before their contact holds again: if the member has not let go
#: by then, it stands and stops the piece. A founded brick wall's debris at dt 1/10,000 s
#: (the wave frees it over about 1.5 ms) is within 3 % of dt 1/4000 s's at 0.005, and a
#: standing wall's pressed pieces pass under 1 % of a voxel into it.
MEMBER_DEPTH = 0.005


@kernel
def mute_member_rows(rows, count, bodies, voxels, loads, since, holds, half, depth) -> None:
    """While a wave passes, a piece that broke off in it does not collide with a fixed
    body that the wave is loading (one whose voxels hold its impulse, rows of
    loads.held_p N s): they are parts of one member, which the wave moves together though
    its foundation still holds the rest (a wall bends out before its supports give
    way, and the part still held leaves with the impulse it took when its links
    fail: :func:`~blastvox.simulate.kernels.release_held`). Their rows get no corners
    (rows.used = 0: no normal impulse, so no friction) until the piece is ``depth``
    of the smaller voxel's edge into the member. Two pieces that both broke off in the
    current waves touch without friction (rows.grip = 0): the wave gave the parts of
    one member different speeds and spins, and their friction locked a wall's pieces
    against those caught at a house's corners. Against an immovable body, a
    wall's first pieces to break free, pressed by the wave against the part still
    founded, gave their momentum to the ground, more the finer the step (a founded
    brick wall's debris: 9,030 N s at dt 1/240 s, 2,388 at 1/10,000). Once the waves
    have passed, contacts hold again and the soft push-out separates what overlaps.
    since: the step the current waves began loading; holds (B,) bool: work."""
    body, held_p = voxels.body, loads.held_p
    holds[:] = False
    for s in range(loads.held_count[0]):
        if held_p[s, 0] != 0.0 or held_p[s, 1] != 0.0 or held_p[s, 2] != 0.0:
            holds[body[loads.held_voxel[s]]] = True
    for r in range(count):
        a, b = rows.body[r, 0], rows.body[r, 1]
        if a < 0 or b < 0:
            continue
        if bodies.fixed[a] == bodies.fixed[b]:
            if not bodies.fixed[a] and bodies.born[a] >= since and bodies.born[b] >= since:
                rows.grip[r] = 0.0
            continue
        fixed, free = (a, b) if bodies.fixed[a] else (b, a)
        if holds[fixed] and bodies.born[free] >= since and \
                rows.gap[r] > -depth * _edge(half, rows.voxel[r, 0], rows.voxel[r, 1]):
            rows.used[r] = 0


@kernel
def damp_resting(resting, body_mass, body_inv_inertia, body_rot, body_lin, body_ang,
                 body_radius, n_bodies, decay, limit) -> None:
    """Resting-contact damping between fragments (as the ground's, Martins 2001 §5.2).

    Bodies flagged in ``resting`` (B,) (a gentle contact this step) that move
    slower than ``limit`` (m/s, centre speed and rim speed) lose the fraction
    1 - ``decay`` of their momenta; the flags are cleared. Only ever removes
    energy, and lets piles settle and sleep instead of jittering. Called every
    step with contacts: it takes the arrays it reads (see :func:`body_rotations`).
    """
    for b in range(n_bodies):
        if not resting[b]:
            continue
        resting[b] = False
        speed = math.sqrt(body_lin[b, 0] ** 2 + body_lin[b, 1] ** 2 + body_lin[b, 2] ** 2) \
            / body_mass[b]
        wx, wy, wz = angular_velocity(body_rot[b], body_inv_inertia[b], body_ang[b])
        spin = math.sqrt(wx * wx + wy * wy + wz * wz) * body_radius[b]
        if speed > limit or spin > limit:
            continue
        for a in range(3):
            body_lin[b, a] *= decay
            body_ang[b, a] *= decay


def begin_contacts(state) -> None:
    """Per-step contact bookkeeping: no voxel destroyed or body dirty yet, and last
    step's support flags become this step's, the next ones starting empty."""
    state.marks.destroyed[:] = False
    state.marks.dirty[:state.n_bodies] = False
    c = state.contacts  # swap the two flag arrays (the constructor: _replace is ~10x slower)
    state.contacts = Contacts(c.resting, c.supported_next, c.supported, c.hits, c.points,
                              c.vertex_stamp, c.memory)
    c.supported[:] = False


def collide_phase(model, state, settings, dt: float) -> None:
    """Phase: contacts between fragments and, with a ground, with the ground, solved
    together at velocity level; then resting-contact damping.

    Reads the bodies' poses and momenta and the boundary; writes momenta, poses
    (where bodies interpenetrate), asleep, the contact flags (after
    :func:`begin_contacts`, once a step) and memory. What the contacts struck is
    :func:`strike_phase`'s, after the step's last solve. ``settings``: the run's
    SimSettings. The ground phase then has nothing left to do
    (:func:`~blastvox.simulate.contact.ground.ground_phase`).
    """
    s = settings
    boundary = boundary_of(model, state)
    memory = state.contacts.memory
    if memory is None:
        v = model.voxels
        memory = new_memory(state, voxel_size(v.contact_radius), v.box_half, v.box_radius)
    reach = model.max_contact_radius  # half the largest voxel: the motion limit
    params = CollideParams(dt=dt, wake_speed=s.sleep_speed,
                           rest_speed=rest_speed(s, dt),
                           weakening=s.weakening,
                           cell=2.0 * float(memory.radius.max(initial=0.0)) + reach,
                           reach=reach, slop=SLOP * memory.size)
    static, rest = _static(model, state, params.cell), _rest_grid(model, state, params.cell)
    count = collide_bodies(model.voxels, state.voxels, state.bodies, params, boundary, static,
                           rest, memory)
    if count > len(memory.rows.key):
        memory = grow_rows(state, count, 0)
        collide_bodies(model.voxels, state.voxels, state.bodies, params, boundary, static, rest,
                       memory)
    ground = model.ground_height if s.ground else None
    end = count if ground is None else ground_rows(model, state, s, dt, ground, count)
    memory = state.contacts.memory
    if state.holding:  # a wave is passing: a member's parts move together
        mute_member_rows(memory.rows, count, state.bodies, state.voxels, state.loads,
                         state.hold_since, _holds(state), memory.half, MEMBER_DEPTH)
    solve_contacts(state.bodies, memory, end, solver_params(memory, s, dt, model.up),
                   state.loads)
    memory.rows.grip[:count] = 1.0
    state.caches.fragment_rows = (int(count), int(end))
    c = state.contacts
    resting_flags(memory.rows, count, params.rest_speed, c.resting)
    if ground is not None:
        settle_on_ground(model, state, s, dt, count, end)
    b = state.bodies
    balanced = state.caches.balanced
    if balanced is None or len(balanced) != len(b.mass):
        balanced = state.caches.balanced = np.zeros(len(b.mass), dtype=bool)
    balance(memory.rows, end, b, model.up_axis, balanced)
    c.resting[:state.n_bodies] &= balanced[:state.n_bodies]  # wedged or leaning: not resting
    # without gravity nothing rests on anything: no pile to settle, momentum is conserved
    decay = math.exp(-s.rest_damping * dt) if s.gravity > 0.0 else 1.0
    damp_resting(state.contacts.resting, b.mass, b.inv_inertia, b.rot, b.lin, b.ang, b.radius,
                 state.n_bodies, decay, 4.0 * s.sleep_speed)


def strike_phase(model, state, settings) -> int:
    """Phase: what the step's fragment contacts, as finally solved (the last
    :func:`collide_phase`'s rows), struck (:func:`contact_strikes`): voxels weakened or
    marked destroyed (the caller splits), contacts.hits and counters.collisions. Run
    once a step, after the last solve: a solve that is taken back and done again
    (:func:`blastvox.simulate.engine._collide`'s punch rounds) strikes nothing.
    Returns how many of the strikes are in contacts.hits (for dust)."""
    memory = state.contacts.memory
    count = state.caches.fragment_rows[0]
    if memory is None or count == 0:
        return 0
    c = state.contacts
    resolved = contact_strikes(memory.rows, count, model.voxels.density, state.voxels,
                               state.marks, c.hits, settings.weakening, memory.half,
                               model.strength.shatter_pa)
    state.counters.collisions += int(resolved)
    return min(int(resolved), len(c.hits))


def _holds(state) -> np.ndarray:
    """Work array (B,) of :func:`mute_member_rows`, kept in state.caches."""
    caches = state.caches
    if caches.holds is None:
        caches.holds = np.zeros(len(state.bodies.mass), dtype=bool)
    return caches.holds


def _rest_grid(model, state, cell: float) -> tuple:
    """Boundary voxels by body and rest cell, rebuilt when the boundary changes."""
    caches = state.caches
    if caches.rest_version != caches.version:
        caches.rest = rest_grid(model.voxels.centroid, state.voxels.body, caches.boundary[1],
                                cell)
        caches.rest_version = caches.version
    return caches.rest


def _static(model, state, cell: float) -> tuple:
    """The hash of resting bodies' voxels, rebuilt when what rests changes."""
    b, n, caches = state.bodies, state.n_bodies, state.caches
    resting = b.live[:n] & ~b.dust[:n] & (b.fixed[:n] | b.asleep[:n])
    key = (caches.version, resting.tobytes())
    if caches.static_key != key:
        offsets, members = caches.boundary
        caches.static = static_hash(model.voxels, offsets, members, state.bodies, cell)
        caches.static_key = key
    return caches.static
