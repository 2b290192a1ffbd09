"""Stress-solver benchmark: the cost of one solve against its node count, and the
solver's share of the example shots' simulate time.

    python benchmarks/stress.py            # both tables (a few minutes on 2 cores)
    python benchmarks/stress.py --quick    # the solve table and the house only

Table 1, one solve: a 4 x 4 x 0.3 m plain concrete slab on one 40 cm corner column
at 0.1 m voxels (5,280 voxels), nodes from grid cells of k = 2, 3, 4 voxels and from
the model's chunks; seconds for the node graph, the assembly, SuperLU's
factorization and solve, and the stresses (best of 3, kernels warm).

Table 2, shots: each example scene's model (voxelized beforehand from its
scene), simulated through its own settings by stepping ``engine.Run``; the
wall time of the whole run and of the stress solver's phases (gravity solves and
impact fracture), with the solve count and links broken.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh
from _machine import machine  # benchmarks/ is on sys.path when run as a script

ROOT = Path(__file__).resolve().parents[1]


def _slab_model(tmp: Path):
    from blastvox.materials import MaterialLibrary
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    def box(e, c):
        return trimesh.creation.box(extents=e).apply_translation(c)

    mesh = trimesh.boolean.union([box((4, 4, 0.3), (2, 2, 3.15)),
                                  box((0.4, 0.4, 3.0), (0.2, 0.2, 1.5))])
    path = tmp / "slab.stl"
    mesh.export(path)
    return voxelize([ObjectRequest(mesh=path, voxel_size=(0.1,) * 3, material="concrete")],
                    VoxelizeSettings(up_axis="Z", ground=0.0, library=MaterialLibrary.builtin()))


def solve_table(tmp: Path, repeat: int) -> list[str]:
    from scipy.sparse import csc_matrix
    from scipy.sparse.linalg import splu

    from blastvox.simulate import stress

    model = _slab_model(tmp)
    a = model.arrays
    n = model.voxel_count
    springs = stress.link_springs(a)
    links = a["link_voxels"].astype(np.int64)
    fixed = a["voxel_foundation"]
    rows = ["| nodes from | nodes | interfaces | graph s | assemble s | SuperLU s | stresses s "
            "| worst utilization |", "|---|---|---|---|---|---|---|---|"]
    keys = [(f"grid k = {k}", np.concatenate([np.zeros((n, 1), dtype=np.int64),
                                               fixed[:, None].astype(np.int64),
                                               a["voxel_ijk"].astype(np.int64) // k], axis=1))
            for k in (2, 3, 4)]
    if "voxel_chunk" in a:
        keys.append(("chunks", np.concatenate([np.zeros((n, 1), dtype=np.int64),
                                               fixed[:, None].astype(np.int64),
                                               a["voxel_chunk"][:, None].astype(np.int64),
                                               np.zeros((n, 2), dtype=np.int64)], axis=1)))
    for label, key in keys:
        best = [np.inf] * 4
        for _ in range(repeat + 1):  # the first run warms the kernels
            t0 = time.perf_counter()
            g = stress.coarse_graph(springs, links, np.ones(n, dtype=bool), fixed,
                                    np.ones(len(links), dtype=bool), key, a["voxel_mass"],
                                    a["voxel_centroid"])
            free = ~g.node_fixed
            dof = np.full(len(free), -1, dtype=np.int64)
            dof[free] = np.arange(int(free.sum()))
            t1 = time.perf_counter()
            r, c, v = stress.assemble(g, dof)
            size = 6 * int(free.sum())
            matrix = csc_matrix((v, (r, c)), shape=(size, size))
            rhs = np.zeros(size)
            blocks = np.flatnonzero(free)
            rhs[6 * dof[blocks] + 2] = -9.81 * g.node_mass[blocks]
            t2 = time.perf_counter()
            q = splu(matrix, permc_spec="COLAMD").solve(rhs)
            t3 = time.perf_counter()
            out = np.zeros((len(g.links), 4))
            stress.link_stresses(springs.rows(g.links), g, dof, q, out)
            t4 = time.perf_counter()
            best = [min(b, x) for b, x in zip(best, (t1 - t0, t2 - t1, t3 - t2, t4 - t3),
                                              strict=True)]
        rows.append(f"| {label} | {len(free)} | {len(g.pair)} | {best[0]:.4f} | {best[1]:.4f} "
                    f"| {best[2]:.4f} | {best[3]:.4f} | {out[:, 3].max():.2f} |")
    return rows


def shot_row(scene_path: Path) -> str:
    from blastvox.scene import load_scene
    from blastvox.simulate import engine
    from blastvox.simulate.settings import settings_from_scene
    from blastvox.voxelize.pipeline import voxelize
    from blastvox.voxelize.requests import requests_from_scene
    from blastvox.voxelize.requests import settings_from_scene as voxel_settings

    scene = load_scene(scene_path)
    model = voxelize(requests_from_scene(scene), voxel_settings(scene))
    settings = settings_from_scene(scene, str(scene_path))
    started = time.perf_counter()
    run = engine.Run.start(model, settings)
    per_frame = settings.steps_per_frame()
    steps = (settings.frame_count() - 1) * per_frame
    for n in range(1, steps + 1):
        engine.step(run, n, -(-n // per_frame))
    total = time.perf_counter() - started
    s = run.stress
    if s is None:
        return f"| {scene_path.parent.name} | {model.voxel_count} | {total:.2f} | off | | | |"
    return (f"| {scene_path.parent.name} | {model.voxel_count} | {total:.2f} | {s.seconds:.2f} "
            f"| {100 * s.seconds / total:.0f} % | {s.solves} | {s.broken} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(machine(("blastvox", "numpy", "numba", "scipy")))
    with tempfile.TemporaryDirectory() as tmp:
        print("\n".join(solve_table(Path(tmp), 1 if args.quick else args.repeat)))
        print()
        print("| shot | voxels | simulate s (warm) | stress s | share | solves | links broken |")
        print("|---|---|---|---|---|---|---|")
        scenes = ["house"] if args.quick else ["house", "building"]
        for name in scenes:
            path = ROOT / "examples" / name / "scene.toml"
            shot_row(path)  # warm-up: kernels compiled or loaded
            print(shot_row(path), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
