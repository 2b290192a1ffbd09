"""Voxelize benchmark: prints a markdown table of timings for the voxelize stage.

    python benchmarks/voxelize.py            # all cases (about a minute)
    python benchmarks/voxelize.py --quick    # small cases, one timed run each (~15 s)
    python benchmarks/voxelize.py --repeat 5 # best of 5 (default: 3, or 1 with --quick)

Each case runs in its own Python process (so the peak RSS column belongs to
that case alone), calls :func:`blastvox.voxelize.pipeline.voxelize` directly,
first does one warm-up run of the same mesh and shape at a tiny resolution
(imports, numba compilation or cache load), then reports the best of N timed
runs. Reading the mesh file is part of every timed run, writing the model is not.

Targets: the bunny at ~1M cube voxels in under 10 s, and the example building
in conform mode (~5,000 voxels) in under 5 s.

Many objects (issue 37): 1,000 separate 0.5 m cubes (one mesh file, 1,000 objects
placed by transforms, 1 m apart in a 10 x 10 x 10 grid) against the same cubes as one
mesh and one object, 0.125 m voxels (64,000 either way); target: the 1,000 objects
within 3 x the one object's time. And 10,000 objects of a scene: refused by the
objects budget (``--max-objects``, default 2,000) before any is read, in one line.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from _machine import machine, repeat_count  # benchmarks/ is on sys.path when run as a script

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
WARMUP_RESOLUTION = 12


@dataclass(frozen=True)
class Case:
    name: str
    mesh: Path
    shape: str
    resolution: int
    up_axis: str = "Y"
    quick: bool = False          # included in --quick
    target_s: float | None = None


CASES = [
    Case("bunny r60", DATA / "bunny.ply", "cube", 60, quick=True),
    Case("bunny r120", DATA / "bunny.ply", "cube", 120),
    Case("bunny r172 (~1M)", DATA / "bunny.ply", "cube", 172, target_s=10.0),
    # The bunny has small holes in its base: cube mode's winding number tolerates them,
    # conform mode needs a closed manifold and refuses it (reported as an error row).
    Case("bunny r40", DATA / "bunny.ply", "conform", 40, quick=True),
    # A closed CAD part, so there is a conform row at a moderate resolution anyway.
    Case("fandisk r40", DATA / "fandisk.obj", "conform", 40, quick=True),
    # As examples/building/scene.toml (same mesh, resolution, shape; no region rule).
    Case("building r40", DATA / "no_indices_3storybuilding.glb", "conform", 40, quick=True,
         target_s=5.0),
]


def peak_rss_mib() -> float:
    """Peak resident set size of this process so far, MiB."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 2**10  # bytes vs KiB


def run_case(case: Case, repeat: int) -> dict:
    """Warm up, then time ``repeat`` runs of one case (called in a worker process)."""
    from blastvox.errors import BlastvoxError
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    def once(resolution: int):
        request = ObjectRequest(mesh=case.mesh, resolution=resolution, shape=case.shape)
        return voxelize([request], VoxelizeSettings(up_axis=case.up_axis))

    try:
        once(WARMUP_RESOLUTION)
        seconds = []
        for _ in range(repeat):
            started = time.perf_counter()
            model = once(case.resolution)
            seconds.append(time.perf_counter() - started)
    except BlastvoxError as exc:
        return {"error": str(exc)}
    return {"voxels": model.voxel_count, "links": model.link_count, "seconds": seconds,
            "peak_rss_mib": peak_rss_mib()}


MANY_OBJECTS = 1000
MANY_SIZE = 0.125  # m
MANY_TARGET = 3.0  # x the one object's time


def many_objects(repeat: int) -> dict:
    """Time MANY_OBJECTS cubes as that many objects and as one (called in a worker)."""
    import tempfile

    import numpy as np
    import trimesh

    from blastvox.errors import BudgetError
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    side = round(MANY_OBJECTS ** (1 / 3))
    places = [(i, j, k + 0.25) for i in range(side) for j in range(side) for k in range(side)]
    cube = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    settings = VoxelizeSettings(up_axis="Z", ground="auto")
    out: dict = {}
    with tempfile.TemporaryDirectory(prefix="blastvox-bench-") as tmp:
        cube.export(Path(tmp) / "cube.stl")
        trimesh.util.concatenate([cube.copy().apply_translation(p) for p in places]).export(
            Path(tmp) / "cubes.stl")

        def placed(count: int) -> list:
            requests = []
            for n in range(count):
                move = np.eye(4)
                move[:3, 3] = places[n % len(places)]
                move[2, 3] += 10.0 * (n // len(places))
                requests.append(ObjectRequest(mesh=Path(tmp) / "cube.stl", name=f"cube{n}",
                                              voxel_size=(MANY_SIZE,) * 3, transform=move))
            return requests

        cases = {"one": [ObjectRequest(mesh=Path(tmp) / "cubes.stl",
                                       voxel_size=(MANY_SIZE,) * 3)],
                 "many": placed(len(places))}
        for name, requests in cases.items():
            voxelize(requests, settings)  # warm-up
            seconds = []
            for _ in range(repeat):
                started = time.perf_counter()
                model = voxelize(requests, settings)
                seconds.append(time.perf_counter() - started)
            out[name] = {"voxels": model.voxel_count, "objects": len(requests),
                         "seconds": min(seconds)}
        started = time.perf_counter()
        try:
            voxelize(placed(10 * len(places)), settings)
            out["refused"] = None
        except BudgetError as exc:
            out["refused"] = str(exc)
        out["refused_seconds"] = time.perf_counter() - started
    return out


def many_table(repeat: int) -> None:
    """Print the many-objects table (a worker process does the work)."""
    proc = subprocess.run([sys.executable, __file__, "--many", "--repeat", str(repeat)],
                          capture_output=True, text=True)
    print()
    print(f"### Many objects: {MANY_OBJECTS:,} cubes as {MANY_OBJECTS:,} objects and as one")
    print()
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"]
        print(f"worker crashed: {lines[-1]}")
        return
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    one, many = result["one"], result["many"]
    ratio = many["seconds"] / one["seconds"]
    print("| case | objects | voxels | seconds | x one object | target | result |")
    print("|---|--:|--:|--:|--:|---|---|")
    print(f"| one mesh | {one['objects']:,} | {one['voxels']:,} | {one['seconds']:.2f} | 1 | | |")
    print(f"| separate objects | {many['objects']:,} | {many['voxels']:,} | "
          f"{many['seconds']:.2f} | {ratio:.2f} | < {MANY_TARGET:g} x | "
          f"{'pass' if ratio < MANY_TARGET else 'FAIL'} |")
    print()
    refused = result["refused"] or "not refused"
    print(f"{10 * MANY_OBJECTS:,} objects: {refused} ({result['refused_seconds']:.2f} s)")


def run_in_subprocess(index: int, repeat: int) -> dict:
    proc = subprocess.run([sys.executable, __file__, "--worker", str(index),
                           "--repeat", str(repeat)], capture_output=True, text=True)
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"]
        return {"error": f"worker crashed: {lines[-1]}", "crashed": True}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="only the small cases")
    parser.add_argument("--repeat", type=int, help="timed runs per case, best of them counts "
                        "(default: 3, or 1 with --quick)")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--many", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    args.repeat = repeat_count(parser, args)
    if args.worker is not None:
        print(json.dumps(run_case(CASES[args.worker], args.repeat)))
        return 0
    if args.many:
        print(json.dumps(many_objects(args.repeat)))
        return 0

    print(machine(("blastvox", "numpy", "numba", "trimesh", "manifold3d")))
    print()
    runs = f"Best of {args.repeat} warm runs" if args.repeat > 1 else "One warm run"
    print(f"{runs} per case (after one warm-up run); "
          "targets: ~1M cube voxels < 10 s, building conform (~5k voxels) < 5 s.")
    print()
    print("| case | mode | voxels | links | seconds | voxels/s | peak RSS MiB | target "
          "| result |")
    print("|---|---|--:|--:|--:|--:|--:|---|---|")
    notes, crashed = [], False
    for index, case in enumerate(CASES):
        if args.quick and not case.quick:
            continue
        result = run_in_subprocess(index, args.repeat)
        target = f"< {case.target_s:g} s" if case.target_s else ""
        if "error" in result:
            crashed |= bool(result.get("crashed"))
            notes.append(f"{case.name} ({case.shape}): {result['error']}")
            print(f"| {case.name} | {case.shape} | — | — | — | — | — | {target} | "
                  f"error [{len(notes)}] |")
            continue
        best = min(result["seconds"])
        verdict = "" if case.target_s is None else (
            "pass" if best < case.target_s else "FAIL")
        print(f"| {case.name} | {case.shape} | {result['voxels']:,} | {result['links']:,} | "
              f"{best:.2f} | {result['voxels'] / best:,.0f} | {result['peak_rss_mib']:,.0f} | "
              f"{target} | {verdict} |", flush=True)
    for number, note in enumerate(notes, 1):
        if number == 1:
            print()
        print(f"[{number}] {note}")
    many_table(args.repeat)
    return 1 if crashed else 0


if __name__ == "__main__":
    sys.exit(main())
