"""The building's rubble pile: blastvox's contact phase beside PyBullet on the same pieces.

    python benchmarks/pile.py [--split 2.5] [--iterations 8] [--contact-substeps N]

Runs ``examples/building`` (its VoxelModel at ``out/building/model.npz``: run
``blastvox run examples/building/scene.toml`` first) in blastvox up to
``--split`` seconds, when the west half has come down and its pieces start to
pile up, then times the rest of the shot twice from that same state:

* blastvox: ``engine.step`` in a loop (what ``simulate()`` runs, every phase,
  without recording frames), after an untimed warm-up run of the whole shot;
* PyBullet (``p.DIRECT``, one thread): every moving piece a rigid body of its
  mass, shaped as the convex hull of its voxels' corners (kinder to Bullet than
  the pieces' real, often concave shapes), at its position and velocity; the
  standing pieces one static triangle mesh of their voxels' faces; a ground
  plane; the shot's gravity and dt; ``numSolverIterations`` ``--iterations``
  (8, a game engine's budget, against blastvox's 4 sub-steps of two sweeps each);
  sleeping on at blastvox's sleep speed. Building the Bullet scene is not timed.

It prints the machine and a Markdown table: steps, seconds and milliseconds per
step of each engine, and the moving pieces at the split. What it
answers: what a second of this pile costs a mature C++ rigid-body engine, against
the 1 s over the start-up floor that the whole 5 s shot is asked to fit.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from _machine import machine  # benchmarks/ is on sys.path when run as a script
from performance import import_pybullet

from blastvox.model import VoxelModel
from blastvox.scene import load_scene
from blastvox.simulate import engine

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "examples" / "building" / "scene.toml"
MODEL = ROOT / "out" / "building" / "model.npz"

#: The eight corners of a unit cube's 12 triangles (two per face), outward winding.
CUBE_TRIANGLES = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                           [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])


@dataclass
class Pile:
    """The run's moving and standing pieces at the split, world frame (m, kg, m/s)."""

    hulls: list[np.ndarray]  # per moving piece: its voxels' corners about its centre of mass
    mass: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    omega: np.ndarray
    static_corners: np.ndarray  # (S, 8, 3) the standing voxels' corners


def run_to_split(settings, split_step: int, steps: int) -> tuple[Pile, float, object]:
    """blastvox up to ``split_step``; returns the pile there, the seconds of steps
    split_step + 1 .. steps, and the run."""
    model = VoxelModel.load(MODEL)
    engine.simulate(model, settings)  # warm-up: numba's cache, untimed
    run = engine.Run.start(model, settings)
    per_frame = settings.steps_per_frame()
    for n in range(1, split_step + 1):
        engine.step(run, n, -(-n // per_frame))
    pile = _pile(run)
    started = time.perf_counter()
    for n in range(split_step + 1, steps + 1):
        engine.step(run, n, -(-n // per_frame))
    return pile, time.perf_counter() - started, run


def _pile(run) -> Pile:
    state, geometry = run.state, run.model.voxels
    bodies, n = state.bodies, state.n_bodies
    alive = state.voxels.alive
    corners_rest = geometry.vertices[geometry.corners]  # (N, 8, 3)
    hulls, masses, pos, vel, omega, static = [], [], [], [], [], []
    for b in range(n):
        if not bodies.live[b] or bodies.dust[b]:
            continue
        members = np.flatnonzero(alive & (state.voxels.body == b))
        if not members.size:
            continue
        rot = bodies.rot[b]
        world = (corners_rest[members] - bodies.com[b]) @ rot.T + bodies.pos[b]
        if bodies.fixed[b]:
            static.append(world)
            continue
        hulls.append((world - bodies.pos[b]).reshape(-1, 3))
        masses.append(bodies.mass[b])
        pos.append(bodies.pos[b].copy())
        vel.append(bodies.lin[b] / bodies.mass[b])
        world_inv = rot @ bodies.inv_inertia[b] @ rot.T
        omega.append(world_inv @ bodies.ang[b])
    return Pile(hulls, np.array(masses), np.array(pos), np.array(vel), np.array(omega),
                np.concatenate(static) if static else np.zeros((0, 8, 3)))


def bullet_seconds(p, pile: Pile, settings, dt: float, steps: int, ground: float,
                   up: np.ndarray, iterations: int) -> tuple[float, int]:
    """Seconds of PyBullet's ``steps`` from the pile, and its contact points at the end."""
    c = p.connect(p.DIRECT)
    try:
        p.setGravity(*(-settings.gravity * up).tolist(), physicsClientId=c)
        p.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0,
                                    numSolverIterations=iterations, physicsClientId=c)
        plane = p.createCollisionShape(p.GEOM_PLANE, planeNormal=up.tolist(), physicsClientId=c)
        p.createMultiBody(0.0, plane, basePosition=(ground * up).tolist(), physicsClientId=c)
        if len(pile.static_corners):
            vertices = pile.static_corners.reshape(-1, 3)
            indices = (CUBE_TRIANGLES[None] + 8 * np.arange(len(pile.static_corners))[:, None,
                                                                                       None])
            mesh = p.createCollisionShape(p.GEOM_MESH, vertices=vertices.tolist(),
                                          indices=indices.ravel().tolist(), physicsClientId=c)
            p.createMultiBody(0.0, mesh, physicsClientId=c)
        for k, hull in enumerate(pile.hulls):
            shape = p.createCollisionShape(p.GEOM_MESH, vertices=hull.tolist(), physicsClientId=c)
            body = p.createMultiBody(float(pile.mass[k]), shape,
                                     basePosition=pile.pos[k].tolist(),
                                     flags=p.URDF_ENABLE_SLEEPING, physicsClientId=c)
            p.changeDynamics(body, -1, sleepThreshold=settings.sleep_speed,
                             lateralFriction=settings.friction, physicsClientId=c)
            p.resetBaseVelocity(body, pile.vel[k].tolist(), pile.omega[k].tolist(),
                                physicsClientId=c)
        started = time.perf_counter()
        for _ in range(steps):
            p.stepSimulation(physicsClientId=c)
        seconds = time.perf_counter() - started
        return seconds, len(p.getContactPoints(physicsClientId=c))
    finally:
        p.disconnect(c)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", type=float, default=2.5,
                        help="seconds of shot before the timed part (default 2.5)")
    parser.add_argument("--iterations", type=int, default=8,
                        help="PyBullet's solver iterations (default 8)")
    parser.add_argument("--contact-substeps", type=int,
                        help="blastvox's contact_substeps (default: the scene's)")
    args = parser.parse_args(argv)
    if not MODEL.exists():
        print(f"{MODEL}: missing; run `blastvox run {SCENE}` first", file=sys.stderr)
        return 1
    p = import_pybullet()
    if p is None:
        print("pybullet is missing: pip install -e '.[bench]'", file=sys.stderr)
        return 1
    from blastvox.simulate.settings import settings_from_scene

    settings = settings_from_scene(load_scene(SCENE), str(SCENE))
    if args.contact_substeps is not None:
        settings = replace(settings, contact_substeps=args.contact_substeps)
    dt = settings.step_seconds()
    steps = (settings.frame_count() - 1) * settings.steps_per_frame()
    split = max(1, min(steps - 1, round(args.split / dt)))
    pile, blastvox_s, run = run_to_split(settings, split, steps)
    ground = float(run.model.ground_height)
    bullet_s, contacts = bullet_seconds(p, pile, settings, dt, steps - split, ground,
                                        np.asarray(run.model.up, dtype=float), args.iterations)
    timed = steps - split
    print(machine())
    print(f"\nexamples/building from {split * dt:g} s to {steps * dt:g} s ({timed:,} steps of "
          f"{dt * 1e3:.4g} ms); {len(pile.hulls):,} moving pieces and "
          f"{len(pile.static_corners):,} standing voxels at the split\n")
    print("| engine | s | ms per step |")
    print("|---|--:|--:|")
    print(f"| blastvox, every phase, contact_substeps {settings.contact_substeps} | "
          f"{blastvox_s:.2f} | {1e3 * blastvox_s / timed:.2f} |")
    print(f"| PyBullet, {args.iterations} solver iterations, convex hulls ({contacts:,} contact "
          f"points at the end) | {bullet_s:.2f} | {1e3 * bullet_s / timed:.2f} |")
    print(f"\nPer second of shot: blastvox {blastvox_s / (timed * dt):.2f} s, "
          f"PyBullet {bullet_s / (timed * dt):.2f} s.")
    return 0 if math.isfinite(blastvox_s) else 1


if __name__ == "__main__":
    raise SystemExit(main())
