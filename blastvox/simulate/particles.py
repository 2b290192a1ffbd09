"""Particles: cheap ballistic points with drag and a lifetime, stored as spawn events.

A particle never collides, so its motion has a closed form. With linear drag
k (1/s) and acceleration a (gravity times the system's ``gravity_scale``;
negative for buoyant smoke and fire):

    x(t) = x0 + v0 (1 - e^(-k s)) / k + a (s - (1 - e^(-k s)) / k) / k,   s = t - t0

so a SimCache stores only each particle's birth (time, position, velocity,
lifetime, size, system) and export evaluates positions at any frame exactly
(:func:`positions_at`). Each system has a particle budget set by the scene;
emission beyond it is dropped (first come, first kept), and each system draws
from its own seeded random stream, so switching one effect off leaves the
others' particles unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class SystemSpec:
    """Behaviour of one particle system: drag (1/s), gravity_scale (-), lifetime (s), size (m)."""

    drag: float
    gravity_scale: float
    lifetime: float
    size: float


SYSTEMS: dict[str, SystemSpec] = {
    "dust": SystemSpec(drag=1.5, gravity_scale=0.3, lifetime=4.0, size=0.15),
    "fire": SystemSpec(drag=3.0, gravity_scale=-0.4, lifetime=0.8, size=0.25),
    "smoke": SystemSpec(drag=1.0, gravity_scale=-0.15, lifetime=4.0, size=0.6),
    "fireball": SystemSpec(drag=4.0, gravity_scale=-0.3, lifetime=1.2, size=0.8),
}
SYSTEM_NAMES = tuple(SYSTEMS)


def particle_meta() -> list[dict]:
    """The systems as stored in a SimCache's meta (index = particle_system value)."""
    return [{"name": n, "drag_per_s": s.drag, "gravity_scale": s.gravity_scale,
             "lifetime_s": s.lifetime, "size_m": s.size} for n, s in SYSTEMS.items()]


@dataclass
class Emitter:
    """Collects spawn events during a run, within per-system budgets."""

    budgets: dict[str, int]
    seed: int
    _parts: dict[str, list[tuple]] = field(default_factory=dict)
    _count: dict[str, int] = field(default_factory=dict)
    _rng: dict[str, np.random.Generator] = field(default_factory=dict)

    def rng(self, system: str) -> np.random.Generator:
        """The system's own random stream (independent of the other systems)."""
        if system not in self._rng:
            index = SYSTEM_NAMES.index(system)
            self._rng[system] = np.random.default_rng([self.seed, 7919, index])
        return self._rng[system]

    def room(self, system: str) -> int:
        return max(0, self.budgets.get(system, 0) - self._count.get(system, 0))

    def emit(self, system: str, time: float, positions: np.ndarray, velocities: np.ndarray,
             size_scale: np.ndarray | float = 1.0) -> int:
        """Spawn particles (K, 3) at ``time`` (s); returns how many fit in the budget."""
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        keep = min(len(positions), self.room(system))
        if keep <= 0:
            return 0
        spec = SYSTEMS[system]
        sizes = np.broadcast_to(np.asarray(size_scale, dtype=np.float64) * spec.size,
                                (len(positions),))[:keep]
        self._parts.setdefault(system, []).append(
            (np.full(keep, time), positions[:keep], np.asarray(velocities).reshape(-1, 3)[:keep],
             sizes))
        self._count[system] = self._count.get(system, 0) + keep
        return keep

    def arrays(self) -> dict[str, np.ndarray]:
        """SimCache arrays ``particle_*`` (system order, then emission order)."""
        birth, pos, vel, size, system = [], [], [], [], []
        for index, name in enumerate(SYSTEM_NAMES):
            for t, p, v, s in self._parts.get(name, []):
                birth.append(t)
                pos.append(p)
                vel.append(v)
                size.append(s)
                system.append(np.full(len(t), index, dtype=np.uint8))
        if not birth:
            return {"particle_system": np.zeros(0, np.uint8), "particle_birth": np.zeros(0),
                    "particle_position": np.zeros((0, 3)), "particle_velocity": np.zeros((0, 3)),
                    "particle_size": np.zeros(0, np.float32)}
        return {"particle_system": np.concatenate(system),
                "particle_birth": np.concatenate(birth),
                "particle_position": np.concatenate(pos),
                "particle_velocity": np.concatenate(vel),
                "particle_size": np.concatenate(size).astype(np.float32)}


def positions_at(birth: np.ndarray, position: np.ndarray, velocity: np.ndarray,
                 system: np.ndarray, time: float, gravity: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Alive particles at ``time``: (indices (K,), positions (K, 3) m).

    gravity: (3,) m/s^2 in the same frame as the positions.
    """
    lifetime = np.array([SYSTEMS[n].lifetime for n in SYSTEM_NAMES])[system]
    age = time - birth
    alive = np.flatnonzero((age >= 0.0) & (age < lifetime))
    s = age[alive][:, None]
    k = np.array([SYSTEMS[n].drag for n in SYSTEM_NAMES])[system[alive]][:, None]
    g = np.array([SYSTEMS[n].gravity_scale for n in SYSTEM_NAMES])[system[alive]][:, None]
    decay = -np.expm1(-k * s) / k  # (1 - e^-ks) / k
    accel = g * np.asarray(gravity)[None, :]
    x = position[alive] + velocity[alive] * decay + accel * (s - decay) / k
    return alive, x
