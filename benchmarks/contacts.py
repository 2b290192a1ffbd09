"""Contact cost against the number of boundary voxels of moving bodies.

    python benchmarks/contacts.py [--quick]

A cloud of n^3 separate 0.2 m cubes (one voxel each, so every voxel is a
boundary voxel of a moving body) 0.3 m apart is dropped from 1 m onto the
ground with a small random spin, and falls into a pile: bodies collide with
the ground and each other. The table gives wall ms per step with collisions on
and off (ground contact on in both), and per boundary voxel, so near-linear
growth shows as a near-constant last column; then frames per second at 24 fps
and 1/240 s steps (10 steps a frame) laid out like Mazarak 1999 Table 5-1,
with the paper's figures (333 MHz Pentium II) beside ours.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh
from _machine import machine  # benchmarks/ is on sys.path when run as a script

from blastvox.simulate import run as simrun
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.simulate.state import build_model
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

PAPER = {"1 - 10": (">100", ">100", ">100"), "10 - 100": ("70", "20", "15"),
         "100 - 1,000": ("15", "0.25", "5"), "1,000 - 10,000": ("<1", "<0.017", "<0.33")}


def cloud(n: int, directory: Path):
    cubes = [trimesh.creation.box(extents=(0.2, 0.2, 0.2)).apply_translation(
        (0.3 * i, 0.3 * j, 1.0 + 0.3 * k)) for i in range(n) for j in range(n) for k in range(n)]
    path = directory / f"cloud{n}.stl"
    trimesh.util.concatenate(cubes).export(path)
    return voxelize([ObjectRequest(mesh=path, voxel_size=(0.2,) * 3, material="stone")],
                    VoxelizeSettings(up_axis="Z", ground=0.0, max_voxels=2_000_000))


def ms_per_step(model, collisions: bool, steps: int) -> float:
    settings = SimSettings(collisions=collisions, fps=24.0, duration=1.0,
                           charges=(ChargeSpec((1e5, 0.0, 0.0), 1e-3),), dust=False)
    sm = build_model(model)
    state = simrun.initial_state(model, sm)
    rng = np.random.default_rng(0)
    n = int(state.n_bodies[0])
    state.body_ang[:n] = rng.normal(0.0, 1.0, (n, 3)) * state.body_mass[:n, None] * 0.01
    run = simrun._Run(sm, state, simrun.build_charges(settings.charges), settings,
                      settings.step_seconds())
    for step in range(1, 3):  # compile / warm up
        run.step(step, 0)
    started = time.perf_counter()
    for step in range(3, 3 + steps):
        run.step(step, 0)
    return 1e3 * (time.perf_counter() - started) / steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1k and 10k only")
    args = parser.parse_args()
    sizes = (10, 22) if args.quick else (10, 22, 46)
    print(machine() + "\n")
    print("| boundary voxels (moving) | ms/step, collisions on | ms/step, off | "
          "µs per voxel-step (on) |")
    print("|--:|--:|--:|--:|")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            model = cloud(n, Path(tmp))
            steps = max(20, 2000 // n)
            on = ms_per_step(model, True, steps)
            off = ms_per_step(model, False, steps)
            rows.append((model.voxel_count, on, off))
            print(f"| {model.voxel_count:,} | {on:.2f} | {off:.2f} | "
                  f"{1e3 * on / model.voxel_count:.2f} |", flush=True)
    print("\nFrames per second (24 fps shot, 10 steps a frame) beside Mazarak 1999 Table 5-1:\n")
    print("| boundary voxels | paper: no collisions | paper: pairwise | paper: buckets | "
          "blastvox: ground only | blastvox: collisions |")
    print("|---|--:|--:|--:|--:|--:|")
    for (voxels, on, off), band in zip(rows, ["100 - 1,000", "1,000 - 10,000", "> 10,000"],
                                       strict=False):
        paper = PAPER.get(band, ("—", "—", "—"))
        print(f"| {voxels:,} ({band}) | {paper[0]} | {paper[1]} | {paper[2]} | "
              f"{1e3 / (10 * off):.1f} | {1e3 / (10 * on):.1f} |")


if __name__ == "__main__":
    main()
