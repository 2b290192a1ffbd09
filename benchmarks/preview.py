"""Preview benchmark: seconds per frame at 960x540 for 1,000 pieces (markdown table).

    python benchmarks/preview.py               # 24 frames per case, best of 3
    python benchmarks/preview.py --repeat 1
    python benchmarks/preview.py --pieces 8000 --size 1920x1080

The SimCache is the export benchmark's synthetic one (benchmarks/export.py: a
cube of 0.25 m voxels cut into 2x2x2-voxel pieces, 48 triangles each, all
flying off and tumbling; a tenth vanish part-way), its debris cloud shrunk to a
third and kept above the ground so that it stays in view, plus particles (4,000 dust
born over the first 2 s, 1,000 smoke, 300 fireball at the charge), the
shock sphere's opacity and a ground plane under the block, all seen by the
automatic camera. Timed: :meth:`blastvox.preview.api.Shot.render` of every
fifth frame (24 frames of the 120), after one warm-up frame (numba's cache
load), best of N runs; then whole files through :func:`blastvox.preview.api.preview`
(render, labels, encoding, atomic write) per frame. "s/frame" is wall time,
"CPU s/frame" the process's CPU time (less disturbed by a busy machine).
Target: < 0.2 s/frame for 1,000 pieces at 960x540 with everything drawn.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _machine import machine  # benchmarks/ is on sys.path when run as a script
from export import synthetic_cache  # benchmarks/export.py

TARGET_S = 0.2


def preview_cache(pieces: int = 1000, frames: int = 120, seed: int = 1):
    """The export benchmark's cache with particles, shock opacity and a ground height."""
    from blastvox.cache import SimCache
    from blastvox.particles import SYSTEM_NAMES, particle_meta
    from blastvox.simulate.cues import shock_opacity

    cache = synthetic_cache(pieces, frames)
    a = dict(cache.arrays)
    rng = np.random.default_rng(seed)
    lo = cache.model.arrays["vertices"].min(axis=0)
    hi = cache.model.arrays["vertices"].max(axis=0)
    # a debris cloud that stays in view: a third of the export benchmark's spread, and
    # nothing below the ground (the block's base)
    pivot = a["piece_pivot"][None]
    position = pivot + (a["piece_position"].astype(np.float64) - pivot) / 3.0
    position[..., 2] = np.maximum(position[..., 2], lo[2] + 0.25)
    a["piece_position"] = position.astype(np.float32)
    charge = a["charge_position"][0]
    births, positions, velocities, systems, sizes = [], [], [], [], []
    for name, count, t_max, where, speed in (("dust", 4000, 2.0, "block", 6.0),
                                             ("smoke", 1000, 2.0, "block", 2.0),
                                             ("fireball", 300, 0.05, "charge", 15.0)):
        births.append(rng.uniform(0.0, t_max, count))
        base = (rng.uniform(lo, hi, (count, 3)) if where == "block"
                else np.repeat(charge[None], count, axis=0))
        positions.append(base)
        velocities.append(rng.normal(0.0, speed, (count, 3)))
        systems.append(np.full(count, SYSTEM_NAMES.index(name), dtype=np.uint8))
        sizes.append(np.full(count, dict(dust=0.15, smoke=0.6, fireball=0.8)[name]))
    order = np.argsort(np.concatenate(systems), kind="stable")
    a.update(particle_birth=np.concatenate(births)[order],
             particle_position=np.concatenate(positions)[order],
             particle_velocity=np.concatenate(velocities)[order],
             particle_system=np.concatenate(systems)[order],
             particle_size=np.concatenate(sizes)[order].astype(np.float32),
             shock_opacity=shock_opacity(a["shock_radius"], a["charge_tnt_kg"]),
             camera_offset=np.zeros((frames, 3)),
             voxel_ignite_frame=np.full(len(a["voxel_piece"]), -1, dtype=np.int32))
    meta = dict(cache.meta, ground_height=float(lo[2]), gravity_vector=[0.0, 0.0, -9.81],
                particle_systems=particle_meta())
    return SimCache(arrays=a, model=cache.model, meta=meta)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pieces", type=int, default=1000)
    parser.add_argument("--size", default="960x540")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs, best counts")
    args = parser.parse_args(argv)

    from blastvox.preview.api import prepare, preview
    from blastvox.preview.options import PreviewOptions, parse_frame_spec, parse_size

    size = parse_size(args.size)
    started = time.perf_counter()
    cache = preview_cache(args.pieces)
    build_s = time.perf_counter() - started
    frames = list(range(0, cache.frame_count, 5))
    print(machine(("blastvox", "numpy", "numba", "pillow", "imageio-ffmpeg")))
    print(f"\nSynthetic SimCache: {cache.piece_count:,} pieces, {cache.frame_count} frames, "
          f"{len(cache.particle_birth):,} particles (built in {build_s:.1f} s); "
          f"{len(frames)} frames per case at {size[0]}x{size[1]}, best of {args.repeat}.\n")
    print("| case | triangles | supersample | s/frame | CPU s/frame | target | result |")
    print("|---|--:|--:|--:|--:|---|---|")
    cases = [("pieces only", frozenset({"ground", "particles", "shock"}), 2),
             ("everything (default)", frozenset(), 2),
             ("everything, no anti-aliasing", frozenset(), 1)]
    for label, hide, ss in cases:
        options = PreviewOptions(size=size, supersample=ss, hide=hide)
        shot = prepare(cache, frames, options)
        shot.render(frames[0])  # warm-up: numba's cache load, buffers
        triangles = len(shot.scene.tri_local)
        best = cpu = float("inf")
        for _ in range(max(1, args.repeat)):
            t0, c0 = time.perf_counter(), time.process_time()
            for f in frames:
                shot.render(f)
            best = min(best, (time.perf_counter() - t0) / len(frames))
            cpu = min(cpu, (time.process_time() - c0) / len(frames))
        target = ss == 2 and not hide
        result = ("pass" if best < TARGET_S else "FAIL") if target else ""
        print(f"| {label} | {triangles:,} | {ss} | {best:.3f} | {cpu:.3f} | "
              f"{f'< {TARGET_S:g} s' if target else ''} | {result} |")
        sys.stdout.flush()

    print("\n| file | frames | s/frame (render + labels + encode + write) | size MB |")
    print("|---|--:|--:|--:|")
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in (".png", ".gif", ".mp4"):
            out = Path(tmp) / f"bench{suffix}"
            spec = "0:115:23" if suffix == ".png" else "0:119:5"
            options = PreviewOptions(size=size, frames=parse_frame_spec(spec))
            t0 = time.perf_counter()
            result = preview(cache, out, options)
            per = (time.perf_counter() - t0) / len(result.frames)
            print(f"| {suffix} | {len(result.frames)} | {per:.3f} | "
                  f"{out.stat().st_size / 1e6:.1f} |")
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
