"""``simulate(model, settings) -> SimCache``: the fixed-step loop over typed state.

A run is an immutable :class:`~blastvox.simulate.model.SimModel`, a mutable
:class:`~blastvox.simulate.state.State`, and :func:`step`, a short sequence of
public phases, each in its own module with a docstring saying what it reads
and writes:

1. blast front: each charge's shock-front radius at the step's start and end
   (:mod:`~blastvox.simulate.wave`), and which bodies it can reach;
2. fracture: links, voxels and foundations the fronts crossed
   (:func:`~blastvox.simulate.fracture.fracture_phase`), ignition
   (:func:`~blastvox.simulate.fire.ignite_phase`);
3. split: bodies that lost links or voxels are searched again and split
   (:func:`~blastvox.simulate.topology.split_phase`);
4. fire: burning and spreading (:func:`~blastvox.simulate.fire.burn_phase`);
   load paths: founded bodies that changed are solved under gravity and their
   overloaded links break (:func:`~blastvox.simulate.stress.stress_phase`);
5. forces: the exact blast impulse of the step on exposed faces
   (:func:`~blastvox.simulate.forces.blast_phase`);
6. integrate velocities: blast impulse, gravity, drag;
7. collide: fragments (:func:`~blastvox.simulate.contact.fragments.collide_phase`), then the
   ground (:func:`~blastvox.simulate.contact.ground.ground_phase`), at velocity level; chunks
   of founded bodies the contacts pushed out (:func:`~blastvox.simulate.contact.loads.punch_phase`),
   and the contacts solved again with them free;
   impact fracture of the bodies the contacts stopped hard
   (:func:`~blastvox.simulate.impact.impact_phase`); sleeping;
8. integrate positions and orientations;
9. record: at every frame boundary, live body transforms and damage
   (:class:`~blastvox.simulate.recorder.Recorder`); particle cues
   (:class:`~blastvox.simulate.effects.Effects`) along the way.

Every kernel runs serially in a fixed order, so results are bit-identical for
any NUMBA_NUM_THREADS.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from blastvox import __version__
from blastvox.cache import SimCache
from blastvox.geometry import exact
from blastvox.model import VoxelModel
from blastvox.particles import particle_meta
from blastvox.simulate import cues
from blastvox.simulate.bodies import aggregate, inverse_inertia
from blastvox.simulate.clearing import reset_clearing
from blastvox.simulate.confinement import Rooms, find_rooms, gas_phase
from blastvox.simulate.contact.fragments import begin_contacts, collide_phase, strike_phase
from blastvox.simulate.contact.ground import ground_phase, rest_speed
from blastvox.simulate.contact.loads import Punch, punch_phase
from blastvox.simulate.contact.warmstart import lighten_carried, mass_kept
from blastvox.simulate.effects import Effects
from blastvox.simulate.fire import Fire, burn_phase, ignite_phase
from blastvox.simulate.forces import blast_phase
from blastvox.simulate.fracture import fracture_phase
from blastvox.simulate.impact import impact_phase
from blastvox.simulate.integrate import integrate_positions, integrate_velocities
from blastvox.simulate.kernels import (
    any_moving,
    bodies_in_shell,
    body_radii,
    body_rotations,
    link_alive_counts,
    link_masks,
    settle,
    wake_on_impulse,
)
from blastvox.simulate.leakage import LeakyRooms, find_leaky_rooms, leak_phase
from blastvox.simulate.ledger import Ledger
from blastvox.simulate.limits import LimitMonitor
from blastvox.simulate.model import SimModel, build_model, crush_pressures
from blastvox.simulate.recorder import Recorder
from blastvox.simulate.settings import (
    SimSettings,
    check_record_memory,
    check_run_memory,
    check_settings,
    gravity_vector,
)
from blastvox.simulate.shielding import corner_boxes, inside_solid, refresh_occupancy
from blastvox.simulate.state import (
    SPARE_BODIES,
    Contacts,
    Front,
    Links,
    Marks,
    Scratch,
    State,
    Voxels,
    empty_bodies,
    held_loads,
    padded,
)
from blastvox.simulate.stress import Stress, invalidate, stress_phase
from blastvox.simulate.stress import start as start_stress
from blastvox.simulate.support import support_phase
from blastvox.simulate.topology import split_phase
from blastvox.simulate.warmup import compile_ahead
from blastvox.simulate.wave import Charges, build_charges


class Progress:
    """Progress sink: ``update(sim_time_s, steps_done, total_steps)``, a no-op here,
    and ``note(line)``, a one-line status (first-run compilation) passed to
    ``notes`` if given."""

    def __init__(self, notes: Callable[[str], None] | None = None) -> None:
        self._notes = notes

    def update(self, sim_time: float, done: int, total: int) -> None: ...

    def note(self, line: str) -> None:
        if self._notes is not None:
            self._notes(line)


def initial_state(model: VoxelModel, sm: SimModel, ground: bool = True) -> State:
    """One body per object of the model, at rest in its rest pose. Without a ground
    nothing is founded."""
    a = model.arrays
    n, n_links = sm.n_voxels, sm.n_links
    objects = a["voxel_object"].astype(np.int64)
    n_objects = int(objects.max()) + 1 if n else 0
    capacity = n_objects + min(SPARE_BODIES, 2 * n + 2)  # grows as splits need
    foundation = a["voxel_foundation"].copy() if ground else np.zeros(n, dtype=bool)
    voxels = Voxels(
        body=objects, alive=np.ones(n, dtype=bool), link_mask=np.zeros(n, dtype=np.uint8),
        yield_pa=a["voxel_yield"].astype(np.float64), foundation=foundation,
        foundation_pa=a["voxel_foundation_yield"].astype(np.float64),
        # the model's own combustibility until a fire burns it (_start_fire copies it)
        damage=np.zeros(n), combust=np.asarray(a["voxel_combustibility"], dtype=np.float64),
        burning=np.zeros(n, dtype=bool))
    links = Links(alive=np.ones(n_links, dtype=bool),
                  yield_pa=a["link_yield"].astype(np.float64))
    bodies = empty_bodies(capacity)
    bodies.count[0] = n_objects
    order = np.argsort(objects, kind="stable").astype(np.int32)  # as split_bodies' members
    bounds = np.searchsorted(objects[order], np.arange(n_objects + 1))
    for b in range(n_objects):
        members = order[bounds[b]:bounds[b + 1]]
        mass, com, inertia = aggregate(members, sm.voxels.mass, sm.voxels.centroid,
                                       sm.voxels.inertia)
        bodies.mass[b], bodies.com[b], bodies.inertia[b] = mass, com, inertia
        bodies.inv_inertia[b] = inverse_inertia(inertia)
        bodies.pos[b] = com
        bodies.quat[b] = (1.0, 0.0, 0.0, 0.0)
        bodies.live[b] = True
        bodies.fixed[b] = bool(foundation[members].any())
    link_masks(sm.links, links, voxels)
    body_radii(sm.voxels, voxels, bodies)
    state = State(
        bodies=bodies, voxels=voxels, links=links,
        marks=Marks(broken=np.zeros(n_links, dtype=bool), destroyed=np.zeros(n, dtype=bool),
                    crossed=np.zeros(n, dtype=bool), dirty=np.zeros(capacity, dtype=bool),
                    active=np.zeros(capacity, dtype=bool)),
        loads=held_loads(n, capacity),
        contacts=Contacts(resting=np.zeros(capacity, dtype=bool),
                          supported=np.zeros(capacity, dtype=bool),
                          supported_next=np.zeros(capacity, dtype=bool),
                          hits=np.zeros((4096, 4)), points=np.zeros((64, 3)),
                          vertex_stamp=np.full(len(sm.voxels.contact_vertices), -1,
                                               dtype=np.int32)),
        scratch=Scratch.for_model(sm),
        shielding=sm.rest_grid._replace(count=sm.rest_grid.count.copy(),
                                        member=sm.rest_grid.member.copy()))
    return state


@dataclass
class Run:
    """One run: the model, its state, the charges and settings, and what records it.

    ground: the plane's height (m along up) or None without one; fire: fire's
    memory, or None when nothing in the scene can burn (or fire is off); rooms:
    the closed rooms of confined charges (:mod:`blastvox.simulate.confinement`)
    or None, and gas (C, 2) their charges' gas pressures and vent times."""

    model: SimModel
    state: State
    charges: Charges
    settings: SimSettings
    dt: float
    gravity: np.ndarray
    ground: float | None
    still_steps: int
    recorder: Recorder
    effects: Effects
    fire: Fire | None
    rooms: Rooms | None = None
    gas: np.ndarray | None = None
    leaky: LeakyRooms | None = None
    stress: Stress | None = None
    punch: Punch | None = None
    ledger: Ledger = field(default_factory=Ledger)

    @classmethod
    def start(cls, model: VoxelModel, settings: SimSettings) -> Run:
        sm = build_model(model)
        state = initial_state(model, sm, ground=settings.ground)
        if settings.fracture == "pressure-impulse":  # only a crushing pressure pulverizes
            np.maximum(state.voxels.yield_pa,
                       crush_pressures(sm.strength, "voxel_chunk" in model.arrays),
                       out=state.voxels.yield_pa)
        charges = build_charges(settings.charges, sm.up,
                                sm.ground_height if settings.ground else None)
        dt = settings.step_seconds()
        combustible = bool(np.isfinite(state.voxels.combust).any())
        if settings.ground and sm.ground_height is not None:  # the detours' solid below it
            state.caches.ground = (np.asarray(sm.up, dtype=np.float64), float(sm.ground_height))
        return cls(
            model=sm, state=state, charges=charges, settings=settings, dt=dt,
            gravity=gravity_vector(sm.up, settings.gravity),
            ground=sm.ground_height if settings.ground else None,
            still_steps=max(1, round(0.5 / dt)),  # half a second below sleep_speed
            recorder=Recorder(sm.n_voxels, sm.voxels.link_offsets,
                              state.voxels.yield_pa.copy()),
            effects=Effects(settings.budgets, settings.seed, len(charges.tnt_kg)),
            # model only what the scene needs: no combustible material, no fire
            fire=_start_fire(state) if settings.fire and combustible else None,
            # model only what the scene needs: no founded body, no load paths
            stress=(stress := start_stress(model.arrays, len(state.bodies.mass),
                                           settings.stress)),
            # founded bodies' contact loads need the links' strengths, and something to hit
            punch=(Punch.of(stress.chunk, sm.n_voxels)
                   if stress is not None and settings.collisions else None),
            **_rooms(sm, state, charges, sm.ground_height if settings.ground else None))

    def effects_on(self) -> dict[str, bool]:
        """Which effects this run models (stored in the SimCache meta)."""
        s = self.settings
        return {"collisions": s.collisions, "ground": self.ground is not None,
                "fire": self.fire is not None, "dust": s.dust, "fireball": s.fireball,
                "stress": self.stress is not None,
                "shock_sphere": s.shock_sphere,
                "camera_shake": s.camera_shake and s.camera is not None}


def _start_fire(state: State) -> Fire:
    """The run's fire; the voxels' combustibility, the model's array until now, becomes
    the run's own copy, which the fire burns away."""
    state.voxels = state.voxels._replace(combust=state.voxels.combust.copy())
    return Fire.start(state)


def _rooms(sm: SimModel, state: State, charges: Charges, ground: float | None) -> dict:
    """Run.start's rooms and gas: the closed rooms of confined charges, if any, and the
    rooms the waves enter through openings (:mod:`blastvox.simulate.leakage`)."""
    def half() -> np.ndarray:
        lo, hi = corner_boxes(sm.voxels.vertices, sm.voxels.corners)
        return 0.5 * (hi - lo)

    out: dict = {}
    leaky = find_leaky_rooms(state.shielding, charges, sm.voxels.centroid, half, sm.up,
                             ground)
    if leaky is not None:
        out["leaky"] = leaky
        state.caches.leaky = leaky.cells
    rooms = find_rooms(state.shielding, charges, sm.voxels.centroid, half)
    if rooms.any:
        out.update(rooms=rooms, gas=rooms.gas())
    return out


def step(run: Run, n: int, frame_next: int) -> None:
    """Advance ``run`` by step n (from (n - 1) dt to n dt); frame_next: the output frame
    this step leads to (for event records)."""
    model, state, s, charges, dt = run.model, run.state, run.settings, run.charges, run.dt
    t0, t1 = (n - 1) * dt, n * dt
    bodies, n_bodies = state.bodies, state.n_bodies
    body_rotations(bodies.quat, bodies.live, n_bodies, bodies.rot)
    front = _front(charges, t0, t1)
    was_holding = state.holding
    ledger = run.ledger
    ledger.book(state, "initial")  # what a caller set between steps
    if bodies_in_shell(bodies.pos, bodies.radius, bodies.live, n_bodies, front.position,
                       front.inner, front.outer, state.marks.active):
        if not state.holding:  # a wave arrives: it sees the structure as it stands
            refresh_occupancy(state.shielding, model.voxels, state.voxels, bodies)
            reset_clearing(state)
        fracture_phase(model, state, front, s, run.gas)
        if run.fire is not None:
            ignite_phase(model, state, run.fire, front, s, frame_next)
        split(run, n, t1, frame_next)
        if s.dust:
            run.effects.shock_dust(model, state, charges, t1)
    if run.fire is not None and run.fire.burning:
        burn_phase(model, state, run.fire, s, dt, frame_next)
        split(run, n, t1, frame_next)
        run.effects.flames(model, state, t1, dt)
    if s.fireball:
        run.effects.fireball(charges, t0, t1)
    if s.dust and run.ground is not None:
        run.effects.ground_ring(model, charges, run.ground, t1, front.outer, dt)
    if run.stress is not None and stress_phase(model, state, run.stress, run.gravity,
                                               None if run.punch is None
                                               else run.punch.sustained):
        split(run, n, t1, frame_next)
    ledger.book(state, "released")  # founded voxels' held impulses, to freed pieces
    held = ledger.founded_held(state) if state.holding else None
    blast_phase(model, state, charges, t0, t1, front.outer)
    bodies = state.bodies  # a split may have grown the body arrays
    if run.rooms is not None:
        gas_phase(model, state, run.rooms, t0, t1)
        wake_on_impulse(state.loads.impulse, state.loads.angular, bodies.asleep, n_bodies)
    if run.leaky is not None and leak_phase(model, state, run.leaky, charges, t0, t1):
        wake_on_impulse(state.loads.impulse, state.loads.angular, bodies.asleep, n_bodies)
    if state.holding:
        ledger.founded += ledger.founded_held(state) - (0.0 if held is None else held)
        if not was_holding:
            state.hold_since = n
    if not any_moving(bodies.live, bodies.fixed, bodies.dust, bodies.asleep, state.n_bodies):
        _still_step(run)
        return
    blast = ledger.blast_applied(state)
    integrate_velocities(dt, run.gravity, s.linear_drag, s.angular_drag, state.loads,
                         state.bodies)
    ledger.book(state, "gravity_drag", ("blast", blast))
    before = state.bodies.lin[:state.n_bodies].copy() if run.stress is not None else None
    if s.collisions:
        _collide(run, n, t1, frame_next)
        ground, founded = ledger.contacts(state, state.caches.fragment_rows[1])
        ledger.book(state, "damping", ("ground", ground), ("foundations", founded))
    if run.ground is not None:
        ground_phase(model, state, s, dt, run.ground)
        ledger.book(state, "ground")
    if before is not None and impact_phase(model, state, run.stress, before,
                                           _sustained_speed(run, dt)):
        split(run, n, t1, frame_next)
    if run.stress is not None and state.contacts.memory is not None and support_phase(
            model, state, run.stress, run.gravity, state.contacts.memory.rows,
            state.caches.fragment_rows[1], run.ground):
        split(run, n, t1, frame_next)
    if (s.collisions or run.ground is not None) and s.gravity > 0.0:
        settle(state.bodies, s.sleep_speed, run.still_steps, _balanced(run))  # without
        # gravity nothing rests
        ledger.book(state, "sleep")
    integrate_positions(dt, state.bodies)


def _balanced(run: Run) -> np.ndarray:
    """(B,) bool: the bodies that stood balanced on this step's contacts (the contact
    phase's, :func:`~blastvox.simulate.contact.balance.balance`); with collisions off,
    every body (the ground's own contact puts only balanced bodies to sleep)."""
    state = run.state
    if run.settings.collisions and state.caches.balanced is not None:
        return state.caches.balanced
    return np.ones(len(state.bodies.mass), dtype=bool)


#: Contact solves at most in a step whose contacts punch chunks out of founded bodies:
#: a chunk punched out of a wall's face is pressed into the layer behind it, which the
#: next solve may punch out in turn.
PUNCH_ROUNDS = 8


def _collide(run: Run, n: int, t1: float, frame_next: int) -> None:
    """Step n's fragment contacts (:func:`~blastvox.simulate.contact.fragments.collide_phase`),
    then what they struck (:func:`~blastvox.simulate.contact.fragments.strike_phase`),
    with its dust and splits. When the contacts pushed a chunk out of a founded body
    (:func:`~blastvox.simulate.contact.loads.punch_phase`), the step's contacts are
    solved again from the bodies as they were before them, with the chunk free: the
    pieces that struck it share their momentum with it as with any free body (an
    immovable wall stopped them dead). A solve taken back leaves nothing behind: no
    strike, dust or flag of it counts."""
    model, state, s = run.model, run.state, run.settings
    count = state.n_bodies
    begin_contacts(state)
    if run.punch is not None:  # what the contacts are solved again from
        b = state.bodies
        before = tuple(a[:count].copy() for a in (b.lin, b.ang, b.pos, b.quat, b.rot,
                                                  b.asleep))
    for attempt in range(PUNCH_ROUNDS):
        collide_phase(model, state, s, run.dt)
        if attempt == PUNCH_ROUNDS - 1 or run.punch is None or not punch_phase(
                model, state, run.stress, run.punch, state.contacts.memory.rows,
                *state.caches.fragment_rows, run.dt, rest_speed(s, run.dt), model.up):
            break
        _restore(state, count, before)
        split(run, n, t1, frame_next)
        state.marks.dirty[:] = False  # split: the punched bodies are apart
    resolved = strike_phase(model, state, s)
    if s.dust and resolved:
        run.effects.collision_dust(model, state.contacts.hits[:resolved], t1)
    if state.marks.destroyed.any():
        split(run, n, t1, frame_next)
    _sustain(run)


def _sustain(run: Run) -> None:
    """What the step's contacts (as finally solved) pushed into founded bodies, into
    their sustained loads (:class:`~blastvox.simulate.contact.loads.SustainedLoads`)."""
    punch = run.punch
    if punch is None:
        return
    if punch.last is not None:
        punch.sustained.add(*punch.last, float(exact.norm(run.gravity)) * run.dt)
        punch.last = None
    punch.sustained.close(run.state, run.stress, run.gravity, run.model.voxels.mass, run.dt)


def _restore(state, count: int, before: tuple) -> None:
    """The bodies as they were before a step's contacts (the solve moves bodies and puts
    them to sleep too): before, lin, ang, pos (count, 3), quat (count, 4), rot (count,
    3, 3) and asleep (count,) of the first ``count`` bodies; a body split off since
    starts from its parent's momenta (a fixed one's: none). The flags of support the
    solve set for the next step are cleared (the next solve sets them again)."""
    bodies = state.bodies
    live = bodies.live[:count]
    for now, then in zip((bodies.lin, bodies.ang, bodies.pos, bodies.quat, bodies.rot,
                          bodies.asleep), before, strict=True):
        now[:count][live] = then[live]
    for b in range(count, int(bodies.count[0])):
        parent = int(bodies.parent[b])
        while parent >= count:
            parent = int(bodies.parent[parent])
        if parent < 0 or bodies.fixed[parent]:
            bodies.lin[b] = 0.0
            bodies.ang[b] = 0.0
        # a piece of a free body keeps what the split gave it: its parent moved on
    state.contacts.supported_next[:] = False


def _sustained_speed(run: Run, dt: float) -> float:
    """Velocity change (m/s) below which contacts only held a body up: the step's
    gravity with its Coulomb friction, sqrt(1 + mu^2) |g| dt, plus the contacts' own
    line between resting and striking (sleep_speed + 2 |g| dt, the rest_speed of
    :mod:`blastvox.simulate.contact.fragments` and :mod:`blastvox.simulate.contact.ground`)."""
    g, s = float(exact.norm(run.gravity)), run.settings
    return g * dt * float(np.hypot(1.0, s.friction)) + rest_speed(s, dt)


def _front(charges: Charges, t0: float, t1: float) -> Front:
    """The fronts over [t0, t1] (see :class:`~blastvox.simulate.state.Front`)."""
    return Front(charges.position, charges.time, charges.scale, charges.table, charges.burst,
                 charges.front_radius(t0, before=-1.0), charges.front_radius(t1))


def split(run: Run, n: int, t1: float, frame_next: int) -> None:
    """Split bodies by what broke (:func:`~blastvox.simulate.topology.split_phase`), and
    record the breaks and the dusted voxels, which burst into dust particles."""
    state = run.state
    mass_before = state.bodies.mass[:state.n_bodies].copy()
    broken, destroyed = split_phase(run.model, state, n)
    if not broken.size and not destroyed.size:
        return
    if run.stress is not None:
        run.stress.solved = padded(run.stress.solved, len(state.bodies.mass), False)
        invalidate(run.stress, state.voxels.body, run.model.links.voxels, broken, destroyed)
    if state.contacts.memory is not None:  # what their contacts held, for what they weigh
        lighten_carried(state.contacts.memory, state.voxels.body,
                        mass_kept(mass_before, state.bodies))
    if run.rooms is not None:  # a room whose wall broke vents
        run.rooms.vent(np.concatenate([run.model.links.voxels[broken].ravel(), destroyed]), t1)
    run.recorder.link_breaks(broken, t1)
    run.recorder.voxels_destroyed(destroyed, t1, frame_next, state, run.model.voxels.mass)
    if run.settings.dust and destroyed.size:
        run.effects.voxel_dust(run.model, state, destroyed, t1)


def _still_step(run: Run) -> None:
    """The rest of a step in which no body can move: the velocity, contact and
    position kernels would only do their bookkeeping, done here (the results are
    byte-identical to running them; a settled shot's steps cost ~10x less)."""
    if run.settings.collisions:
        begin_contacts(run.state)
    if run.settings.collisions or run.ground is not None:
        run.state.bodies.still[:run.state.n_bodies] = 0  # settle() resets what cannot move


def simulate(model: VoxelModel, settings: SimSettings, progress: Progress | None = None,
             warn: Callable[[str], None] | None = None) -> SimCache:
    """Run the blast simulation of ``model`` with ``settings``.

    Settings outside their bounds or over their budget are refused before anything is
    built (:func:`~blastvox.simulate.settings.check_settings`), and so is a model whose
    run would need more memory than the budget
    (:func:`~blastvox.simulate.settings.check_run_memory`); the recorded frames'
    memory is checked at every frame as pieces appear. All raise a one-line
    :class:`~blastvox.errors.BlastvoxError` (a BudgetError for a budget).
    """
    check_settings(settings)
    run_bytes = check_run_memory(settings, model)
    _warn_if_host_dependent()
    progress = progress or Progress()
    warn = warn or (lambda message: None)
    cold = not _compiled_before()
    if cold:
        progress.note("first run of this blastvox source: compiling the simulator's kernels "
                      "into numba's cache (about a minute on 2 cores, once)")
    run = Run.start(model, settings)
    finish = compile_ahead(run) if cold else None  # the late phases, on another core
    if finish is None:
        return _simulate(run, model, settings, progress, warn, run_bytes)
    try:
        cache = _simulate(run, model, settings, progress, warn, run_bytes)
    except BaseException:
        finish(cancel=True)
        raise
    finish()
    return cache


def _warn_if_host_dependent() -> None:
    """A :class:`~blastvox.errors.HostDependenceWarning` when scipy's BLAS was loaded
    before blastvox could pin its kernels (``blastvox.SCIPY_BLAS_FIRST``)."""
    import warnings

    import blastvox
    from blastvox.errors import HostDependenceWarning

    if blastvox.SCIPY_BLAS_FIRST:
        warnings.warn(HostDependenceWarning(
            "scipy.linalg was imported before blastvox, so its BLAS kept the kernels this "
            "CPU picks: the stress solver may round differently from another CPU's and the "
            "shot differ from the CLI's there; import blastvox first, or set "
            "OPENBLAS_CORETYPE=Haswell before importing scipy"), stacklevel=3)


def _simulate(run: Run, model: VoxelModel, settings: SimSettings, progress: Progress,
              warn: Callable[[str], None], run_bytes: int = 0) -> SimCache:
    state, dt = run.state, run.dt
    if dt < settings.dt * (1 - 1e-12):
        warn(f"dt {settings.dt:g} s does not divide the frame interval 1/{settings.fps:g} s; "
             f"using {dt:g} s ({settings.steps_per_frame()} steps per frame)")
    per_frame = settings.steps_per_frame()
    frames = settings.frame_count()
    total_steps = (frames - 1) * per_frame
    for line in (*_duration_warnings(settings, total_steps), *_ground_warnings(run),
                 *_charge_warnings(run, total_steps * dt)):
        warn(line)
    limits = LimitMonitor(run.model, settings, dt)  # warns once per limit the run passes
    counts, counted = _alive_counts(run), state.counters.topology_version
    check_record_memory(settings, _live_count(state), frames, run_bytes)
    run.recorder.frame(0, state, counts, run.charges.front_radius(0.0))
    for n in range(1, total_steps + 1):
        step(run, n, -(-n // per_frame))
        if n % per_frame == 0:
            if state.counters.topology_version != counted:  # links only change in a split
                counts, counted = _alive_counts(run), state.counters.topology_version
                check_record_memory(settings, _live_count(state), frames,  # pieces appear
                                    run_bytes)
            run.recorder.frame(n, state, counts, run.charges.front_radius(n * dt))
            limits.check(state)
            progress.update(n * dt, n, total_steps)
    limits.finish()
    return _cache(run, model, frames, per_frame, total_steps)


def _duration_warnings(settings: SimSettings, total_steps: int) -> list[str]:
    """A line if the shot is shorter than one frame interval (1/fps s): frames run to the
    last one at or before the duration, so the cache holds frame 0 alone and no step
    runs (no charge goes off)."""
    if total_steps > 0:
        return []
    return [f"duration {settings.duration:g} s is shorter than one frame (1/{settings.fps:g} "
            f"s): the cache holds frame 0 only and nothing is simulated, no charge goes "
            f"off; lengthen the duration to at least {1.0 / settings.fps:.3g} s (or raise "
            f"--fps)"]


def _ground_warnings(run: Run) -> list[str]:
    """A line if voxels start more than half under the ground plane (their centre below
    it: a ground height typed above the model's base), deeper than the contacts' 0.5
    voxel limit on sinking: the ground's contacts throw them out of it."""
    if run.ground is None or run.model.n_voxels == 0:
        return []
    vox = run.model.voxels
    heights = exact.dot(vox.centroid, run.model.up)
    below = int(np.count_nonzero(heights < run.ground))
    if below == 0:
        return []
    lowest = float(exact.dot(vox.vertices, run.model.up).min())
    return [f"{below} of {run.model.n_voxels} voxels start below the ground at "
            f"{run.ground:g} m (the model's lowest point is at {lowest:g} m): the ground "
            "throws them out of it; lower the ground, or set ground = \"auto\""]


def _charge_warnings(run: Run, end: float) -> list[str]:
    """One line per charge the run cannot model as asked: buried in solid voxels or
    below the ground, a surface burst with no ground, or detonating after the shot's
    last step (``end``, s)."""
    lines, charges = [], run.charges
    up = run.model.up
    for c, position in enumerate(charges.position):
        where = f"charge {c} at ({position[0]:g}, {position[1]:g}, {position[2]:g}) m"
        if inside_solid(run.state.shielding, position):
            lines.append(f"{where} is inside solid voxels: a buried charge is not modelled "
                         "(no ground shock, no cavity gas); its air blast craters the voxels "
                         "around it from point-blank range, a rough guess; move it into the "
                         "air")
        depth = None if run.ground is None else run.ground - float(exact.dot(position, up))
        if depth is not None and depth > 0.0:
            lines.append(f"{where} is {depth:g} m below the ground: it bursts there as a "
                         "surface burst through the ground plane (a buried charge's ground "
                         "shock and crater are not modelled); put it on the ground")
        if run.ground is None and run.settings.charges[c].burst == "surface":
            lines.append(f"{where} is a surface burst, but the run has no ground: it loads "
                         "as a surface burst in open air (about 1.8 times an air burst of "
                         "its mass); give it burst = \"air\", or a ground")
        if charges.time[c] > end:
            lines.append(f"{where} detonates at {charges.time[c]:g} s, after the shot ends "
                         f"at {end:g} s: it does nothing; lengthen the duration")
    return lines


def _compiled_before() -> bool:
    """Does the kernel cache of this source tree (blastvox.jit.KERNEL_CACHE) hold the
    step's first kernel already?"""
    from blastvox.jit import KERNEL_CACHE

    return next(KERNEL_CACHE.rglob("kernels.body_rotations-*.nbi"), None) is not None


def _live_count(state: State) -> int:
    """Bodies alive now: the fewest pieces the run will record from here on."""
    return int(np.count_nonzero(state.bodies.live[:state.n_bodies]))


def _alive_counts(run: Run) -> np.ndarray:
    v = run.model.voxels
    return link_alive_counts(v.link_offsets, v.link_ids, run.state.links.alive)


def _cache(run: Run, model: VoxelModel, frames: int, per_frame: int,
           total_steps: int) -> SimCache:
    """Pack the run's records into a SimCache (see :mod:`blastvox.cache`)."""
    settings, charges, state, dt = run.settings, run.charges, run.state, run.dt
    frame_time = np.arange(frames) * (per_frame * dt)
    arrays = run.recorder.pack(state, run.model.voxels.mass, frame_time)
    ignite = run.fire.ignite_frame if run.fire is not None else np.full(
        run.model.n_voxels, -1, dtype=np.int32)
    arrays.update(charge_position=charges.position.copy(), charge_tnt_kg=charges.tnt_kg.copy(),
                  charge_time=charges.time.copy(), voxel_ignite_frame=ignite)
    arrays.update(run.effects.emitter.arrays())
    radius = arrays["shock_radius"]
    arrays["shock_opacity"] = (cues.shock_opacity(radius, charges.tnt_kg)
                               if settings.shock_sphere else np.zeros_like(radius))
    camera = settings.camera if settings.camera_shake else None
    arrays["camera_offset"] = (np.zeros((frames, 3)) if camera is None else cues.camera_shake(
        np.asarray(camera[0]), frame_time, charges.position, charges.tnt_kg, charges.time))
    counters = state.counters
    meta = {"tool_version": __version__, "fps": settings.fps, "dt": dt,
            "duration": settings.duration, "fracture": settings.fracture, "seed": settings.seed,
            "settings": settings.to_dict(), "up_axis": model.meta.get("up_axis"),
            "ground_height": run.ground,
            "steps": total_steps, "broken_links": counters.broken_links,
            "ground_contacts": counters.ground_contacts, "collisions": counters.collisions,
            "effects": run.effects_on(), "gravity_vector": run.gravity.tolist(),
            "particle_systems": particle_meta(),
            "camera": settings.to_dict()["camera"],
            "confinement": [] if run.rooms is None else run.rooms.meta(),
            "leaky_rooms": [] if run.leaky is None else run.leaky.meta(),
            "momentum": run.ledger.meta(),
            "stress": None if run.stress is None else {
                "solves": run.stress.solves, "links_broken": run.stress.broken}}
    # wall time is reported by the CLI, never stored: caches must be byte-identical
    return SimCache(arrays=arrays, model=model, meta=meta)
