"""Particle emission during a run, within per-system budgets (the model and the
closed-form motion are the SimCache contract's: :mod:`blastvox.particles`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from blastvox.particles import SYSTEM_NAMES, SYSTEMS


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
