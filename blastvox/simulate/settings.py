"""Run settings and charges, from a scene and/or command-line overrides; their bounds and
the run's budgets.

:func:`check_settings` refuses, before a run allocates or loops, every setting outside
its documented bound (:data:`BOUNDS`, :mod:`blastvox.bounds`) and a run over its
:class:`Budget` (steps, frames, particles), with one line naming where the value came
from (a flag, a scene file's key: :class:`Origin`), the value, the limit and the flag
that raises it. :func:`blastvox.simulate.engine.simulate` calls it, so the CLI's
``simulate`` and ``run`` and Python callers all get it; the memory of the recorded
frames is checked as the run goes (:func:`check_record_memory`), once the piece count
is known.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from blastvox.bounds import (
    CHARGE_KG,
    CHARGE_TIME_S,
    CONTACT_SUBSTEPS,
    COORDINATE,
    MAX_FRAMES,
    MAX_MEMORY_GIB,
    MAX_PARTICLES,
    MAX_STEPS,
    SEED,
    Bound,
    check_count,
    fmt,
)
from blastvox.errors import BlastvoxError, BudgetError

#: Bytes recorded per piece and output frame: the live bodies' transforms during the run
#: (index, position, orientation, centre of mass: 88 B) and the pieces' float64 and
#: float32 transforms packed at the end (84 B).
RECORD_BYTES_PER_PIECE_FRAME = 88 + 84
#: Relative slack of "dt divides the frame interval": a dt typed with a few digits
#: too few (0.0020833333 for 1/480 s) is taken as the step it rounds.
DT_ROUNDING = 1e-6


@dataclass(frozen=True)
class Budget:
    """How much a run may take, checked before it allocates or loops (see the module doc).

    max_steps: fixed steps (about duration / dt); max_frames: output frames (duration x
    fps + 1); max_particles: the particle budgets of all systems together;
    max_memory_gib: the run's memory: its arrays, estimated from the model's voxels,
    links and charges before it starts, and the recorded frames (pieces x frames,
    checked as pieces appear). The CLI's --max-steps, --max-frames, --max-particles and --max-memory
    raise them.
    """

    max_steps: int = MAX_STEPS
    max_frames: int = MAX_FRAMES
    max_particles: int = MAX_PARTICLES
    max_memory_gib: float = MAX_MEMORY_GIB


@dataclass(frozen=True)
class Origin:
    """Where settings came from, to name them in errors: ``source`` (a scene or model
    file) and what each setting is called there (a flag such as ``--dt``, a scene key
    such as ``simulation.dt``); a setting not named is called by its field name."""

    source: str = "SimSettings"
    names: tuple[tuple[str, str], ...] = ()

    def name(self, key: str) -> str:
        """What ``key`` (a SimSettings field, ``charges``, ``particles``) is called."""
        return dict(self.names).get(key, key)

    def renamed(self, names: Mapping[str, str], source: str | None = None) -> Origin:
        """This origin with ``names`` (and ``source``) replacing those it had."""
        merged = dict(self.names) | dict(names)
        return Origin(self.source if source is None else source, tuple(merged.items()))


#: Documented bounds of the numeric settings (docs/user-guide.md, "Limits and exit codes").
#: dt >= 1 ns and 0.001 <= fps <= 1e6 keep the steps per frame a small whole number; the
#: duration is bounded by the budgets; gravity <= 1000 m/s^2 (about 100 g) and charge
#: times <= 1e9 s keep every speed and position finite.
BOUNDS: dict[str, Bound] = {
    "dt": Bound(1e-9, unit="s"),
    "fps": Bound(1e-3, 1e6, unit="frames/s"),
    "duration": Bound(0.0, lo_open=True, unit="s"),
    "gravity": Bound(0.0, 1000.0, unit="m/s^2"),
    "linear_drag": Bound(0.0, unit="1/s"),
    "angular_drag": Bound(0.0, unit="1/s"),
    "weakening": Bound(0.0, 1.0),
    "orientation_factor": Bound(0.0, 1.0),
    "damage_b": Bound(0.0),
    "damage_c": Bound(0.0, unit="1/(Pa s)"),
    "friction": Bound(0.0),
    "rest_damping": Bound(0.0, unit="1/s"),
    "sleep_speed": Bound(0.0, unit="m/s"),
    "contact_substeps": CONTACT_SUBSTEPS,
    "fire_pressure_scale": Bound(0.0),
    "fire_spread": Bound(0.0, unit="Pa/s"),
    "burn_rate": Bound(0.0, unit="1/s"),
    "fire_side_factor": Bound(0.0),
}


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
    a balanced resting body is clamped to rest; contact_substeps: sub-steps of the
    contact solver a step (see :mod:`blastvox.simulate.contact.solver`).
    fire, stress, dust, fireball, shock_sphere, camera_shake: effects on/off (an effect
    that is off costs nothing); fire_*/burn_rate: see blastvox.simulate.fire;
    budgets: particles per system; camera: (position, look_at, focal mm).
    budget: the run's resource :class:`Budget`; origin: where the values came from, for
    error messages (:class:`Origin`). Neither is recorded in the SimCache.
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
    contact_substeps: int = 4
    fire: bool = True
    stress: bool = True
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
    budget: Budget = field(default_factory=Budget, compare=False)
    origin: Origin = field(default_factory=Origin, compare=False)

    def steps_per_frame(self) -> int:
        """Whole steps per output frame; dt is shortened to divide the frame interval. A dt
        within a millionth of dividing it does (0.0020833333 s, 1/480 s typed to ten
        places, is 4 steps of a 1/120 s frame, not 5)."""
        return max(1, math.ceil(1.0 / (self.fps * self.dt) * (1.0 - DT_ROUNDING)))

    def step_seconds(self) -> float:
        """The step actually used, s: 1 / (fps x steps_per_frame), never above dt by more
        than DT_ROUNDING."""
        return 1.0 / (self.fps * self.steps_per_frame())

    def frame_count(self) -> int:
        """Output frames, the first at t = 0 and the last at or before ``duration``."""
        return int(math.floor(self.duration * self.fps + 1e-9)) + 1

    def to_dict(self) -> dict:
        d = {k: getattr(self, k) for k in ("dt", "fps", "duration", "fracture", "gravity",
                                           "linear_drag", "angular_drag", "weakening",
                                           "orientation_factor", "damage_b", "damage_c", "seed",
                                           "ground", "collisions", "friction", "rest_damping",
                                           "sleep_speed", "contact_substeps", "fire",
                                           "stress", "dust",
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


#: What a scene calls each setting (its keys, as scene errors name them).
SCENE_NAMES = {**{k: f"simulation.{k}" for k in BOUNDS}, "seed": "seed", "charges": "charges",
               "budgets": "particles"}


def settings_from_scene(scene, source: str = "the scene", budget: Budget | None = None
                        ) -> SimSettings:
    """SimSettings from a validated :class:`blastvox.scene.Scene`; ``source`` names the
    scene file in errors (see :class:`Origin`); ``budget``: the run's (default
    :class:`Budget`). Bounds and budgets are checked by :func:`check_settings` (the
    engine calls it), after any overrides."""
    s = scene.simulation
    charges = tuple(ChargeSpec(tuple(c.position), c.mass_kg, c.explosive, c.time_s, c.burst)
                    for c in scene.charges)
    return SimSettings(dt=s.dt, fps=s.fps, duration=s.duration, fracture=s.fracture,
                       gravity=s.gravity, linear_drag=s.linear_drag, angular_drag=s.angular_drag,
                       weakening=s.weakening, orientation_factor=s.orientation_factor,
                       damage_b=s.damage_b, damage_c=s.damage_c, seed=scene.seed,
                       ground=scene.effects.ground and scene.ground != "none",
                       collisions=scene.effects.collisions, fire=scene.effects.fire,
                       stress=scene.effects.stress,
                       dust=scene.effects.dust, fireball=scene.effects.fireball,
                       shock_sphere=scene.effects.shock_sphere,
                       camera_shake=scene.effects.camera_shake, friction=s.friction,
                       contact_substeps=s.contact_substeps,
                       fire_pressure_scale=s.fire_pressure_scale, fire_spread=s.fire_spread,
                       burn_rate=s.burn_rate,
                       budgets=tuple((k, getattr(scene.particles, k))
                                     for k in ("dust", "fire", "smoke", "fireball")),
                       camera=None if scene.camera is None else (
                           tuple(scene.camera.position), tuple(scene.camera.look_at),
                           scene.camera.focal_length_mm),
                       charges=charges, budget=budget or Budget(),
                       origin=Origin(str(source), tuple(SCENE_NAMES.items())))


def check_seed(value: object, name: str = "--seed", source: str | None = None) -> int:
    """A seed: a whole number 0 .. 2**64 - 1, else a one-line BlastvoxError."""
    return SEED.named(int(value) if isinstance(value, np.integer) else value, name, source)


def _count(value: float) -> str:
    """A count for messages: 1,234,567 up to ten million, then 2.4e+14."""
    if not math.isfinite(value):
        return "over 1e+308"
    return f"{int(value):,}" if value < 1e7 else f"{value:.3g}"


def check_bounds(settings: SimSettings) -> None:
    """Every numeric setting, the seed and the charges within their bounds (:data:`BOUNDS`,
    :mod:`blastvox.bounds`), else one BlastvoxError line naming it (see :class:`Origin`)."""
    origin = settings.origin
    for key, bound in BOUNDS.items():
        bound.named(getattr(settings, key), origin.name(key), origin.source)
    check_seed(settings.seed, origin.name("seed"), origin.source)
    charges = origin.name("charges")
    for i, c in enumerate(settings.charges):
        CHARGE_KG.named(c.mass_kg, f"{charges}[{i}].mass_kg", origin.source)
        CHARGE_TIME_S.named(c.time_s, f"{charges}[{i}].time_s", origin.source)
        if len(c.position) != 3:
            raise BlastvoxError(f"{origin.source}: {charges}[{i}].position must be X, Y, Z")
        for axis, value in zip("xyz", c.position, strict=True):
            COORDINATE.named(value, f"{charges}[{i}].position {axis}", origin.source)


def run_size(settings: SimSettings) -> tuple[float, float]:
    """(output frames, fixed steps) of a run as numbers that may be huge or infinite (never
    an overflow): :meth:`SimSettings.frame_count` and (frames - 1) x
    :meth:`SimSettings.steps_per_frame`, for any positive dt, fps and duration."""
    span = settings.duration * settings.fps
    frames = float(math.floor(span + 1e-9) + 1) if span < 1e18 else span
    if frames <= 1.0:
        return frames, 0.0
    rate = settings.fps * settings.dt  # frames per step
    per_frame = 1.0 / rate if rate > 0.0 else math.inf
    per_frame = max(1.0, math.ceil(per_frame - 1e-9)) if per_frame < 1e18 else per_frame
    return frames, (frames - 1.0) * per_frame


def _check_budget_values(budget: Budget, where: str) -> None:
    for key, low in (("max_steps", 1), ("max_frames", 1), ("max_particles", 0)):
        check_count(getattr(budget, key), "--" + key.replace("_", "-"), low, where)
    Bound(0.0, lo_open=True, unit="GiB").named(budget.max_memory_gib, "--max-memory", where)


def check_budget(settings: SimSettings) -> None:
    """The run's frames, steps and particle budgets within ``settings.budget``, else one
    :class:`~blastvox.errors.BudgetError` line naming the values, the limit and the flag
    that raises it. Needs positive, finite dt, fps and duration (any size)."""
    origin, budget = settings.origin, settings.budget
    where, name = origin.source, origin.name
    _check_budget_values(budget, where)
    frames, steps = run_size(settings)
    if steps > budget.max_steps:
        pace = (f"{name('dt')} {fmt(settings.dt)} s" if steps > frames - 1 else
                f"{name('fps')} {fmt(settings.fps)} frames/s (one step per frame)")
        raise BudgetError(
            f"{where}: {name('duration')} {fmt(settings.duration)} s at {pace} is "
            f"{_count(steps)} steps, over the limit of {budget.max_steps:,} (raise it with "
            f"--max-steps)")
    if frames > budget.max_frames:
        raise BudgetError(
            f"{where}: {name('duration')} {fmt(settings.duration)} s at {name('fps')} "
            f"{fmt(settings.fps)} frames/s is {_count(frames)} frames, over the limit of "
            f"{budget.max_frames:,} (raise it with --max-frames)")
    particles = name("budgets")
    total = 0
    for system, count in settings.budgets:
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise BlastvoxError(f"{where}: {particles}.{system} {count!r} must be a whole "
                                f"number >= 0")
        total += int(count)
    if total > budget.max_particles:
        parts = " + ".join(f"{system} {_count(count)}" for system, count in settings.budgets)
        raise BudgetError(
            f"{where}: {particles}: the particle budgets total {_count(total)} ({parts}), over "
            f"the limit of {budget.max_particles:,} (raise it with --max-particles)")


def check_settings(settings: SimSettings) -> None:
    """What a run refuses before it allocates anything: a dt, fps or duration that is not a
    positive number, then a run over its budget (:func:`check_budget`: "--dt 1e-300" is
    refused for its steps), then any setting outside its bound (:func:`check_bounds`)."""
    origin = settings.origin
    for key in ("dt", "fps", "duration"):
        Bound(0.0, lo_open=True, unit=BOUNDS[key].unit).named(
            getattr(settings, key), origin.name(key), origin.source)
    check_budget(settings)
    check_bounds(settings)


#: What a run's arrays take besides its model's own (bytes): per voxel, per link, per
#: voxel and charge (the waves' element views and lines of sight), and numba's loaded
#: kernels. Fitted to simulate()'s peak RSS over the loaded model for the 10 m block of
#: benchmarks/performance.py at 10^4, 10^5 and 10^6 voxels, the most of the worker's
#: five runs (77, 110 and 395 MiB, 2026-11-30; the estimate: 84, 113 and 422 MiB).
#: Per link: the CSR ids, the yield, the chunk interface and three flags (the strength
#: factors and the stress springs are worked out where used); per voxel: some twenty
#: columns of state, geometry and scratch.
RUN_BYTES_PER_VOXEL = 230
RUN_BYTES_PER_LINK = 30
RUN_BYTES_PER_VOXEL_CHARGE = 40
RUN_BYTES_FIXED = 80 * 2**20


def model_bytes(model) -> int:
    """Bytes of a VoxelModel's arrays."""
    return sum(a.nbytes for a in model.arrays.values())


def run_memory_bytes(model, charges: int) -> int:
    """Estimated memory (bytes) of a run of ``model`` (a VoxelModel) with ``charges``
    charges: the model's arrays and what the run adds per voxel, link and voxel-charge
    (see RUN_BYTES_*)."""
    voxels, links = model.voxel_count, len(model.arrays["link_voxels"])
    return int(model_bytes(model) + RUN_BYTES_FIXED + RUN_BYTES_PER_VOXEL * voxels
               + RUN_BYTES_PER_LINK * links + RUN_BYTES_PER_VOXEL_CHARGE * voxels * charges)


def check_run_memory(settings: SimSettings, model) -> int:
    """The estimated memory of a run of ``model`` (:func:`run_memory_bytes`, returned)
    within ``max_memory_gib``, else BudgetError naming the figure: checked before a run
    allocates anything."""
    need = run_memory_bytes(model, len(settings.charges))
    voxels, links = model.voxel_count, len(model.arrays["link_voxels"])
    limit = settings.budget.max_memory_gib
    if need / 2**30 > limit:
        raise BudgetError(
            f"{settings.origin.source}: simulating {voxels:,} voxels and {links:,} links "
            f"needs about {need / 2**30:.3g} GiB ({model_bytes(model) / 2**30:.2g} GiB of model, "
            f"the rest the run's arrays), over the limit of {fmt(limit)} GiB (raise it with "
            f"--max-memory, or voxelize with larger voxels)")
    return need


def check_record_memory(settings: SimSettings, pieces: int, frames: int,
                        run_bytes: int = 0) -> None:
    """The recorded frames of ``pieces`` over ``frames``, on top of the run's own
    ``run_bytes`` (:func:`check_run_memory`), within ``max_memory_gib``, else
    BudgetError (the engine calls it at the first frame and at each frame after a split:
    pieces only appear in splits)."""
    record = pieces * frames * RECORD_BYTES_PER_PIECE_FRAME
    need = (record + run_bytes) / 2**30
    limit = settings.budget.max_memory_gib
    if need > limit:
        name = settings.origin.name
        raise BudgetError(
            f"{settings.origin.source}: recording {pieces:,} piece{'s' * (pieces != 1)} over "
            f"{frames:,} frames needs about {record / 2**30:.3g} GiB on top of the run's "
            f"{run_bytes / 2**30:.3g}, over the limit of {fmt(limit)} GiB (raise it with "
            f"--max-memory, or lower {name('fps')} or {name('duration')})")


def gravity_vector(up: np.ndarray, gravity: float) -> np.ndarray:
    """(3,) m/s^2 pointing down the model's up axis."""
    return -gravity * np.asarray(up, dtype=np.float64)
