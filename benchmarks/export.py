"""Export benchmark: 1,000 pieces x 120 frames to .usdc, .usda and .glb (markdown table).

    python benchmarks/export.py               # best of 3
    python benchmarks/export.py --repeat 1
    python benchmarks/export.py --pieces 8000 # a bigger shot

The SimCache is synthetic (so the benchmark takes seconds, not a long
simulation): a cube of 0.25 m voxels cut into blocks of 2x2x2 voxels, one piece
per block (48 triangles each), every piece flying off ballistically and
tumbling for the whole shot, so no time sample can be pruned (the worst case
for the USD writer). A tenth of the pieces vanish part-way and turn into dust
(8 emitters each), a fifth of the voxels get three damage steps, and one
charge's shock front grows. Timings are of
:func:`blastvox.export.api.export` alone (the cache is built once), best of N;
the first run per format is a warm-up. "seconds" is wall time, "CPU s" the
process's CPU time (all threads), which a busy machine disturbs less. Target:
under 3 s for .usdc and .glb. The load average is printed with the machine.
The .glb row is skipped if :mod:`blastvox.export.gltf` is not there.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _machine import machine  # benchmarks/ is on sys.path when run as a script

TARGET_S = {".usdc": 3.0, ".glb": 3.0}


def synthetic_cache(pieces: int = 1000, frames: int = 120, fps: float = 24.0, seed: int = 0):
    """A deterministic SimCache with ``pieces`` moving 2x2x2-voxel pieces (see module doc)."""
    import trimesh

    from blastvox.cache import SimCache
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    voxel = 0.25
    k = max(1, round(pieces ** (1.0 / 3.0)))
    while k ** 3 < pieces:
        k += 1
    side = 2 * k * voxel
    with tempfile.TemporaryDirectory() as tmp:
        mesh = Path(tmp) / "block.stl"
        trimesh.creation.box(extents=(side,) * 3).export(mesh)
        model = voxelize([ObjectRequest(mesh=mesh, voxel_size=(voxel,) * 3, material="brick")],
                         VoxelizeSettings(up_axis="Z", ground=None))
    a = model.arrays
    block = (a["voxel_ijk"].astype(np.int64) // 2) @ np.array([k * k, k, 1])
    piece = (block * pieces // k ** 3).astype(np.int32)
    n = model.voxel_count
    mass = np.bincount(piece, weights=a["voxel_mass"], minlength=pieces)
    pivot = np.stack([np.bincount(piece, weights=a["voxel_mass"] * a["voxel_centroid"][:, i],
                                  minlength=pieces) for i in range(3)], axis=1) / mass[:, None]

    rng = np.random.default_rng(seed)
    t = np.arange(frames) / fps
    velocity = rng.normal(0.0, 5.0, (pieces, 3))
    gravity = np.array([0.0, 0.0, -9.81])
    position = pivot[None] + t[:, None, None] * velocity[None] + 0.5 * t[:, None, None] ** 2 \
        * gravity
    axis = rng.normal(size=(pieces, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    half = 0.5 * rng.uniform(1.0, 20.0, pieces)[None] * t[:, None]
    orientation = np.concatenate([np.cos(half)[..., None], np.sin(half)[..., None] * axis[None]],
                                 axis=-1)
    end = np.full(pieces, frames, dtype=np.int32)
    gone = rng.random(pieces) < 0.1
    end[gone] = rng.integers(1, max(frames, 2), int(gone.sum()))
    destroyed = np.where(end[piece] < frames, end[piece], -1).astype(np.int32)
    dust = np.flatnonzero(destroyed >= 0)
    dust_frame = destroyed[dust]
    damaged = np.flatnonzero(rng.random(n) < 0.2)
    steps = np.sort(rng.integers(0, frames, (len(damaged), 3)), axis=1)
    d_frame = steps.ravel().astype(np.int32)
    d_voxel = np.repeat(damaged, 3).astype(np.int32)
    d_value = np.tile(np.array([85, 170, 255], np.uint8), len(damaged))
    order = np.lexsort((d_voxel, d_frame))
    i4, f8 = np.zeros(0, np.int32), np.zeros(0)
    arrays = {
        "frame_time": t, "voxel_piece": piece, "piece_pivot": pivot, "piece_mass": mass,
        "piece_position": position.astype(np.float32),
        "piece_orientation": orientation.astype(np.float32), "piece_end_frame": end,
        "voxel_destroyed_frame": destroyed,
        "damage_frame": d_frame[order], "damage_voxel": d_voxel[order],
        "damage_value": d_value[order],
        "link_break_link": i4, "link_break_time": f8,
        "dust_voxel": dust.astype(np.int32), "dust_time": t[dust_frame],
        "dust_mass": a["voxel_mass"][dust],
        "dust_position": position[dust_frame, piece[dust]].astype(np.float64),
        "dust_velocity": velocity[piece[dust]] + gravity * t[dust_frame, None],
        "charge_position": np.array([[0.0, -2.0 * side, 0.5 * side]]),
        "charge_tnt_kg": np.array([10.0]), "charge_time": np.array([0.0]),
        "shock_radius": (340.0 * t)[:, None],
    }
    settings = {"gravity": 9.81, "fps": fps}
    return SimCache(arrays=arrays, model=model,
                    meta={"fps": fps, "duration": float(t[-1]), "settings": settings})


def _has_gltf() -> bool:
    try:
        import blastvox.export.gltf  # noqa: F401
    except ImportError:
        return False
    return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pieces", type=int, default=1000)
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--repeat", type=int, default=3, help="timed runs, best counts")
    args = parser.parse_args(argv)

    from blastvox.export.api import ExportOptions, export

    started = time.perf_counter()
    cache = synthetic_cache(args.pieces, args.frames)
    build_s = time.perf_counter() - started
    cases = [(".usdc", "xforms"), (".usda", "xforms"), (".usdc", "instancer")]
    if _has_gltf():
        cases.append((".glb", "xforms"))
    print(machine(("blastvox", "numpy", "usd-core")))
    print(f"\nSynthetic SimCache: {cache.piece_count:,} pieces, {cache.frame_count} frames, "
          f"{cache.model.voxel_count:,} voxels, {len(cache.dust_voxel):,} dust emitters, "
          f"{len(cache.damage_frame):,} damage events (built in {build_s:.1f} s); "
          f"best of {args.repeat}.\n")
    print("| format | layout | seconds | CPU s | size MB | target | result |")
    print("|---|---|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for suffix, layout in cases:
            out = Path(tmp) / f"bench{suffix}"
            options = ExportOptions(up_axis="Y", layout=layout)
            export(cache, out, options)  # warm-up
            best = cpu = float("inf")
            for _ in range(max(1, args.repeat)):
                t0, c0 = time.perf_counter(), time.process_time()
                export(cache, out, options)
                best = min(best, time.perf_counter() - t0)
                cpu = min(cpu, time.process_time() - c0)
            target = TARGET_S.get(suffix) if layout == "xforms" else None
            result = "" if target is None else ("pass" if best < target else "FAIL")
            print(f"| {suffix} | {layout} | {best:.2f} | {cpu:.2f} | "
                  f"{out.stat().st_size / 1e6:.1f} | "
                  f"{'' if target is None else f'< {target:g} s'} | {result} |")
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
