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

from collections.abc import Callable

import numpy as np

from blastvox import __version__
from blastvox.cache import SimCache
from blastvox.model import VoxelModel
from blastvox.simulate import contact, fracture, topology
from blastvox.simulate.bodies import aggregate, inverse_inertia
from blastvox.simulate.forces import blast_impulses
from blastvox.simulate.integrate import integrate_positions, integrate_velocities
from blastvox.simulate.kernels import (
    bodies_in_shell,
    body_radii,
    body_rotations,
    link_alive_counts,
    link_masks,
    wake_on_impulse,
)
from blastvox.simulate.recorder import Recorder
from blastvox.simulate.settings import SimSettings, gravity_vector
from blastvox.simulate.state import SimModel, State, build_model
from blastvox.simulate.wave import Charges, build_charges


class Progress:
    """Progress sink: ``update(sim_time_s, steps_done, total_steps)``; no-op here."""

    def update(self, sim_time: float, done: int, total: int) -> None: ...


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
        voxel_damage=np.zeros(n), link_alive=np.ones(n_links, dtype=bool),
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
    counts = link_alive_counts(sm.voxel_link_offsets, sm.voxel_link_ids, state.link_alive)
    run.rec.frame(0, state, counts, charges.front_radius(0.0))
    for step in range(1, total_steps + 1):
        run.step(step, -(-step // per_frame))
        if step % per_frame == 0:
            counts = link_alive_counts(sm.voxel_link_offsets, sm.voxel_link_ids,
                                       state.link_alive)
            run.rec.frame(step, state, counts, charges.front_radius(step * dt))
            progress.update(step * dt, step, total_steps)
    frame_time = np.arange(frames) * (per_frame * dt)
    arrays = run.rec.pack(state, sm.voxel_mass, frame_time)
    arrays.update(charge_position=charges.position.copy(), charge_tnt_kg=charges.tnt_kg.copy(),
                  charge_time=charges.time.copy())
    meta = {"tool_version": __version__, "fps": settings.fps, "dt": dt,
            "duration": settings.duration, "fracture": settings.fracture, "seed": settings.seed,
            "settings": settings.to_dict(), "up_axis": model.meta.get("up_axis"),
            "ground_height": sm.ground_height if settings.ground else None,
            "steps": total_steps, "broken_links": run.broken_total,
            "ground_contacts": run.ground_contacts, "collisions": run.collisions}
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
        self.max_contact_radius = float(sm.voxel_contact_radius.max(initial=0.0))
        self.contacts = np.zeros((64, 3))
        self.ground = sm.ground_height if settings.ground else None
        self.boundary = None  # (offsets, members), rebuilt after topology changes
        self.broken_total = self.ground_contacts = self.collisions = 0

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
            self._topology(step, t1, frame_next)
        self._blast(t0, t1, front_out)
        integrate_velocities(self.dt, self.gravity, self.settings.linear_drag,
                             self.settings.angular_drag, self.impulse, self.angular,
                             st.body_mass, st.body_lin, st.body_ang, st.body_fixed,
                             st.body_live, st.body_dust, st.body_asleep, self.n_bodies)
        if self.settings.collisions:
            self._collide(step, t1, frame_next)
        if self.ground is not None:
            self._ground()
        integrate_positions(self.dt, st.body_mass, st.body_inv_inertia, self.rot, st.body_pos,
                            st.body_quat, st.body_lin, st.body_ang, st.body_fixed, st.body_live,
                            st.body_dust, st.body_asleep, self.n_bodies)

    def _fracture(self, front_in, front_out) -> None:
        st, sm, ch, s = self.state, self.sm, self.charges, self.settings
        self.broken[:] = False
        self.destroyed[:] = False
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
                self.broken, self.dirty)
        self.broken_total += int(n)
        released = fracture.fracture_voxels(
            ch.position, ch.scale, front_in, front_out, ch.table, s.weakening,
            sm.voxel_centroid, st.voxel_alive, st.voxel_yield, st.voxel_foundation,
            st.voxel_foundation_yield, st.voxel_body, self.active, st.body_pos, self.rot,
            st.body_com, self.destroyed, self.dirty)
        if released:
            topology.refresh_fixed(st.voxel_body, st.voxel_alive, st.voxel_foundation,
                                   st.body_fixed, st.body_live, st.body_lin, st.body_ang)

    def _topology(self, step: int, t1: float, frame_next: int) -> None:
        """Apply this step's broken links and dusted voxels: masks, splits, records."""
        st, sm = self.state, self.sm
        destroyed = np.flatnonzero(self.destroyed)
        broken = np.flatnonzero(self.broken)
        if not destroyed.size and not broken.size:
            return
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
        body_radii(st.voxel_body, st.voxel_alive, sm.voxel_centroid, sm.voxel_radius,
                   st.body_com, st.body_radius, self.n_bodies)
        self.rec.voxels_destroyed(destroyed, t1, frame_next, st, sm.voxel_mass)
        body_rotations(st.body_quat, st.body_live, self.n_bodies, self.rot)
        self.boundary = None
        self.broken[:] = False
        self.destroyed[:] = False

    def _blast(self, t0: float, t1: float, front_out) -> None:
        st, sm, ch = self.state, self.sm, self.charges
        n = self.n_bodies
        self.impulse[:n] = 0.0
        self.angular[:n] = 0.0
        reach_in = ch.tail_radius(t0)
        if not bodies_in_shell(st.body_pos, st.body_radius, st.body_live, n, ch.position,
                               reach_in, front_out, self.active):
            return
        blast_impulses(t0, t1, ch.position, ch.time, ch.scale, front_out, reach_in, ch.table,
                       sm.vertices, sm.voxel_vertices, sm.voxel_centroid, st.voxel_body,
                       st.voxel_alive, st.voxel_link_mask, sm.voxel_radius, sm.conform_slot,
                       sm.conform_face_area, sm.conform_face_centroid, self.active, st.body_com,
                       st.body_pos, self.rot, st.body_fixed, st.body_live, st.body_dust,
                       self.impulse, self.angular)
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
        return self.boundary

    def _collide(self, step: int, t1: float, frame_next: int) -> None:
        st, sm, s = self.state, self.sm, self.settings
        offsets, members = self._boundary()
        self.destroyed[:] = False
        self.dirty[:self.n_bodies] = False
        self.collisions += contact.collide_bodies(
            sm.voxel_centroid, sm.voxel_contact_radius, sm.voxel_restitution, st.voxel_yield,
            st.voxel_alive, st.voxel_body, offsets, members, st.body_mass, st.body_inv_inertia,
            st.body_radius, st.body_com, st.body_pos, self.rot, st.body_lin, st.body_ang,
            st.body_fixed, st.body_live, st.body_dust, st.body_asleep, self.n_bodies,
            s.sleep_speed, s.impact_time, s.weakening, self.destroyed, self.dirty, self.hits,
            self.max_contact_radius)
        if self.destroyed.any():
            self._topology(step, t1, frame_next)

    def _ground(self) -> None:
        st, sm, s = self.state, self.sm, self.settings
        offsets, members = self._boundary()
        self.ground_contacts += contact.ground_contacts(
            self.dt, self.ground, sm.up_axis, s.friction, s.rest_damping, s.sleep_speed,
            sm.vertices, sm.voxel_vertices, sm.voxel_restitution, offsets, members,
            self.vertex_stamp, st.body_mass, st.body_inv_inertia, st.body_radius, st.body_com,
            st.body_pos, self.rot, st.body_lin, st.body_ang, st.body_fixed, st.body_live,
            st.body_dust, st.body_asleep, self.n_bodies, self.contacts)
