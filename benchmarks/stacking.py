"""Stacking: blastvox's box-contact solver beside PyBullet on columns of cubes.

    python benchmarks/stacking.py [--quick]

Separate 0.2 m cubes of unbreakable concrete (concrete's density, infinite voxel
yield, so impacts never dust a cube) are dropped onto the ground and left for
3 s of simulated time; every cube ends resting on the one below it, if the
solver can stack:

* A: ten cubes in one column, cube k centred at z = 0.1 + 0.25 k (0.05 m gaps):
  the top cube's centre should end at 1.90 m, the mean centre at 1.00 m;
* B: 1,000 cubes in a 10 x 10 x 10 lattice 0.4 m apart, cube (i, j, k) at
  (0.4 i, 0.4 j, 0.1 + 0.4 k): every column's top at 1.90 m, mean centre 1.00 m.

Each at dt = 1/240 s and 1/1000 s, in blastvox (``engine.step`` in a loop, what
``simulate()`` runs, without recording frames; foundations cleared, so every
cube is loose; effects, stress and fire off, so only gravity and contacts act)
and in PyBullet (DIRECT mode, box shapes, maximal coordinates, a static ground
plane, the same mass, friction 0.6, restitution 0 where blastvox keeps
concrete's 0.2, the same dt via ``setPhysicsEngineParameter(fixedTimeStep=dt,
numSubSteps=0)``, pybullet's default solver iterations (50) and its default of
no sleeping). The Markdown table gives the top cube's centre (for B, the lowest
and highest of the 100 column tops; a column is the cubes that started in it),
the mean centre height, the fraction of blastvox's cubes asleep at the end, and
the wall seconds of the stepping loop only: building the scenes is not timed,
and blastvox first runs an untimed warm-up at both steps, so numba's
compilation (or cache load) is not in the times. ``--quick``: scenario A, and
B at 1/240 s only.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np
import trimesh
from _machine import machine  # benchmarks/ is on sys.path when run as a script
from performance import import_pybullet

from blastvox.materials import MaterialLibrary
from blastvox.model import VoxelModel
from blastvox.simulate import engine
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

EDGE = 0.2  # cube edge and voxel size, m
DURATION = 3.0  # s of simulated time
DTS = (1.0 / 240.0, 1.0 / 1000.0)
FRICTION = 0.6
FPS = 40.0  # 1 / (fps dt) is whole at both steps (6 and 25), so run.dt is dt exactly
MATERIAL = "hard"
LIBRARY = MaterialLibrary.builtin().extended({MATERIAL: {
    "base": "concrete", "voxel_yield_mean": float("inf"), "voxel_yield_var": 0.0}}, "bench")
FAR = (ChargeSpec((1e5, 0.0, 0.0), 1e-3),)  # a charge whose wave never arrives
EXPECTED_TOP = 1.9  # m: ten cubes resting on one another
EXPECTED_MEAN = 1.0  # m


@dataclass(frozen=True)
class Scenario:
    """Cube centres (K, 3) m and the column (0 ... C - 1) each cube starts in."""

    name: str
    centres: np.ndarray
    columns: np.ndarray


@dataclass(frozen=True)
class Outcome:
    """Final cube centres (K, 3), fraction asleep (None: not measured), loop wall s."""

    pos: np.ndarray
    asleep: float | None
    seconds: float


def column_a() -> Scenario:
    """Scenario A: ten cubes in one column, 0.05 m apart."""
    k = np.arange(10)
    centres = np.column_stack([np.zeros(10), np.zeros(10), 0.1 + 0.25 * k])
    return Scenario("A: 10 cubes, one column", centres, np.zeros(10, dtype=np.int64))


def lattice_b() -> Scenario:
    """Scenario B: a 10 x 10 x 10 lattice of cubes 0.4 m apart."""
    i, j, k = np.meshgrid(np.arange(10), np.arange(10), np.arange(10), indexing="ij")
    centres = np.column_stack([0.4 * i.ravel(), 0.4 * j.ravel(), 0.1 + 0.4 * k.ravel()])
    return Scenario("B: 1,000 cubes, 10 × 10 columns", centres, (10 * i + j).ravel())


def export_cubes(centres: np.ndarray, path: Path) -> Path:
    """One STL of a 0.2 m cube at each of ``centres``."""
    boxes = [trimesh.creation.box(extents=(EDGE,) * 3).apply_translation(c) for c in centres]
    trimesh.util.concatenate(boxes).export(path)
    return path


def blastvox_model(scenario: Scenario, directory: Path) -> VoxelModel:
    """The cubes voxelized to one voxel each. Cubes closer than a voxel (scenario A)
    would merge on one 0.2 m lattice, so each cube is then its own object."""
    centres = scenario.centres
    gaps = np.diff(np.sort(np.unique(centres[:, 2])))
    if gaps.size and gaps.min() < 2 * EDGE:
        paths = [export_cubes(c[None], directory / f"cube{n}.stl") for n, c in enumerate(centres)]
    else:
        paths = [export_cubes(centres, directory / f"cubes{len(centres)}.stl")]
    requests = [ObjectRequest(mesh=p, voxel_size=(EDGE,) * 3, material=MATERIAL) for p in paths]
    model = voxelize(requests, VoxelizeSettings(up_axis="Z", ground=0.0, library=LIBRARY))
    if model.voxel_count != len(centres) or len(model.arrays["link_voxels"]):
        raise RuntimeError(f"{len(centres)} cubes made {model.voxel_count} voxels and "
                           f"{len(model.arrays['link_voxels'])} links")
    return model


def blastvox_settings(dt: float, duration: float = DURATION) -> SimSettings:
    """Gravity, ground and collisions; no wave, no effects, no stress, no fire."""
    return SimSettings(gravity=9.81, ground=True, fps=FPS, duration=duration, dt=dt,
                       friction=FRICTION, charges=FAR, dust=False, fireball=False,
                       shock_sphere=False, camera_shake=False, stress=False, fire=False)


def blastvox_run(model: VoxelModel, scenario: Scenario, settings: SimSettings) -> Outcome:
    """Step ``model`` for the settings' duration; the loop alone is timed."""
    run = engine.Run.start(model, settings)
    bodies, n = run.state.bodies, run.state.n_bodies
    if n != len(scenario.centres):
        raise RuntimeError(f"{n} bodies for {len(scenario.centres)} cubes")
    run.state.voxels.foundation[:] = False
    bodies.fixed[:n] = False  # loose on the ground, not founded
    order = body_order(bodies.pos[:n], scenario.centres)
    steps = round(settings.duration / run.dt)
    started = time.perf_counter()
    for s in range(1, steps + 1):
        engine.step(run, s, 0)
    seconds = time.perf_counter() - started
    return Outcome(bodies.pos[:n][order].copy(), float(bodies.asleep[:n].mean()), seconds)


def body_order(pos: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Index of the body starting at each of ``centres`` (to within a quarter voxel)."""
    distance = np.linalg.norm(pos[None, :, :] - centres[:, None, :], axis=2)
    order = distance.argmin(axis=1)
    if distance[np.arange(len(centres)), order].max() > EDGE / 4:
        raise RuntimeError("blastvox's bodies do not start at the cubes' centres")
    return order


def bullet_run(p: ModuleType, scenario: Scenario, dt: float, mass: float
               ) -> tuple[Outcome, int]:
    """PyBullet's run; returns the outcome and the solver iterations it used."""
    c = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=c)
        p.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0, physicsClientId=c)
        iterations = int(p.getPhysicsEngineParameters(physicsClientId=c)["numSolverIterations"])
        # Bullet multiplies the two bodies' coefficients: sqrt(mu) each gives mu at every pair
        surface = {"lateralFriction": math.sqrt(FRICTION), "restitution": 0.0}
        plane = p.createMultiBody(0.0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=c),
                                  physicsClientId=c)
        p.changeDynamics(plane, -1, **surface, physicsClientId=c)
        box = p.createCollisionShape(p.GEOM_BOX, halfExtents=[EDGE / 2] * 3, physicsClientId=c)
        ids = [p.createMultiBody(mass, box, basePosition=centre.tolist(),
                                 useMaximalCoordinates=True, physicsClientId=c)
               for centre in scenario.centres]
        for b in ids:
            p.changeDynamics(b, -1, **surface, physicsClientId=c)
        steps = round(DURATION / dt)
        started = time.perf_counter()
        for _ in range(steps):
            p.stepSimulation(physicsClientId=c)
        seconds = time.perf_counter() - started
        pos = np.array([p.getBasePositionAndOrientation(b, physicsClientId=c)[0] for b in ids])
        return Outcome(pos, None, seconds), iterations
    finally:
        p.disconnect(c)


def row(scenario: Scenario, engine_name: str, dt: float, outcome: Outcome) -> str:
    """One Markdown row."""
    z = outcome.pos[:, 2]
    tops = np.full(scenario.columns.max() + 1, -np.inf)
    np.maximum.at(tops, scenario.columns, z)
    top = f"{tops[0]:.3f}" if len(tops) == 1 else f"{tops.min():.3f} – {tops.max():.3f}"
    asleep = "—" if outcome.asleep is None else f"{100 * outcome.asleep:.0f} %"
    return (f"| {scenario.name} | {engine_name} | 1/{1 / dt:.0f} | {top} | {z.mean():.3f} | "
            f"{asleep} | {outcome.seconds:.2f} |")


def warm_up(model: VoxelModel, scenario: Scenario) -> None:
    """Untimed short runs at every step: numba compiles (or loads) the kernels."""
    for dt in DTS:
        blastvox_run(model, scenario, blastvox_settings(dt, duration=0.5))


def cases(quick: bool) -> list[tuple[Scenario, float]]:
    """(scenario, dt) pairs to run."""
    a, b = column_a(), lattice_b()
    pairs = [(a, dt) for dt in DTS] + [(b, dt) for dt in DTS]
    return [(s, dt) for s, dt in pairs if not (quick and s is b and dt != DTS[0])]


def print_header(mass: float, p: ModuleType | None) -> None:
    """What the table holds."""
    print(f"Cubes: {EDGE:g} m, {mass:g} kg (concrete, {LIBRARY[MATERIAL].density:g} kg/m³), "
          f"friction {FRICTION:g}, restitution {LIBRARY[MATERIAL].restitution:g} (blastvox) "
          f"and 0 (PyBullet); {DURATION:g} s simulated. Expected: top centre "
          f"{EXPECTED_TOP:.2f} m, mean centre z {EXPECTED_MEAN:.2f} m. Wall s: the stepping "
          "loop only, after an untimed warm-up (numba compilation excluded).")
    if p is None:
        print("\npybullet is not installed (`pip install -e '.[bench]'`): blastvox rows only.")
    print("\n| scenario | engine | dt (s) | top centre (m) | mean centre z (m) | "
          "asleep (blastvox) | wall s |")
    print("|---|---|--:|--:|--:|--:|--:|", flush=True)


def main() -> None:
    """Print the machine line and the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="A, and B at 1/240 s only")
    args = parser.parse_args()
    print(machine(("blastvox", "numpy", "numba", "pybullet")) + "\n")
    p = import_pybullet()
    with tempfile.TemporaryDirectory(prefix="blastvox-stack-") as tmp:
        iterations = table(cases(args.quick), p, Path(tmp))
    if iterations is not None:
        print(f"\nPyBullet: pybullet's default numSolverIterations ({iterations}), "
              "sleeping off (its default), one thread.")


def table(pairs: list[tuple[Scenario, float]], p: ModuleType | None, directory: Path
          ) -> int | None:
    """Build the models, warm up, print the table; PyBullet's solver iterations, if run."""
    mass = LIBRARY[MATERIAL].density * EDGE ** 3
    models: dict[str, VoxelModel] = {}
    for scenario, _ in pairs:
        if scenario.name not in models:
            models[scenario.name] = blastvox_model(scenario, directory)
            check_mass(models[scenario.name], mass)
    warm_up(models[pairs[0][0].name], pairs[0][0])
    print_header(mass, p)
    iterations = None
    for scenario, dt in pairs:
        outcome = blastvox_run(models[scenario.name], scenario, blastvox_settings(dt))
        print(row(scenario, "blastvox", dt, outcome), flush=True)
        if p is not None:
            outcome, iterations = bullet_run(p, scenario, dt, mass)
            print(row(scenario, "PyBullet", dt, outcome), flush=True)
    return iterations


def check_mass(model: VoxelModel, mass: float) -> None:
    """Refuse a model whose cubes do not weigh ``mass`` (the PyBullet boxes' mass)."""
    masses = np.asarray(model.arrays["voxel_mass"])
    if not np.allclose(masses, mass, rtol=1e-6):
        raise RuntimeError(f"blastvox cubes weigh {masses.min()} ... {masses.max()} kg, "
                           f"not {mass} kg")


if __name__ == "__main__":
    main()

