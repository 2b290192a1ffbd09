"""``simulate(model, settings) -> SimCache``: the fixed-step loop.

A step is a sequence of kernels over flat arrays:

1. charges: each charge's shock-front radius at the step's start and end;
2. fracture: links, voxels and foundations the fronts crossed (yield or damage model);
3. topology: bodies that lost links or voxels are searched again and split;
4. blast: exact impulse of the step on exposed faces of free bodies;
5. velocities: blast impulse, gravity, drag;
6. collisions between fragments, then ground contact, at velocity level
   (impacts may dust voxels: topology again);
7. positions and orientations;
8. output: at every frame boundary, live body transforms and damage.

Every kernel runs serially in a fixed order, so results are bit-identical for
any NUMBA_NUM_THREADS.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from blastvox import __version__
from blastvox.cache import SimCache
from blastvox.model import VoxelModel
from blastvox.particles import particle_meta
from blastvox.simulate import contact, cues, fire, fracture, topology
from blastvox.simulate.bodies import aggregate, inverse_inertia
from blastvox.simulate.forces import blast_impulses
from blastvox.simulate.integrate import integrate_positions, integrate_velocities
from blastvox.simulate.kernels import (
    any_moving,
    bodies_in_shell,
    body_radii,
    body_rotations,
    damp_resting,
    link_alive_counts,
    link_masks,
    release_held,
    settle,
    wake_on_impulse,
)
from blastvox.simulate.limits import LimitMonitor
from blastvox.simulate.particles import Emitter
from blastvox.simulate.precompile import ensure_compiled, features_of
from blastvox.simulate.recorder import Recorder
from blastvox.simulate.settings import SimSettings, gravity_vector
from blastvox.simulate.shell import mark_in_shell
from blastvox.simulate.state import SimModel, State, build_model
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


def initial_state(model: VoxelModel, sm: SimModel) -> State:
    """One body per object of the model, at rest in its rest pose."""
    a = model.arrays
    n, n_links = sm.n_voxels, sm.n_links
    capacity = 2 * n + 2
    objects = a["voxel_object"].astype(np.int64)
    n_objects = int(objects.max()) + 1 if n else 0
    state = State(
        voxel_body=objects.copy(), voxel_alive=np.ones(n, dtype=bool),
        voxel_link_mask=np.zeros(n, dtype=np.uint8),
        voxel_yield=a["voxel_yield"].astype(np.float64).copy(),
        voxel_foundation=a["voxel_foundation"].copy(),
        voxel_foundation_yield=a["voxel_foundation_yield"].astype(np.float64).copy(),
        voxel_damage=np.zeros(n),
        voxel_combust=a["voxel_combustibility"].astype(np.float64).copy(),
        voxel_burning=np.zeros(n, dtype=bool), link_alive=np.ones(n_links, dtype=bool),
        link_yield=a["link_yield"].astype(np.float64).copy(),
        body_mass=np.zeros(capacity), body_com=np.zeros((capacity, 3)),
        body_inertia=np.zeros((capacity, 3, 3)), body_inv_inertia=np.zeros((capacity, 3, 3)),
        body_radius=np.zeros(capacity), body_pos=np.zeros((capacity, 3)),
        body_quat=np.zeros((capacity, 4)), body_lin=np.zeros((capacity, 3)),
        body_ang=np.zeros((capacity, 3)), body_fixed=np.zeros(capacity, dtype=bool),
        body_live=np.zeros(capacity, dtype=bool), body_dust=np.zeros(capacity, dtype=bool),
        body_asleep=np.zeros(capacity, dtype=bool),
        body_parent=np.full(capacity, -1, dtype=np.int64),
        body_born=np.zeros(capacity, dtype=np.int64),
        body_died=np.full(capacity, -1, dtype=np.int64),
        n_bodies=np.array([n_objects], dtype=np.int64))
    order = np.argsort(objects, kind="stable")
    bounds = np.searchsorted(objects[order], np.arange(n_objects + 1))
    for b in range(n_objects):
        members = order[bounds[b]:bounds[b + 1]]
        mass, com, inertia = aggregate(members, sm.voxel_mass, sm.voxel_centroid,
                                       sm.voxel_inertia)
        state.body_mass[b], state.body_com[b], state.body_inertia[b] = mass, com, inertia
        state.body_inv_inertia[b] = inverse_inertia(inertia)
        state.body_pos[b] = com
        state.body_quat[b] = (1.0, 0.0, 0.0, 0.0)
        state.body_live[b] = True
        state.body_fixed[b] = bool(state.voxel_foundation[members].any())
    link_masks(sm.link_voxels, sm.link_face, state.link_alive, state.voxel_link_mask)
    body_radii(state.voxel_body, state.voxel_alive, sm.voxel_centroid, sm.voxel_radius,
               state.body_com, state.body_radius, n_objects)
    return state


def simulate(model: VoxelModel, settings: SimSettings, progress: Progress | None = None,
             warn: Callable[[str], None] | None = None) -> SimCache:
    """Run the blast simulation of ``model`` with ``settings``."""
    progress = progress or Progress()
    warn = warn or (lambda message: None)
    ensure_compiled(features_of(settings, model), notify=progress.note)
    sm = build_model(model)
    state = initial_state(model, sm)
    if not settings.ground:
        state.voxel_foundation[:] = False
        state.body_fixed[:] = False
    charges = build_charges(settings.charges)
    dt = settings.step_seconds()
    if dt < settings.dt * (1 - 1e-12):
        warn(f"dt {settings.dt:g} s does not divide the frame interval 1/{settings.fps:g} s; "
             f"using {dt:g} s ({settings.steps_per_frame()} steps per frame)")
    per_frame = settings.steps_per_frame()
    frames = settings.frame_count()
    total_steps = (frames - 1) * per_frame
    run = _Run(sm, state, charges, settings, dt)
    limits = LimitMonitor(sm, settings, dt)  # warns once per limit the run passes
    counts = link_alive_counts(sm.voxel_link_offsets, sm.voxel_link_ids, state.link_alive)
    counted = run.links_version
    run.rec.frame(0, state, counts, charges.front_radius(0.0))
    for step in range(1, total_steps + 1):
        run.step(step, -(-step // per_frame))
        if step % per_frame == 0:
            if run.links_version != counted:  # links only change in _topology
                counts = link_alive_counts(sm.voxel_link_offsets, sm.voxel_link_ids,
                                           state.link_alive)
                counted = run.links_version
            run.rec.frame(step, state, counts, charges.front_radius(step * dt))
            limits.check(state)
            progress.update(step * dt, step, total_steps)
    limits.finish()
    frame_time = np.arange(frames) * (per_frame * dt)
    arrays = run.rec.pack(state, sm.voxel_mass, frame_time)
    arrays.update(charge_position=charges.position.copy(), charge_tnt_kg=charges.tnt_kg.copy(),
                  charge_time=charges.time.copy(), voxel_ignite_frame=run.ignite_frame)
    arrays.update(run.emitter.arrays())
    radius = arrays["shock_radius"]
    arrays["shock_opacity"] = (cues.shock_opacity(radius, charges.tnt_kg)
                               if settings.shock_sphere else np.zeros_like(radius))
    camera = settings.camera if settings.camera_shake else None
    arrays["camera_offset"] = (np.zeros((frames, 3)) if camera is None else cues.camera_shake(
        np.asarray(camera[0]), frame_time, charges.position, charges.tnt_kg, charges.time))
    meta = {"tool_version": __version__, "fps": settings.fps, "dt": dt,
            "duration": settings.duration, "fracture": settings.fracture, "seed": settings.seed,
            "settings": settings.to_dict(), "up_axis": model.meta.get("up_axis"),
            "ground_height": sm.ground_height if settings.ground else None,
            "steps": total_steps, "broken_links": run.broken_total,
            "ground_contacts": run.ground_contacts, "collisions": run.collisions,
            "effects": run.effects, "gravity_vector": run.gravity.tolist(),
            "particle_systems": particle_meta(),
            "camera": settings.to_dict()["camera"]}
    # wall time is reported by the CLI, never stored: caches must be byte-identical
    return SimCache(arrays=arrays, model=model, meta=meta)


class _Run:
    """The mutable machinery of one run: state, scratch arrays and the step."""

    def __init__(self, sm: SimModel, state: State, charges: Charges, settings: SimSettings,
                 dt: float) -> None:
        self.sm, self.state, self.charges, self.settings, self.dt = sm, state, charges, settings, dt
        capacity = len(state.body_mass)
        self.gravity = gravity_vector(sm.up, settings.gravity)
        self.rec = Recorder(sm.n_voxels, sm.voxel_link_offsets, state.voxel_yield.copy())
        self.broken = np.zeros(sm.n_links, dtype=bool)
        self.destroyed = np.zeros(sm.n_voxels, dtype=bool)
        self.dirty = np.zeros(capacity, dtype=bool)
        self.impulse = np.zeros((capacity, 3))
        self.angular = np.zeros((capacity, 3))
        self.rot = np.zeros((capacity, 3, 3))
        self.active = np.zeros(capacity, dtype=bool)
        self.component = np.zeros(sm.n_voxels, dtype=np.int64)
        self.order = np.zeros(sm.n_voxels, dtype=np.int64)
        self.vertex_stamp = np.full(len(sm.vertices), -1, dtype=np.int64)
        self.hits = np.zeros((4096, 4))
        self.resting = np.zeros(capacity, dtype=bool)
        # bodies resting on the ground or on something at rest, last step and this one
        self.supported = np.zeros(capacity, dtype=bool)
        self.supported_next = np.zeros(capacity, dtype=bool)
        # a contact slower than one step of gravity's pull (plus sleep speed) is resting
        self.rest_speed = settings.sleep_speed + 2.0 * abs(settings.gravity) * dt
        self.rest_decay = math.exp(-settings.rest_damping * dt)
        self.max_contact_radius = float(sm.voxel_contact_radius.max(initial=0.0))
        # kg/m^3 per voxel (its contact radius is (volume)^(1/3) / 2)
        self.voxel_density = sm.voxel_mass / np.maximum((2.0 * sm.voxel_contact_radius) ** 3,
                                                        1e-300)
        self.contacts = np.zeros((64, 3))
        self.ground = sm.ground_height if settings.ground else None
        self.boundary = None  # (offsets, members), rebuilt after topology changes
        self.boundary_version = 0
        self.still = np.zeros(capacity, dtype=np.int64)
        self.still_steps = max(1, round(0.5 / dt))  # half a second below sleep_speed
        self.static_key = None
        self.rest, self.rest_version = None, -1
        self.links_version = 0  # counts topology changes (the only place links die)
        # fracture candidates: points of the rest grids a shell can reach this step
        self.link_owner = np.ascontiguousarray(sm.link_voxels[:, 0])
        self.voxel_owner = np.arange(sm.n_voxels, dtype=np.int64)
        self.link_candidate = np.zeros(sm.n_links, dtype=bool)
        self.voxel_candidate = np.zeros(sm.n_voxels, dtype=bool)
        # blast impulse taken by voxels of fixed bodies during the current wave (N s, N m s)
        self.held_p = np.zeros((sm.n_voxels, 3))
        self.held_l = np.zeros((sm.n_voxels, 3))
        self.holding = False
        self.static = None
        self.broken_total = self.ground_contacts = self.collisions = 0
        self.crossed = np.zeros(sm.n_voxels, dtype=bool)
        combustible = bool(np.isfinite(state.voxel_combust).any())
        # model only what the scene needs: no combustible material, no fire
        self.fire_on = settings.fire and combustible
        self.effects = {"collisions": settings.collisions, "ground": self.ground is not None,
                        "fire": self.fire_on, "dust": settings.dust,
                        "fireball": settings.fireball, "shock_sphere": settings.shock_sphere,
                        "camera_shake": settings.camera_shake and settings.camera is not None}
        self.emitter = Emitter(dict(settings.budgets), settings.seed)
        self.ignite_frame = np.full(sm.n_voxels, -1, dtype=np.int32)
        self.initial_voxel_yield = state.voxel_yield.copy()
        self.initial_link_yield = state.link_yield.copy()
        self.ignite_scratch = np.zeros(sm.n_voxels, dtype=bool)
        self.burning_count = 0
        self.ring_done = np.zeros(len(charges.tnt_kg), dtype=bool)

    @property
    def n_bodies(self) -> int:
        return int(self.state.n_bodies[0])

    def step(self, step: int, frame_next: int) -> None:
        st, ch = self.state, self.charges
        t0, t1 = (step - 1) * self.dt, step * self.dt
        body_rotations(st.body_quat, st.body_live, self.n_bodies, self.rot)
        front_in, front_out = ch.front_radius(t0, before=-1.0), ch.front_radius(t1)
        if bodies_in_shell(st.body_pos, st.body_radius, st.body_live, self.n_bodies,
                           ch.position, front_in, front_out, self.active):
            self._fracture(front_in, front_out)
            if self.fire_on:
                self._ignite(front_in, front_out, frame_next)
            self._topology(step, t1, frame_next)
            if self.settings.dust:
                self._shock_dust(t1, front_out)
        if self.fire_on and self.burning_count:
            self._burn(step, t1, frame_next)
        if self.settings.fireball:
            self._fireball(t0, t1)
        if self.settings.dust and self.ground is not None:
            self._ground_ring(t1, front_out)
        self._blast(t0, t1, front_out)
        if not any_moving(st.body_live, st.body_fixed, st.body_dust, st.body_asleep,
                          self.n_bodies):
            self._still_step()
            return
        integrate_velocities(self.dt, self.gravity, self.settings.linear_drag,
                             self.settings.angular_drag, self.impulse, self.angular,
                             st.body_mass, st.body_lin, st.body_ang, st.body_fixed,
                             st.body_live, st.body_dust, st.body_asleep, self.n_bodies)
        if self.settings.collisions:
            self._collide(step, t1, frame_next)
        if self.ground is not None:
            self._ground()
        if self.settings.collisions or self.ground is not None:
            settle(st.body_mass, st.body_inv_inertia, self.rot, st.body_lin, st.body_ang,
                   st.body_radius, st.body_fixed, st.body_live, st.body_dust, st.body_asleep,
                   self.still, self.n_bodies, self.settings.sleep_speed, self.still_steps)
        integrate_positions(self.dt, st.body_mass, st.body_inv_inertia, self.rot, st.body_pos,
                            st.body_quat, st.body_lin, st.body_ang, st.body_fixed, st.body_live,
                            st.body_dust, st.body_asleep, self.n_bodies)

    def _still_step(self) -> None:
        """The rest of a step in which no body can move: the velocity, contact and
        position kernels would only do their bookkeeping, done here (the results are
        byte-identical to running them; a settled shot's steps cost ~10x less)."""
        if self.settings.collisions:
            self._begin_contacts()
        if self.settings.collisions or self.ground is not None:
            self.still[:self.n_bodies] = 0  # settle() resets every body it cannot move

    def _fracture(self, front_in, front_out) -> None:
        st, sm, ch, s = self.state, self.sm, self.charges, self.settings
        self.broken[:] = False
        self.destroyed[:] = False
        self.crossed[:] = False
        self.dirty[:self.n_bodies] = False
        if s.fracture == "damage":
            n = fracture.fracture_damage(
                ch.position, ch.scale, front_in, front_out, ch.table, s.damage_b, s.damage_c,
                s.orientation_factor, sm.voxel_centroid, st.voxel_alive, st.voxel_damage,
                sm.voxel_link_offsets, sm.voxel_link_ids, sm.link_voxels, sm.link_direction,
                st.link_alive, st.link_yield, st.voxel_body, self.active, st.body_pos, self.rot,
                st.body_com, self.broken, self.dirty)
        else:
            n = fracture.fracture_links(
                ch.position, ch.scale, front_in, front_out, ch.table, s.orientation_factor,
                s.weakening, sm.link_voxels, sm.link_midpoint, sm.link_direction, st.link_alive,
                st.link_yield, st.voxel_body, self.active, st.body_pos, self.rot, st.body_com,
                self._candidates(sm.link_grid, self.link_owner, self.link_candidate, front_in,
                                 front_out),
                self.broken, self.dirty)
        self.broken_total += int(n)
        released = fracture.fracture_voxels(
            ch.position, ch.scale, front_in, front_out, ch.table, s.weakening,
            sm.voxel_centroid, st.voxel_alive, st.voxel_yield, st.voxel_foundation,
            st.voxel_foundation_yield, st.voxel_body, self.active, st.body_pos, self.rot,
            st.body_com,
            self._candidates(sm.voxel_grid, self.voxel_owner, self.voxel_candidate, front_in,
                             front_out),
            self.destroyed, self.dirty, self.crossed)
        if released:
            topology.refresh_fixed(st.voxel_body, st.voxel_alive, st.voxel_foundation,
                                   st.body_fixed, st.body_live, st.body_lin, st.body_ang)
            self._release_held()

    def _candidates(self, grid, owner, out, front_in, front_out) -> np.ndarray:
        """Flag the grid's points that a front's shell can reach this step (see shell)."""
        st, ch = self.state, self.charges
        origin, dims, offsets, ids = grid
        out[:] = False
        mark_in_shell(origin, dims, self.sm.grid_cell, offsets, ids, owner, st.voxel_body,
                      self.active, st.body_com, st.body_pos, self.rot, st.body_radius,
                      ch.position, front_in, front_out, out)
        return out

    def _topology(self, step: int, t1: float, frame_next: int) -> None:
        """Apply this step's broken links and dusted voxels: masks, splits, records."""
        st, sm = self.state, self.sm
        destroyed = np.flatnonzero(self.destroyed)
        broken = np.flatnonzero(self.broken)
        if not destroyed.size and not broken.size:
            return
        self.links_version += 1
        if destroyed.size:
            fracture.kill_links_of(self.destroyed, sm.voxel_link_offsets, sm.voxel_link_ids,
                                   st.link_alive)
        self.rec.link_breaks(broken, t1)
        link_masks(sm.link_voxels, sm.link_face, st.link_alive, st.voxel_link_mask)
        topology.split_bodies(
            self.dirty, step, st.voxel_body, st.voxel_alive, st.voxel_foundation, st.link_alive,
            sm.link_voxels, sm.voxel_link_offsets, sm.voxel_link_ids, sm.voxel_mass,
            sm.voxel_centroid, sm.voxel_inertia, st.body_mass, st.body_com, st.body_inertia,
            st.body_inv_inertia, st.body_pos, st.body_quat, st.body_lin, st.body_ang,
            st.body_fixed, st.body_live, st.body_dust, st.body_parent, st.body_born,
            st.body_died, st.n_bodies, self.component, self.order)
        st.body_asleep[:self.n_bodies][self.dirty[:self.n_bodies]] = False
        body_rotations(st.body_quat, st.body_live, self.n_bodies, self.rot)
        self._release_held()
        body_radii(st.voxel_body, st.voxel_alive, sm.voxel_centroid, sm.voxel_radius,
                   st.body_com, st.body_radius, self.n_bodies)
        self.rec.voxels_destroyed(destroyed, t1, frame_next, st, sm.voxel_mass)
        if self.settings.dust and destroyed.size:
            self._voxel_dust(destroyed, t1)
        self.boundary = None
        self.broken[:] = False
        self.destroyed[:] = False

    def _release_held(self) -> None:
        """Freed pieces take the impulse their voxels took while held (see forces)."""
        if self.holding:
            st = self.state
            release_held(st.voxel_body, st.voxel_alive, self.sm.voxel_centroid, st.body_fixed,
                         st.body_live, st.body_com, st.body_pos, self.rot, st.body_lin,
                         st.body_ang, self.held_p, self.held_l)

    def _blast(self, t0: float, t1: float, front_out) -> None:
        st, sm, ch = self.state, self.sm, self.charges
        n = self.n_bodies
        self.impulse[:n] = 0.0
        self.angular[:n] = 0.0
        reach_in = ch.tail_radius(t0)
        if not bodies_in_shell(st.body_pos, st.body_radius, st.body_live, n, ch.position,
                               reach_in, front_out, self.active):
            if self.holding:  # every wave has passed: what held voxels took is spent
                self.held_p[:] = 0.0
                self.held_l[:] = 0.0
                self.holding = False
            return
        blast_impulses(t0, t1, ch.position, ch.time, ch.scale, front_out, reach_in, ch.table,
                       self._boundary()[1], sm.vertices, sm.voxel_vertices, sm.voxel_centroid,
                       st.voxel_body, st.voxel_alive, st.voxel_link_mask, sm.voxel_radius,
                       sm.conform_slot, sm.conform_face_area, sm.conform_face_centroid,
                       self.active, st.body_com, st.body_pos, self.rot, st.body_fixed,
                       st.body_live, st.body_dust, self.impulse, self.angular, self.held_p,
                       self.held_l)
        self.holding = True
        wake_on_impulse(self.impulse, self.angular, st.body_asleep, n)

    def _boundary(self):
        if self.boundary is None:
            st, sm = self.state, self.sm
            offsets, members = contact.boundary_lists(st.voxel_body, st.voxel_alive,
                                                      st.voxel_link_mask, sm.conform_slot,
                                                      self.n_bodies)
            need = 8 * int(np.diff(offsets).max(initial=0)) + 8
            if need > len(self.contacts):
                self.contacts = np.zeros((need, 3))
            self.boundary = (offsets, members)
            self.boundary_version += 1
        return self.boundary

    def _rest_grid(self):
        """Boundary voxels by body and rest cell, rebuilt when the boundary changes."""
        self._boundary()
        if self.rest_version != self.boundary_version:
            self.rest = contact.rest_grid(self.sm.voxel_centroid, self.state.voxel_body,
                                          self.boundary[1], 2.0 * self.max_contact_radius)
            self.rest_version = self.boundary_version
        return self.rest

    def _static(self):
        """The hash of resting bodies' voxels, rebuilt when what rests changes."""
        st, sm = self.state, self.sm
        n = self.n_bodies
        resting = st.body_live[:n] & ~st.body_dust[:n] & (st.body_fixed[:n] | st.body_asleep[:n])
        key = (self.boundary_version, resting.tobytes())
        if self.static_key != key:
            offsets, members = self._boundary()
            self.static = contact.static_hash(
                sm.voxel_centroid, st.voxel_body, offsets, members, st.body_com, st.body_pos,
                self.rot, st.body_live, st.body_dust, st.body_fixed, st.body_asleep, n,
                2.0 * self.max_contact_radius)
            self.static_key = key
        return self.static

    def _collide(self, step: int, t1: float, frame_next: int) -> None:
        st, sm, s = self.state, self.sm, self.settings
        offsets, members = self._boundary()
        self._begin_contacts()
        before = self.collisions
        self.collisions += contact.collide_bodies(
            sm.voxel_centroid, sm.voxel_contact_radius, sm.voxel_restitution, st.voxel_yield,
            st.voxel_alive, st.voxel_body, offsets, members, st.body_mass, st.body_inv_inertia,
            st.body_radius, st.body_com, st.body_pos, self.rot, st.body_lin, st.body_ang,
            st.body_fixed, st.body_live, st.body_dust, st.body_asleep, self.n_bodies,
            s.sleep_speed, self.rest_speed, s.friction, self.voxel_density, s.weakening,
            self.destroyed, self.dirty, self.resting, sm.up, self.supported, self.supported_next,
            self.hits, 2.0 * self.max_contact_radius,
            *self._static(), *self._rest_grid())
        damp_resting(self.resting, st.body_mass, st.body_inv_inertia, self.rot, st.body_lin,
                     st.body_ang, st.body_radius, self.n_bodies, self.rest_decay,
                     4.0 * s.sleep_speed)
        resolved = min(self.collisions - before, len(self.hits))
        if self.settings.dust and resolved:
            self._collision_dust(resolved, t1)
        if self.destroyed.any():
            self._topology(step, t1, frame_next)

    def _begin_contacts(self) -> None:
        """Per-step contact bookkeeping: no voxel destroyed or body dirty yet, and last
        step's support flags become this step's, the next ones starting empty."""
        self.destroyed[:] = False
        self.dirty[:self.n_bodies] = False
        self.supported, self.supported_next = self.supported_next, self.supported
        self.supported_next[:] = False

    def _ground(self) -> None:
        st, sm, s = self.state, self.sm, self.settings
        offsets, members = self._boundary()
        self.ground_contacts += contact.ground_contacts(
            self.dt, self.ground, sm.up_axis, s.friction, s.rest_damping, s.sleep_speed,
            sm.vertices, sm.voxel_vertices, sm.voxel_centroid, sm.voxel_radius,
            sm.voxel_restitution, offsets, members,
            self.vertex_stamp, st.body_mass, st.body_inv_inertia, st.body_radius, st.body_com,
            st.body_pos, self.rot, st.body_lin, st.body_ang, st.body_fixed, st.body_live,
            st.body_dust, st.body_asleep, self.n_bodies, self.contacts, self.supported_next)

    # -- fire -------------------------------------------------------------------------

    def _ignite(self, front_in, front_out, frame_next: int) -> None:
        st, sm, ch = self.state, self.sm, self.charges
        was = st.voxel_burning.copy()
        n = fire.ignite_by_blast(ch.position, front_in, front_out,
                                 self.settings.fire_pressure_scale, sm.voxel_centroid,
                                 st.voxel_alive, st.voxel_body, self.active, st.body_pos, self.rot,
                                 st.body_com, st.voxel_combust, st.voxel_burning, ch.table,
                                 ch.scale)
        if n:
            self.ignite_frame[st.voxel_burning & ~was] = frame_next
            self.burning_count += int(n)

    def _burn(self, step: int, t1: float, frame_next: int) -> None:
        st, sm, s = self.state, self.sm, self.settings
        was = st.voxel_burning.copy()
        self.broken[:] = False
        self.destroyed[:] = False
        self.dirty[:self.n_bodies] = False
        self.burning_count = fire.burn(
            self.dt, s.burn_rate, s.fire_spread, s.fire_side_factor, sm.up, st.voxel_alive,
            st.voxel_body, st.voxel_yield, self.initial_voxel_yield, st.voxel_combust,
            st.voxel_burning, sm.voxel_link_offsets, sm.voxel_link_ids, sm.link_voxels,
            sm.link_direction, st.link_alive, st.link_yield, self.initial_link_yield, self.rot,
            self.broken, self.destroyed, self.dirty, self.ignite_scratch)
        self.ignite_frame[st.voxel_burning & ~was] = frame_next
        self.broken_total += int(self.broken.sum())
        self._topology(step, t1, frame_next)
        self._flames(t1)

    # -- particles --------------------------------------------------------------------

    def _world_centres(self, voxels: np.ndarray) -> np.ndarray:
        st, sm = self.state, self.sm
        b = st.voxel_body[voxels]
        rot = self.rot[b]
        rel = sm.voxel_centroid[voxels] - st.body_com[b]
        return st.body_pos[b] + np.einsum("kij,kj->ki", rot, rel)

    def _voxel_dust(self, voxels: np.ndarray, t: float) -> None:
        """Destroyed voxels burst into dust that carries their momentum."""
        st = self.state
        per = 6
        rng = self.emitter.rng("dust")
        b = st.voxel_body[voxels]
        velocity = st.body_lin[b] / st.body_mass[b][:, None]
        centre = self._world_centres(voxels)
        size = np.cbrt(self.sm.voxel_mass[voxels] / np.maximum(self.sm.voxel_mass.max(), 1e-30))
        pos = np.repeat(centre, per, axis=0) + rng.normal(0.0, 0.2, (len(voxels) * per, 3)) \
            * np.repeat(2 * self.sm.voxel_contact_radius[voxels], per)[:, None]
        vel = np.repeat(velocity, per, axis=0) + rng.normal(0.0, 1.0, (len(voxels) * per, 3))
        self.emitter.emit("dust", t, pos, vel, np.repeat(size, per))

    def _collision_dust(self, resolved: int, t: float) -> None:
        if self.hits[:resolved, 3].max() <= 2.0 or not self.emitter.room("dust"):
            return
        hits = self.hits[:resolved]
        strong = hits[hits[:, 3] > 2.0]  # impacts above 2 m/s raise dust; resting contacts don't
        if len(strong):
            rng = self.emitter.rng("dust")
            vel = rng.normal(0.0, 1.0, (len(strong), 3)) + 2.0 * self.sm.up
            self.emitter.emit("dust", t, strong[:, :3], vel)

    def _shock_dust(self, t: float, front_out) -> None:
        """Dust knocked off the exposed voxels the shock front crossed this step."""
        st = self.state
        voxels = np.flatnonzero(self.crossed & st.voxel_alive & (st.voxel_link_mask != 0x3F))
        if not voxels.size or not self.emitter.room("dust"):
            return
        rng = self.emitter.rng("dust")
        pick = voxels[rng.random(len(voxels)) < 0.25]
        if not pick.size:
            return
        centre = self._world_centres(pick)
        away = centre - self.charges.position[np.argmin(
            np.linalg.norm(centre[:, None, :] - self.charges.position[None], axis=2), axis=1)]
        away /= np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-9)
        self.emitter.emit("dust", t, centre, 3.0 * away + rng.normal(0.0, 0.5, away.shape))

    def _ground_ring(self, t: float, front_out) -> None:
        """Dust kicked up where the shock sphere meets the ground (while it is strong)."""
        up, axis = self.sm.up, self.sm.up_axis
        others = [a for a in range(3) if a != axis]
        rng = self.emitter.rng("dust")
        for c in range(len(self.charges.tnt_kg)):
            height = self.charges.position[c, axis] - self.ground
            r = front_out[c]
            if self.ring_done[c] or r <= abs(height) or not self.emitter.room("dust"):
                continue
            if self.charges.peak(c, r) < 2e3:  # below 2 kPa the wave raises no dust
                self.ring_done[c] = True  # and the front only weakens from here
                continue
            ring = np.sqrt(r * r - height * height)
            # about min(64, 4 + ring) particles per 1/240 s whatever the step
            count = int(rng.poisson(min(64.0, 4.0 + ring) * self.dt * 240.0))
            if count == 0:
                continue
            angle = rng.uniform(0.0, 2 * np.pi, count)
            pos = np.repeat(self.charges.position[c:c + 1], count, axis=0)
            pos[:, axis] = self.ground
            pos[:, others[0]] += ring * np.cos(angle)
            pos[:, others[1]] += ring * np.sin(angle)
            out = np.zeros((count, 3))
            out[:, others[0]] = np.cos(angle)
            out[:, others[1]] = np.sin(angle)
            self.emitter.emit("dust", t, pos, 4.0 * out + 2.0 * up[None, :])

    def _fireball(self, t0: float, t1: float) -> None:
        """A burst of flame particles at each charge when it goes off."""
        rng = self.emitter.rng("fireball")
        for c in range(len(self.charges.tnt_kg)):
            if not (t0 < self.charges.time[c] <= t1) and not (t0 == 0 == self.charges.time[c]):
                continue
            count = 200
            radius = 1.5 * self.charges.scale[c]  # visible fireball ~ 1.5 W^(1/3) m
            direction = rng.normal(size=(count, 3))
            direction /= np.linalg.norm(direction, axis=1, keepdims=True)
            speed = radius * 4.0 * rng.uniform(0.6, 1.0, count)  # drag 4/s stops it at ~radius
            pos = self.charges.position[c] + 0.1 * radius * direction
            self.emitter.emit("fireball", self.charges.time[c], pos, direction * speed[:, None],
                              self.charges.scale[c])

    def _flames(self, t: float) -> None:
        """Fire and smoke from burning voxels: on average 4 flames and 1 smoke puff a second."""
        st = self.state
        burning = np.flatnonzero(st.voxel_burning & st.voxel_alive)
        if not burning.size:
            return
        for system, rate in (("fire", 4.0), ("smoke", 1.0)):
            rng = self.emitter.rng(system)
            pick = burning[rng.random(len(burning)) < rate * self.dt]
            if pick.size and self.emitter.room(system):
                centre = self._world_centres(pick)
                vel = rng.normal(0.0, 0.3, (len(pick), 3)) + self.sm.up * 0.5
                self.emitter.emit(system, t, centre, vel)
