"""Fire (Martins 2001 §6): ignition by the blast, burning, and spread along links.

Each voxel has a combustibility limit (Pa) from its material (inf: never
burns). When a wave reaches a voxel, ``fire_pressure_scale`` x its peak
overpressure is taken off the limit; below zero the voxel burns. A burning
voxel loses ``burn_rate`` of its initial yield per second, and so do its
links: a link worn to zero breaks, a voxel worn to zero falls to ash (dust).
Heat spreads along alive links: an unburnt neighbour's limit drops by
``spread`` Pa/s times an orientation factor, 1 for a neighbour straight
above and ``side_factor`` for one beside or below (linearly in between), so
fire climbs a structure faster than it spreads sideways. Ignitions found in a
step take effect at its end, so fire advances at most one link per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from blastvox.jit import kernel
from blastvox.simulate.wave import peak_overpressure


class FireParams(NamedTuple):
    """dt: step, s; burn_rate: fraction of the initial yields burnt away per second;
    spread: combustibility taken from an upward neighbour per second; side_factor:
    the share of that sideways and downwards; up (3,)."""

    dt: float
    burn_rate: float
    spread: float
    side_factor: float
    up: np.ndarray


@kernel
def ignite_by_blast(front, scale, voxel_centroid, voxels, bodies, active) -> int:
    """Erode combustibility by ``scale`` x the peak of waves crossing voxel centres this
    step; returns how many voxels caught fire."""
    charge_pos, front_in, front_out = front.position, front.inner, front.outer
    table, charge_scale = front.table, front.scale
    voxel_alive, voxel_body, combust, burning = (voxels.alive, voxels.body, voxels.combust,
                                                 voxels.burning)
    body_pos, body_rot, body_com = bodies.pos, bodies.rot, bodies.com
    ignited = 0
    centre = np.empty(3)
    for v in range(voxel_centroid.shape[0]):
        if not voxel_alive[v] or burning[v] or not math.isfinite(combust[v]):
            continue
        b = voxel_body[v]
        if not active[b]:
            continue
        rot = body_rot[b]
        for a in range(3):
            centre[a] = (body_pos[b, a] + rot[a, 0] * (voxel_centroid[v, 0] - body_com[b, 0])
                         + rot[a, 1] * (voxel_centroid[v, 1] - body_com[b, 1])
                         + rot[a, 2] * (voxel_centroid[v, 2] - body_com[b, 2]))
        for c in range(charge_pos.shape[0]):
            r = math.sqrt((centre[0] - charge_pos[c, 0]) ** 2 + (centre[1] - charge_pos[c, 1]) ** 2
                          + (centre[2] - charge_pos[c, 2]) ** 2)
            if r <= front_in[c] or r > front_out[c]:
                continue
            combust[v] -= scale * peak_overpressure(table[front.burst[c]], r, charge_scale[c])
            if combust[v] < 0.0:
                burning[v] = True
                ignited += 1
                break
    return ignited


@kernel
def burn(params, model_voxels, model_links, voxels, links, initial, body_rot, marks,
         ignite_scratch) -> int:
    """One step of burning and spreading; returns the number of burning voxels.

    params: :class:`FireParams`; initial: (voxel yields (N,), link yields (L,)) at
    the start of the run, Pa (burning takes burn_rate of them per second);
    ignite_scratch (N,) bool work array."""
    dt, burn_rate, fire_spread = params.dt, params.burn_rate, params.spread
    side_factor, up = params.side_factor, params.up
    voxel_alive, voxel_body, voxel_yield = voxels.alive, voxels.body, voxels.yield_pa
    combust, burning = voxels.combust, voxels.burning
    initial_voxel_yield, initial_link_yield = initial
    voxel_link_offsets, voxel_link_ids = model_voxels.link_offsets, model_voxels.link_ids
    link_voxels, link_direction = model_links.voxels, model_links.direction
    link_alive, link_yield = links.alive, links.yield_pa
    broken, destroyed, dirty = marks.broken, marks.destroyed, marks.dirty
    n_burning = 0
    for v in range(voxel_alive.shape[0]):
        ignite_scratch[v] = False
    for v in range(voxel_alive.shape[0]):
        if not burning[v] or not voxel_alive[v]:
            continue
        n_burning += 1
        b = voxel_body[v]
        if math.isfinite(initial_voxel_yield[v]):
            voxel_yield[v] -= burn_rate * initial_voxel_yield[v] * dt
            if voxel_yield[v] <= 0.0:
                voxel_alive[v] = False
                destroyed[v] = True
                dirty[b] = True
                continue
        rot = body_rot[b]
        for k in range(voxel_link_offsets[v], voxel_link_offsets[v + 1]):
            link = voxel_link_ids[k]
            if not link_alive[link]:
                continue
            if math.isfinite(initial_link_yield[link]):
                link_yield[link] -= burn_rate * initial_link_yield[link] * dt
                if link_yield[link] <= 0.0:
                    link_alive[link] = False
                    broken[link] = True
                    dirty[b] = True
                    continue
            w = link_voxels[link, 1]
            sign = 1.0
            if w == v:
                w = link_voxels[link, 0]
                sign = -1.0
            if burning[w] or not voxel_alive[w] or not math.isfinite(combust[w]):
                continue
            # world direction from v to w, against up
            rise = 0.0
            for a in range(3):
                d = (rot[a, 0] * link_direction[link, 0] + rot[a, 1] * link_direction[link, 1]
                     + rot[a, 2] * link_direction[link, 2])
                rise += sign * d * up[a]
            factor = side_factor + (1.0 - side_factor) * max(0.0, rise)
            combust[w] -= fire_spread * factor * dt
            if combust[w] < 0.0:
                ignite_scratch[w] = True
    for v in range(voxel_alive.shape[0]):
        if ignite_scratch[v]:
            burning[v] = True
    return n_burning


@dataclass
class Fire:
    """What fire remembers over a run: ignite_frame (N,) int32, the first output frame
    at which each voxel burns (-1 never); burning, voxels burning now; initial:
    (voxel yields (N,), link yields (L,)) Pa at the start; scratch (N,) bool."""

    ignite_frame: np.ndarray
    initial: tuple[np.ndarray, np.ndarray]
    scratch: np.ndarray
    burning: int = 0

    @classmethod
    def start(cls, state) -> Fire:
        n = len(state.voxels.alive)
        return cls(np.full(n, -1, dtype=np.int32),
                   (state.voxels.yield_pa.copy(), state.links.yield_pa.copy()),
                   np.zeros(n, dtype=bool))


def ignite_phase(model, state, fire: Fire, front, settings, frame_next: int) -> None:
    """Phase: waves crossing combustible voxels this step may set them alight.

    Reads the front and the bodies' poses; writes voxels.combust and burning, and
    the ignition frames."""
    burning = state.voxels.burning
    was = burning.copy()
    n = ignite_by_blast(front, settings.fire_pressure_scale, model.voxels.centroid,
                        state.voxels, state.bodies, state.marks.active)
    if n:
        fire.ignite_frame[burning & ~was] = frame_next
        fire.burning += int(n)


def burn_phase(model, state, fire: Fire, settings, dt: float, frame_next: int) -> None:
    """Phase: one step of burning and spreading (see the module docstring).

    Writes voxels (yield, alive, combust, burning), links (yield, alive) and
    marks (broken, destroyed, dirty; cleared first): a caller then splits."""
    s, marks = settings, state.marks
    burning = state.voxels.burning
    was = burning.copy()
    marks.broken[:] = False
    marks.destroyed[:] = False
    marks.dirty[:state.n_bodies] = False
    params = FireParams(dt, s.burn_rate, s.fire_spread, s.fire_side_factor, model.up)
    fire.burning = burn(params, model.voxels, model.links, state.voxels, state.links,
                        fire.initial, state.bodies.rot, marks, fire.scratch)
    fire.ignite_frame[burning & ~was] = frame_next
    state.counters.broken_links += int(marks.broken.sum())
