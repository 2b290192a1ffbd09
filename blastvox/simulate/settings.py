"""Run settings and charges, from a scene and/or command-line overrides."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ChargeSpec:
    """A charge: ``mass_kg`` of ``explosive`` at ``position`` (m), detonated at ``time_s``;
    burst: "air", "surface" or "auto" (surface when near the ground, see
    :func:`blastvox.simulate.wave.build_charges`)."""

    position: tuple[float, float, float]
    mass_kg: float
    explosive: str = "TNT"
    time_s: float = 0.0
    burst: str = "auto"


@dataclass(frozen=True)
class SimSettings:
    """Integrator and physics settings (see :class:`blastvox.scene.Simulation`).

    ground: False means no ground at all: foundation voxels are ignored, so
    founded structures float free, and no ground plane. collisions: fragments
    collide with each other. friction: Coulomb mu at the ground; rest_damping:
    1/s decay of momenta in resting ground contact; sleep_speed: m/s below which
    a balanced resting body is clamped to rest.
    fire, dust, fireball, shock_sphere, camera_shake: effects on/off (an effect
    that is off costs nothing); fire_*/burn_rate: see blastvox.simulate.fire;
    budgets: particles per system; camera: (position, look_at, focal mm).
    """

    dt: float = 1.0 / 240.0
    fps: float = 24.0
    duration: float = 5.0
    fracture: str = "pressure-impulse"
    gravity: float = 9.81
    linear_drag: float = 0.0
    angular_drag: float = 0.0
    weakening: float = 0.5
    orientation_factor: float = 0.5
    damage_b: float = 0.1
    damage_c: float = 0.05
    seed: int = 0
    ground: bool = True
    collisions: bool = True
    friction: float = 0.6
    rest_damping: float = 5.0
    sleep_speed: float = 0.05
    fire: bool = True
    dust: bool = True
    fireball: bool = True
    shock_sphere: bool = True
    camera_shake: bool = True
    fire_pressure_scale: float = 1.0
    fire_spread: float = 20_000.0
    burn_rate: float = 0.05
    fire_side_factor: float = 0.2
    budgets: tuple[tuple[str, int], ...] = (("dust", 20_000), ("fire", 10_000),
                                            ("smoke", 10_000), ("fireball", 2_000))
    camera: tuple[tuple[float, float, float], tuple[float, float, float], float] | None = None
    charges: tuple[ChargeSpec, ...] = field(default_factory=tuple)

    def steps_per_frame(self) -> int:
        """Whole steps per output frame; dt is shortened to divide the frame interval."""
        return max(1, math.ceil(1.0 / (self.fps * self.dt) - 1e-9))

    def step_seconds(self) -> float:
        """The step actually used, s: 1 / (fps x steps_per_frame), never above dt."""
        return 1.0 / (self.fps * self.steps_per_frame())

    def frame_count(self) -> int:
        """Output frames, the first at t = 0 and the last at or before ``duration``."""
        return int(math.floor(self.duration * self.fps + 1e-9)) + 1

    def to_dict(self) -> dict:
        d = {k: getattr(self, k) for k in ("dt", "fps", "duration", "fracture", "gravity",
                                           "linear_drag", "angular_drag", "weakening",
                                           "orientation_factor", "damage_b", "damage_c", "seed",
                                           "ground", "collisions", "friction", "rest_damping",
                                           "sleep_speed", "fire", "dust",
                                           "fireball", "shock_sphere", "camera_shake",
                                           "fire_pressure_scale", "fire_spread", "burn_rate",
                                           "fire_side_factor")}
        d["budgets"] = dict(self.budgets)
        d["camera"] = None if self.camera is None else {
            "position": list(self.camera[0]), "look_at": list(self.camera[1]),
            "focal_length_mm": self.camera[2]}
        d["charges"] = [{"position": list(c.position), "mass_kg": c.mass_kg,
                         "explosive": c.explosive, "time_s": c.time_s, "burst": c.burst}
                        for c in self.charges]
        return d


def settings_from_scene(scene) -> SimSettings:
    """SimSettings from a validated :class:`blastvox.scene.Scene`."""
    s = scene.simulation
    charges = tuple(ChargeSpec(tuple(c.position), c.mass_kg, c.explosive, c.time_s, c.burst)
                    for c in scene.charges)
    return SimSettings(dt=s.dt, fps=s.fps, duration=s.duration, fracture=s.fracture,
                       gravity=s.gravity, linear_drag=s.linear_drag, angular_drag=s.angular_drag,
                       weakening=s.weakening, orientation_factor=s.orientation_factor,
                       damage_b=s.damage_b, damage_c=s.damage_c, seed=scene.seed,
                       ground=scene.effects.ground and scene.ground != "none",
                       collisions=scene.effects.collisions, fire=scene.effects.fire,
                       dust=scene.effects.dust, fireball=scene.effects.fireball,
                       shock_sphere=scene.effects.shock_sphere,
                       camera_shake=scene.effects.camera_shake, friction=s.friction,
                       fire_pressure_scale=s.fire_pressure_scale, fire_spread=s.fire_spread,
                       burn_rate=s.burn_rate,
                       budgets=tuple((k, getattr(scene.particles, k))
                                     for k in ("dust", "fire", "smoke", "fireball")),
                       camera=None if scene.camera is None else (
                           tuple(scene.camera.position), tuple(scene.camera.look_at),
                           scene.camera.focal_length_mm),
                       charges=charges)


def gravity_vector(up: np.ndarray, gravity: float) -> np.ndarray:
    """(3,) m/s^2 pointing down the model's up axis."""
    return -gravity * np.asarray(up, dtype=np.float64)
