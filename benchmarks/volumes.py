"""What particle volumes cost: .usdc export with volumes against spheres (markdown table).

    python benchmarks/volumes.py                         # the examples' caches in out/
    python benchmarks/volumes.py --shots truck logo      # some of them
    python benchmarks/volumes.py --voxel 0.1 0.2         # at these cell sizes (m)

Reads each shot's SimCache ``out/<shot>/sim.npz`` (``blastvox run
examples/<shot>/scene.toml`` writes it; a missing one is skipped) and exports it to a
temporary .usdc twice per cell size: ``--particles spheres`` (the PointInstancers) and
``--particles volumes`` (OpenVDB files per frame, ``blastvox/export/volumes.py``).
Columns: the particles of each system, the wall time and the process's CPU time of
each export (one run each, after a warm-up export that compiles or loads the splat
kernel), the .usdc's size, and the volumes folder's size and file count. It
reports and does not gate.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from _machine import machine  # benchmarks/ is on sys.path

ROOT = Path(__file__).resolve().parents[1]
SHOTS = ("house", "truck", "logo", "building")


def _export(cache, out: Path, particles: str, voxel: float) -> tuple[float, float]:
    from blastvox.export.api import ExportOptions, export

    started, cpu = time.perf_counter(), time.process_time()
    export(cache, out, ExportOptions(particles=particles, volume_voxel_m=voxel))
    return time.perf_counter() - started, time.process_time() - cpu


def _folder(path: Path) -> tuple[int, int]:
    files = [p for p in path.rglob("*") if p.is_file()] if path.is_dir() else []
    return sum(p.stat().st_size for p in files), len(files)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shots", nargs="*", default=list(SHOTS))
    parser.add_argument("--voxel", nargs="*", type=float, default=[0.1])
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    import numpy as np

    from blastvox.cache import SimCache
    from blastvox.particles import SYSTEM_NAMES

    print(machine())
    print()
    print("| shot | particles | cell m | spheres s (CPU) | .usdc MB | volumes s (CPU) "
          "| .usdc MB | volumes MB | .vdb files |")
    print("|---|---|--:|--:|--:|--:|--:|--:|--:|")
    warmed = False
    for shot in args.shots:
        sim = ROOT / "out" / shot / "sim.npz"
        if not sim.is_file():
            print(f"| {shot} | (no {sim.relative_to(ROOT)}: run `blastvox run "
                  f"examples/{shot}/scene.toml`) | | | | | | | |")
            continue
        cache = SimCache.load(sim)
        counts = np.bincount(cache.particle_system, minlength=len(SYSTEM_NAMES))
        systems = ", ".join(f"{n} {c:,}" for n, c in zip(SYSTEM_NAMES, counts.tolist(),
                                                           strict=True) if c)
        with tempfile.TemporaryDirectory(prefix="blastvox-volumes-") as tmp:
            if not warmed:
                _export(cache, Path(tmp) / "warm.usdc", "volumes", 1.0)
                warmed = True
            spheres = Path(tmp) / "spheres.usdc"
            s_wall, s_cpu = _export(cache, spheres, "spheres", args.voxel[0])
            for voxel in args.voxel:
                out = Path(tmp) / f"v{voxel}" / "shot.usdc"
                out.parent.mkdir()
                v_wall, v_cpu = _export(cache, out, "volumes", voxel)
                size, count = _folder(out.parent / "shot_volumes")
                print(f"| {shot} | {systems} | {voxel:g} | {s_wall:.1f} ({s_cpu:.1f}) | "
                      f"{spheres.stat().st_size / 1e6:.1f} | {v_wall:.1f} ({v_cpu:.1f}) | "
                      f"{out.stat().st_size / 1e6:.1f} | {size / 1e6:.1f} | {count} |")
                sys.stdout.flush()
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    raise SystemExit(main())
