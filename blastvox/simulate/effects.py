"""Particle effects of a run (Martins 2001 §6): dust, fireballs, flames and smoke.

Each effect emits spawn events into an :class:`~blastvox.simulate.particles.Emitter`
(the closed-form motion is the SimCache contract's, :mod:`blastvox.particles`).
Effects read the state and never change it, so switching one off changes no
motion; each system draws from its own seeded stream.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.blast._numeric import cbrt, libm
from blastvox.simulate.particles import Emitter


class Effects:
    """The particle emitters of one run, and what they remember between steps."""

    def __init__(self, budgets: dict[str, int], seed: int, n_charges: int) -> None:
        self.emitter = Emitter(dict(budgets), seed)
        self.ring_done = np.zeros(n_charges, dtype=bool)

    def voxel_dust(self, model, state, voxels: np.ndarray, t: float) -> None:
        """Destroyed voxels (ids (K,)) burst into dust that carries their momentum."""
        per = 6
        rng = self.emitter.rng("dust")
        bodies = state.bodies
        b = state.voxels.body[voxels]
        velocity = bodies.lin[b] / bodies.mass[b][:, None]
        centre = world_centres(model, state, voxels)
        mass = model.voxels.mass
        size = cbrt(mass[voxels] / np.maximum(mass.max(), 1e-30))
        pos = np.repeat(centre, per, axis=0) + rng.normal(0.0, 0.2, (len(voxels) * per, 3)) \
            * np.repeat(2 * model.voxels.contact_radius[voxels], per)[:, None]
        vel = np.repeat(velocity, per, axis=0) + rng.normal(0.0, 1.0, (len(voxels) * per, 3))
        self.emitter.emit("dust", t, pos, vel, np.repeat(size, per))

    def collision_dust(self, model, hits: np.ndarray, t: float) -> None:
        """Impacts above 2 m/s raise dust (hits (K, 4): point, m, and approach speed, m/s);
        resting contacts don't."""
        if hits[:, 3].max() <= 2.0 or not self.emitter.room("dust"):
            return
        strong = hits[hits[:, 3] > 2.0]
        if len(strong):
            rng = self.emitter.rng("dust")
            vel = rng.normal(0.0, 1.0, (len(strong), 3)) + 2.0 * model.up
            self.emitter.emit("dust", t, strong[:, :3], vel)

    def shock_dust(self, model, state, charges, t: float) -> None:
        """Dust knocked off the exposed voxels the shock front crossed this step."""
        v = state.voxels
        voxels = np.flatnonzero(state.marks.crossed & v.alive & (v.link_mask != 0x3F))
        if not voxels.size or not self.emitter.room("dust"):
            return
        rng = self.emitter.rng("dust")
        pick = voxels[rng.random(len(voxels)) < 0.25]
        if not pick.size:
            return
        centre = world_centres(model, state, pick)
        away = centre - charges.position[np.argmin(
            np.linalg.norm(centre[:, None, :] - charges.position[None], axis=2), axis=1)]
        away /= np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-9)
        self.emitter.emit("dust", t, centre, 3.0 * away + rng.normal(0.0, 0.5, away.shape))

    def ground_ring(self, model, charges, ground: float, t: float, front_out: np.ndarray,
                    dt: float) -> None:
        """Dust kicked up where the shock sphere meets the ground (while it is strong)."""
        up, axis = model.up, model.up_axis
        others = [a for a in range(3) if a != axis]
        rng = self.emitter.rng("dust")
        for c in range(len(charges.tnt_kg)):
            height = charges.position[c, axis] - ground
            r = front_out[c]
            if self.ring_done[c] or r <= abs(height) or not self.emitter.room("dust"):
                continue
            if charges.peak(c, r) < 2e3:  # below 2 kPa the wave raises no dust
                self.ring_done[c] = True  # and the front only weakens from here
                continue
            ring = np.sqrt(r * r - height * height)
            # about min(64, 4 + ring) particles per 1/240 s whatever the step
            count = int(rng.poisson(min(64.0, 4.0 + ring) * dt * 240.0))
            if count == 0:
                continue
            angle = rng.uniform(0.0, 2 * np.pi, count)
            pos = np.repeat(charges.position[c:c + 1], count, axis=0)
            pos[:, axis] = ground
            cos, sin = libm(math.cos, angle), libm(math.sin, angle)
            pos[:, others[0]] += ring * cos
            pos[:, others[1]] += ring * sin
            out = np.zeros((count, 3))
            out[:, others[0]] = cos
            out[:, others[1]] = sin
            self.emitter.emit("dust", t, pos, 4.0 * out + 2.0 * up[None, :])

    def fireball(self, charges, t0: float, t1: float) -> None:
        """A burst of flame particles at each charge when it goes off."""
        rng = self.emitter.rng("fireball")
        for c in range(len(charges.tnt_kg)):
            if not (t0 < charges.time[c] <= t1) and not (t0 == 0 == charges.time[c]):
                continue
            count = 200
            radius = 1.5 * charges.scale[c]  # visible fireball ~ 1.5 W^(1/3) m
            direction = rng.normal(size=(count, 3))
            direction /= np.linalg.norm(direction, axis=1, keepdims=True)
            speed = radius * 4.0 * rng.uniform(0.6, 1.0, count)  # drag 4/s stops it at ~radius
            pos = charges.position[c] + 0.1 * radius * direction
            self.emitter.emit("fireball", charges.time[c], pos, direction * speed[:, None],
                              charges.scale[c])

    def flames(self, model, state, t: float, dt: float) -> None:
        """Fire and smoke from burning voxels: on average 4 flames and 1 smoke puff a second."""
        v = state.voxels
        burning = np.flatnonzero(v.burning & v.alive)
        if not burning.size:
            return
        for system, rate in (("fire", 4.0), ("smoke", 1.0)):
            rng = self.emitter.rng(system)
            pick = burning[rng.random(len(burning)) < rate * dt]
            if pick.size and self.emitter.room(system):
                centre = world_centres(model, state, pick)
                vel = rng.normal(0.0, 0.3, (len(pick), 3)) + model.up * 0.5
                self.emitter.emit(system, t, centre, vel)


def world_centres(model, state, voxels: np.ndarray) -> np.ndarray:
    """World centroids (K, 3) m of voxels (K,) at the bodies' poses (bodies.rot current)."""
    bodies = state.bodies
    b = state.voxels.body[voxels]
    rot = bodies.rot[b]
    rel = model.voxels.centroid[voxels] - bodies.com[b]
    return bodies.pos[b] + np.einsum("kij,kj->ki", rot, rel)
