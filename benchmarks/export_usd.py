"""USD against glTF export of ~20,000 pieces: .usdc and .glb side by side (markdown table).

    python benchmarks/export_usd.py               # synthetic and real shot, best of 3 (~5 min)
    python benchmarks/export_usd.py --quick       # synthetic shot only, one timed run each
    python benchmarks/export_usd.py --repeat 5    # best of 5

Issue 37's target: a ~20k-piece shot's .usdc export within 2x of its .glb export.

Two shots of about 20,000 pieces:

* **synthetic**: ``benchmarks/export.py``'s ``synthetic_cache`` with 20,000 pieces and
  73 frames (3 s at 24 fps): 2x2x2-voxel pieces all flying and tumbling for the whole
  shot, so no time sample can be pruned (the worst case for USD);
* **wall** (not with ``--quick``): a real cache, built through the library: a 14.7 m
  square brick wall one 0.1 m voxel thick (21,609 voxels, no chunks) on the ground, 40
  kg TNT 5 m in front of its centre, 3 s at 24 fps, fragment collisions off (as
  ``benchmarks/export_scale.py``'s wall): about 20,000 pieces, most of them single
  voxels, many of which come to rest (their samples are pruned). Its dust particles
  are exported too (USD only: glTF has none).

Each file is written with :func:`blastvox.export.api.export` (default options: Y up,
an Xform + Mesh per piece in USD, a node per piece in glTF), best of N after a warm-up
export of a tiny cache per format; "CPU s" is the process's CPU time of the same run
(which a shared machine disturbs less than wall time). The .usdc row is split into
building the layer through the Sdf API (:func:`blastvox.export.usd.build_layer`) and
OpenUSD writing it as a crate (``SdfLayer.Export``), timed separately in one more
run, with the layer's counts of prims, properties (attributes and relationships) and
time samples: the crate writer's cost grows with those counts. It reports and does
not gate: exit 0 even when the target is missed.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

from _machine import machine, repeat_count, verdict  # benchmarks/ is on sys.path
from export import synthetic_cache  # benchmarks/export.py

PIECES, FRAMES, FPS = 20_000, 73, 24.0
TARGET_RATIO = 2.0


def wall_cache():
    """The brick wall (see the module doc): about 20,000 pieces."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    side = 14.7
    with tempfile.TemporaryDirectory() as tmp:
        mesh = Path(tmp) / "wall.stl"
        box = trimesh.creation.box(extents=(side, 0.1, side))
        box.apply_translation((0.0, 0.0, side / 2))
        box.export(mesh)
        model = voxelize([ObjectRequest(mesh=mesh, name="wall", voxel_size=(0.1,) * 3,
                                        material="brick", chunk_size=0)],
                         VoxelizeSettings(up_axis="Z"))
    charge = ChargeSpec((0.0, -5.0, side / 2), 40.0)
    return simulate(model, SimSettings(duration=(FRAMES - 1) / FPS, fps=FPS, collisions=False,
                                       charges=(charge,)))


def timed(run, repeat: int) -> tuple[float, float]:
    """Best wall and best CPU seconds of ``repeat`` calls of ``run``."""
    best = cpu = float("inf")
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        run()
        best = min(best, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return best, cpu


def layer_counts(layer) -> tuple[int, int, int]:
    """(prims, properties, time samples) of an Sdf layer."""
    from pxr import Sdf

    counts = [0, 0, 0]

    def visit(path):
        if path.IsPrimPath():
            counts[0] += 1
        elif path.IsPropertyPath():
            counts[1] += 1
            counts[2] += layer.GetNumTimeSamplesForPath(path)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return counts[0], counts[1], counts[2]


def split_usd(cache, out: Path) -> tuple[float, float, tuple[int, int, int]]:
    """(Sdf build s, crate write s, counts) of one .usdc export, timed apart."""
    from blastvox.export.options import ExportOptions
    from blastvox.export.usd import _export_layer, build_layer

    t0 = time.perf_counter()
    layer = build_layer(cache, ExportOptions(), f"{out.stem}_textures")
    t1 = time.perf_counter()
    _export_layer(layer, out)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, layer_counts(layer)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="synthetic shot only, one run")
    parser.add_argument("--repeat", type=int, default=None,
                        help="timed exports per file, best counts (default 3, 1 with --quick)")
    args = parser.parse_args(argv)
    repeat = repeat_count(parser, args)
    started = time.perf_counter()
    print(machine(("blastvox", "numpy", "usd-core")))
    sys.stdout.flush()
    warnings.simplefilter("ignore")  # the node-per-piece glTF's size warning

    from blastvox.export.api import ExportOptions, export

    shots = [("synthetic", lambda: synthetic_cache(PIECES, FRAMES, FPS))]
    if not args.quick:
        shots.append(("wall", wall_cache))
    rows, notes = [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        tiny = synthetic_cache(pieces=8, frames=4)
        for suffix in (".usdc", ".glb"):  # imports and USD plug-ins, not timed
            export(tiny, out / f"warmup{suffix}", ExportOptions())
        for name, build in shots:
            t0 = time.perf_counter()
            cache = build()
            notes.append(f"{name}: {cache.piece_count:,} pieces, {cache.frame_count} frames, "
                         f"{cache.model.voxel_count:,} voxels, "
                         f"{len(cache.arrays.get('particle_system', ())):,} particles "
                         f"(built in {time.perf_counter() - t0:.1f} s)")
            times = {}
            for suffix in (".glb", ".usdc"):
                path = out / f"{name}{suffix}"
                seconds, cpu = timed(lambda p=path, c=cache: export(c, p, ExportOptions()), repeat)
                times[suffix] = (seconds, cpu, path.stat().st_size / 1e6)
            sdf_s, crate_s, (prims, props, samples) = split_usd(cache, out / f"{name}_split.usdc")
            ratio = times[".usdc"][0] / times[".glb"][0]
            rows.append((name, cache.piece_count, times, ratio, sdf_s, crate_s, prims, props,
                         samples))
            print(f"{name}: .glb {times['.glb'][0]:.2f} s, .usdc {times['.usdc'][0]:.2f} s",
                  file=sys.stderr)
            del cache

    print(f"\nBest of {repeat} after a warm-up; the split is one more run.\n")
    print("| shot | pieces | .glb s (CPU) | .glb MB | .usdc s (CPU) | .usdc MB "
          "| .usdc / .glb | target | result |")
    print("|---|--:|--:|--:|--:|--:|--:|---|---|")
    for name, pieces, t, ratio, *_ in rows:
        print(f"| {name} | {pieces:,} | {t['.glb'][0]:.2f} ({t['.glb'][1]:.2f}) | "
              f"{t['.glb'][2]:.1f} | {t['.usdc'][0]:.2f} ({t['.usdc'][1]:.2f}) | "
              f"{t['.usdc'][2]:.1f} | {ratio:.1f}x | < {TARGET_RATIO:g}x | "
              f"{verdict(ratio < TARGET_RATIO)} |")
    print("\n| shot | Sdf build s | crate write s | prims | properties | time samples |")
    print("|---|--:|--:|--:|--:|--:|")
    for name, _, _, _, sdf_s, crate_s, prims, props, samples in rows:
        print(f"| {name} | {sdf_s:.2f} | {crate_s:.2f} | {prims:,} | {props:,} | {samples:,} |")
    print()
    for note in notes:
        print(f"* {note}")
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"\nLoad average at the end: {load}; whole benchmark "
          f"{time.perf_counter() - started:.0f} s.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
