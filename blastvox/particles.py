"""Particles: cheap ballistic points with drag and a lifetime, stored as spawn events.

A particle never collides, so its motion has a closed form. With linear drag
k (1/s) and acceleration a (gravity times the system's ``gravity_scale``;
negative for buoyant smoke and fire):

    x(t) = x0 + v0 (1 - e^(-k s)) / k + a (s - (1 - e^(-k s)) / k) / k,   s = t - t0

so a SimCache stores only each particle's birth (time, position, velocity,
lifetime, size, system) and export evaluates positions at any frame exactly
(:func:`positions_at`). One exception to "never collides": a particle that reaches
the ground stays on it (its height along up is held at the ground's, its motion
across the ground goes on), so dust settles instead of sinking through the floor.
Each system has a particle budget set by the scene; emission beyond it is
dropped (first come, first kept), and each system draws from its own seeded
random stream, so switching one effect off leaves the others' particles unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blastvox.geometry import exact


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


def positions_at(birth: np.ndarray, position: np.ndarray, velocity: np.ndarray,
                 system: np.ndarray, time: float, gravity: np.ndarray,
                 ground: tuple[np.ndarray, float] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Alive particles at ``time``: (indices (K,), positions (K, 3) m).

    gravity: (3,) m/s^2 in the same frame as the positions; ground: (up (3,) unit
    vector, height m along it) in that frame, or None (no ground: see
    :func:`ground_plane`).
    """
    alive, x = all_positions_at(birth, position, velocity, system, time, gravity, ground)
    return np.flatnonzero(alive), x[alive]


def ground_plane(ground_height: float | None, up: np.ndarray,
                 change: np.ndarray | None = None) -> tuple[np.ndarray, float] | None:
    """The ``ground`` argument of :func:`positions_at` from a SimCache's
    ``meta["ground_height"]`` (m along the model's ``up`` (3,), None: no ground), in the
    frame ``change`` (3, 3) rotates model vectors into (the model's own if None)."""
    if ground_height is None:
        return None
    up = np.asarray(up, dtype=np.float64)
    if change is not None:
        up = exact.matvec(change, up)
    return up / exact.norm(up), float(ground_height)

def all_positions_at(birth: np.ndarray, position: np.ndarray, velocity: np.ndarray,
                     system: np.ndarray, time: float, gravity: np.ndarray,
                     ground: tuple[np.ndarray, float] | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Every particle at ``time``: (alive (P,) bool, positions (P, 3) m), an unborn one
    at its birth position and a dead one where it died (the motion of
    :func:`positions_at` at its age clamped to [0, lifetime]; the alive ones' positions
    are the same numbers)."""
    lifetime = np.array([SYSTEMS[n].lifetime for n in SYSTEM_NAMES])[system]
    age = time - birth
    alive = (age >= 0.0) & (age < lifetime)
    s = np.clip(age, 0.0, lifetime)[:, None]
    k = np.array([SYSTEMS[n].drag for n in SYSTEM_NAMES])[system][:, None]
    g = np.array([SYSTEMS[n].gravity_scale for n in SYSTEM_NAMES])[system][:, None]
    from blastvox.geometry import fixed  # libm's: numpy's rounds as its CPU dispatch

    decay = -fixed.expm1(-k * s) / k  # (1 - e^-ks) / k
    accel = g * np.asarray(gravity)[None, :]
    x = position + velocity * decay + accel * (s - decay) / k
    if ground is not None:
        up, height = ground
        below = np.minimum(exact.dot(x, up) - height, 0.0)  # (P,) m under it, or 0
        x = x - below[:, None] * up[None, :]
    return alive, x
