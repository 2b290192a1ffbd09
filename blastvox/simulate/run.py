"""``simulate(model, settings) -> SimCache``: the fixed-step loop.

A step is a sequence of kernels over flat arrays:

1. charges: the shock-front radius of each charge at the step's start and end;
2. fracture: links, voxels and foundations the fronts crossed (yield or damage model);
3. topology: bodies that lost links or voxels are re-searched and split;
4. forces: exact blast impulse of the step on exposed faces of free bodies;
5. integration: momenta, gravity, drag, positions, orientations;
6. output: at every frame boundary, live body transforms and damage.

Every kernel runs serially in a fixed order, so results are bit-identical for
any NUMBA_NUM_THREADS.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from blastvox import __version__
from blastvox.cache import SimCache
from blastvox.model import VoxelModel
from blastvox.simulate import fracture, topology
from blastvox.simulate.bodies import aggregate, inverse_inertia
from blastvox.simulate.forces import blast_impulses
from blastvox.simulate.integrate import integrate_bodies
from blastvox.simulate.kernels import (
    bodies_in_shell,
    body_radii,
    body_rotations,
    link_alive_counts,
    link_masks,
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
        body_radius=np.zeros(capacity),
        body_pos=np.zeros((capacity, 3)),
        body_quat=np.zeros((capacity, 4)), body_lin=np.zeros((capacity, 3)),
        body_ang=np.zeros((capacity, 3)), body_fixed=np.zeros(capacity, dtype=bool),
        body_live=np.zeros(capacity, dtype=bool), body_dust=np.zeros(capacity, dtype=bool),
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
    gravity = gravity_vector(sm.up, settings.gravity)
    radius = _voxel_radius(sm)
    body_radii(state.voxel_body, state.voxel_alive, sm.voxel_centroid, radius, state.body_com,
               state.body_radius, int(state.n_bodies[0]))
    rec = Recorder(sm.n_voxels, sm.voxel_link_offsets, state.voxel_yield.copy())
    scratch = _Scratch(sm, len(state.body_mass))
    counts = link_alive_counts(sm.voxel_link_offsets, sm.voxel_link_ids, state.link_alive)
    rec.frame(0, state, counts, charges.front_radius(0.0))
    broken_total = 0
    for step in range(1, total_steps + 1):
        t0, t1 = (step - 1) * dt, step * dt
        frame_next = -(-step // per_frame)
        broken_total += _step(step, t0, t1, frame_next, sm, state, charges, settings, gravity,
                              radius, rec, scratch)
        if step % per_frame == 0:
            counts = link_alive_counts(sm.voxel_link_offsets, sm.voxel_link_ids,
                                       state.link_alive)
            rec.frame(step, state, counts, charges.front_radius(t1))
            progress.update(t1, step, total_steps)
    frame_time = np.arange(frames) * (per_frame * dt)
    arrays = rec.pack(state, sm.voxel_mass, frame_time)
    arrays.update(charge_position=charges.position.copy(), charge_tnt_kg=charges.tnt_kg.copy(),
                  charge_time=charges.time.copy())
    meta = {"tool_version": __version__, "fps": settings.fps, "dt": dt,
            "duration": settings.duration, "fracture": settings.fracture, "seed": settings.seed,
            "settings": settings.to_dict(), "up_axis": model.meta.get("up_axis"),
            "steps": total_steps, "broken_links": broken_total}
    # wall time is reported by the CLI, never stored: caches must be byte-identical
    return SimCache(arrays=arrays, model=model, meta=meta)


class _Scratch:
    """Per-step work arrays, allocated once."""

    def __init__(self, sm: SimModel, capacity: int) -> None:
        self.broken = np.zeros(sm.n_links, dtype=bool)
        self.destroyed = np.zeros(sm.n_voxels, dtype=bool)
        self.dirty = np.zeros(capacity, dtype=bool)
        self.impulse = np.zeros((capacity, 3))
        self.angular = np.zeros((capacity, 3))
        self.rot = np.zeros((capacity, 3, 3))
        self.active = np.zeros(capacity, dtype=bool)
        self.component = np.zeros(sm.n_voxels, dtype=np.int64)
        self.order = np.zeros(sm.n_voxels, dtype=np.int64)


def _voxel_radius(sm: SimModel) -> np.ndarray:
    """Farthest corner of each voxel from its centroid, m."""
    corners = sm.vertices[sm.voxel_vertices]
    return np.sqrt(((corners - sm.voxel_centroid[:, None, :]) ** 2).sum(-1)).max(axis=1)


def _step(step, t0, t1, frame_next, sm: SimModel, state: State, charges: Charges,
          settings: SimSettings, gravity, radius, rec: Recorder, s: _Scratch) -> int:
    """One fixed step; returns the number of links broken."""
    n_bodies = int(state.n_bodies[0])
    front_in, front_out = charges.front_radius(t0, before=-1.0), charges.front_radius(t1)
    body_rotations(state.body_quat, state.body_live, n_bodies, s.rot)
    broken = 0
    if bodies_in_shell(state.body_pos, state.body_radius, state.body_live, n_bodies,
                       charges.position, front_in, front_out, s.active):
        s.broken[:] = False
        s.destroyed[:] = False
        s.dirty[:n_bodies] = False
        table = charges.table
        if settings.fracture == "damage":
            broken = fracture.fracture_damage(
                charges.position, charges.scale, front_in, front_out, table,
                settings.damage_b, settings.damage_c, settings.orientation_factor,
                sm.voxel_centroid, state.voxel_alive, state.voxel_damage, sm.voxel_link_offsets,
                sm.voxel_link_ids, sm.link_voxels, sm.link_direction, state.link_alive,
                state.link_yield, state.voxel_body, s.active, state.body_pos, s.rot,
                state.body_com, s.broken, s.dirty)
        else:
            broken = fracture.fracture_links(
                charges.position, charges.scale, front_in, front_out, table,
                settings.orientation_factor, settings.weakening, sm.link_voxels,
                sm.link_midpoint, sm.link_direction, state.link_alive, state.link_yield,
                state.voxel_body, s.active, state.body_pos, s.rot, state.body_com, s.broken,
                s.dirty)
        released = fracture.fracture_voxels(
            charges.position, charges.scale, front_in, front_out, table, settings.weakening,
            sm.voxel_centroid, state.voxel_alive, state.voxel_yield, state.voxel_foundation,
            state.voxel_foundation_yield, state.voxel_body, s.active, state.body_pos, s.rot,
            state.body_com, s.destroyed, s.dirty)
        destroyed = np.flatnonzero(s.destroyed)
        if destroyed.size:
            fracture.kill_links_of(s.destroyed, sm.voxel_link_offsets, sm.voxel_link_ids,
                                   state.link_alive)
        if broken or destroyed.size:
            rec.link_breaks(np.flatnonzero(s.broken), t1)
            link_masks(sm.link_voxels, sm.link_face, state.link_alive, state.voxel_link_mask)
            topology.split_bodies(
                s.dirty, step, state.voxel_body, state.voxel_alive, state.voxel_foundation,
                state.link_alive, sm.link_voxels, sm.voxel_link_offsets, sm.voxel_link_ids,
                sm.voxel_mass, sm.voxel_centroid, sm.voxel_inertia, state.body_mass,
                state.body_com, state.body_inertia, state.body_inv_inertia, state.body_pos,
                state.body_quat,
                state.body_lin, state.body_ang, state.body_fixed, state.body_live,
                state.body_dust, state.body_parent, state.body_born, state.body_died,
                state.n_bodies, s.component, s.order)
            body_radii(state.voxel_body, state.voxel_alive, sm.voxel_centroid, radius,
                       state.body_com, state.body_radius, int(state.n_bodies[0]))
            rec.voxels_destroyed(destroyed, t1, frame_next, state, sm.voxel_mass)
        if released:
            topology.refresh_fixed(state.voxel_body, state.voxel_alive, state.voxel_foundation,
                                   state.body_fixed, state.body_live, state.body_lin,
                                   state.body_ang)
        n_bodies = int(state.n_bodies[0])
        body_rotations(state.body_quat, state.body_live, n_bodies, s.rot)
    reach_in, reach_out = charges.tail_radius(t0), front_out
    s.impulse[:n_bodies] = 0.0
    s.angular[:n_bodies] = 0.0
    if bodies_in_shell(state.body_pos, state.body_radius, state.body_live, n_bodies,
                       charges.position, reach_in, reach_out, s.active):
        blast_impulses(t0, t1, charges.position, charges.time, charges.scale, reach_out,
                       reach_in, charges.table, sm.vertices, sm.voxel_vertices, sm.voxel_centroid,
                       state.voxel_body, state.voxel_alive, state.voxel_link_mask, radius,
                       sm.conform_slot, sm.conform_face_area, sm.conform_face_centroid,
                       s.active, state.body_com, state.body_pos, s.rot, state.body_fixed,
                       state.body_live, state.body_dust, s.impulse, s.angular)
    integrate_bodies(t1 - t0, gravity, settings.linear_drag, settings.angular_drag, s.impulse,
                     s.angular, state.body_mass, state.body_inv_inertia, s.rot, state.body_pos,
                     state.body_quat, state.body_lin, state.body_ang, state.body_fixed,
                     state.body_live, state.body_dust, n_bodies)
    return int(broken)
