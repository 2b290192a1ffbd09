"""What rubble faces cost: the example shots exported with rough and with voxel faces.

    python benchmarks/rubble.py               # best of 3
    python benchmarks/rubble.py --quick       # one timed export per row

The caches are the bundled goldens (``examples/golden/<shot>.sim.npz``: the
house, 156 voxels, 112 pieces; the papers' building, 4,314 conform voxels, 1,280
pieces), each exported with :func:`blastvox.export.api.export` to .usdc and .glb,
``fracture_faces`` "voxel" (the cells' faces) and "rough" (the default:
:mod:`blastvox.export.rubble`), best of N after a warm-up. Columns: export wall
time, file size, triangles of the pieces, the share of the fracture faces' area
whose normal is within 5 degrees of an axis (a voxel step), and rough over voxel
for time and size. No target: the issue asks for rubble that does not read as
voxel steps; this says what it costs.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _machine import machine, repeat_count

ROOT = Path(__file__).resolve().parent.parent
SHOTS = ("house", "building")


def stair_share(cache, mode: str) -> tuple[int, float]:
    """(triangles, share of fracture area facing along an axis within 5 degrees)."""
    from blastvox.export.pieces import piece_meshes

    m = piece_meshes(cache, "Y", mode)
    r = m.rest
    area = np.linalg.norm(np.cross(r[:, 1] - r[:, 0], r[:, 2] - r[:, 0]), axis=1)
    aligned = np.abs(m.normals).max(axis=1) > np.cos(np.radians(5.0))
    return len(r), float(area[m.damage & aligned].sum() / max(area[m.damage].sum(), 1e-300))


def timed_export(cache, path: Path, mode: str, repeat: int) -> float:
    from blastvox.export.api import ExportOptions, export

    options = ExportOptions(fracture_faces=mode)
    export(cache, path, options)  # warm-up
    best = np.inf
    for _ in range(repeat):
        started = time.perf_counter()
        export(cache, path, options)
        best = min(best, time.perf_counter() - started)
    return float(best)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=None)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    repeat = repeat_count(parser, args)
    from blastvox.cache import SimCache

    print(machine())
    print()
    print("| shot | file | faces | export s | MB | triangles | stepped fracture area | "
          "rough / voxel time | rough / voxel size |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for shot in SHOTS:
            cache = SimCache.load(ROOT / "examples" / "golden" / f"{shot}.sim.npz")
            shares = {mode: stair_share(cache, mode) for mode in ("voxel", "rough")}
            for suffix in (".usdc", ".glb"):
                row = {}
                for mode in ("voxel", "rough"):
                    path = Path(tmp) / f"{shot}_{mode}{suffix}"
                    seconds = timed_export(cache, path, mode, repeat)
                    row[mode] = (seconds, path.stat().st_size / 1e6)
                    triangles, share = shares[mode]
                    ratio = ("", "") if mode == "voxel" else (
                        f"{seconds / row['voxel'][0]:.2f}",
                        f"{row[mode][1] / row['voxel'][1]:.2f}")
                    print(f"| {shot} | {suffix} | {mode} | {seconds:.2f} | {row[mode][1]:.2f} | "
                          f"{triangles:,} | {share:.0%} | {ratio[0]} | {ratio[1]} |")
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
