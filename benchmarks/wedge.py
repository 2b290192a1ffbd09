"""Wedge throughput on Dask: a 16-shot wedge on a LocalCluster of 1 and of 2 workers.

    python benchmarks/wedge.py                 # 16 shots of the house, 1 and 2 workers
    python benchmarks/wedge.py --shots 8       # fewer shots
    python benchmarks/wedge.py --workers 1,2,4 # more cluster sizes

The wedge is ``examples/house/scene.toml`` (50 kg) over ``seed`` (16 values), each shot
through voxelize, simulate, export (.usda and .glb, as the scene says) and a
preview strip, exactly as ``blastvox wedge`` runs it. Before timing, one shot runs
in this process so the simulator's kernels are compiled and cached (a first run
on a cold cache would time compilation). For each cluster size a fresh output
directory: "start s" is the LocalCluster's start-up, "wedge s" the shots from
submission to the last result (each worker process pays its imports and kernel
loads in its first shot), "shots/min" the throughput and "speed-up" its ratio to
one worker. "same files" checks every shot's sim.npz against the one-worker run
(byte for byte). The last row re-runs the widest wedge: every shot is already
finished, so it only reads the results back.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "examples" / "house" / "scene.toml"


def _run(plan, workers: int) -> tuple[float, float, list[dict]]:
    from dask.distributed import Client, LocalCluster

    from blastvox.wedge.cluster import run_shots

    started = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.ERROR) as cluster, \
            Client(cluster) as client:
        client.wait_for_workers(workers)
        ready = time.perf_counter()
        results = run_shots(client, plan.shots)
        done = time.perf_counter()
    return ready - started, done - ready, results


def _digests(results: list[dict]) -> list[str]:
    return [hashlib.sha256((Path(r["directory"]) / "sim.npz").read_bytes()).hexdigest()
            for r in results]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shots", type=int, default=16)
    parser.add_argument("--workers", default="1,2", help="cluster sizes, comma-separated")
    args = parser.parse_args()
    from blastvox.wedge.plan import plan_wedge
    from blastvox.wedge.shot import run_shot

    sizes = [int(w) for w in args.workers.split(",")]
    # one charge (the scene's [wedge] table varies it too): the shots differ by seed only
    vary = ["charges.0.mass_kg=50", f"seed=0:{args.shots - 1}:{args.shots}"]
    print(machine(("blastvox", "numpy", "numba", "distributed")))
    print()
    print(f"{args.shots} shots of examples/house/scene.toml (50 kg; vary seed), each voxelize, "
          f"simulate, export .usda + .glb, preview strip.")
    print()
    print("| workers | start s | wedge s | shots/min | speed-up | same files |")
    print("|--:|--:|--:|--:|--:|---|")
    root = Path(tempfile.mkdtemp(prefix="blastvox-wedge-bench-"))
    try:
        warm = plan_wedge(SCENE, ["seed=1000,1001"], out=root / "warm")
        run_shot(warm.shots[0])
        base_rate, base_digests, plan = None, None, None
        for workers in sizes:
            plan = plan_wedge(SCENE, vary, out=root / f"w{workers}")
            start_s, wedge_s, results = _run(plan, workers)
            failed = [r for r in results if r["status"] != "ran"]
            if failed:
                raise SystemExit(f"{len(failed)} shots did not run: {failed[0]['error']}")
            rate = 60.0 * len(results) / wedge_s
            base_rate = base_rate or rate
            digests = _digests(results)
            base_digests = base_digests or digests
            same = "yes" if digests == base_digests else "NO"
            print(f"| {workers} | {start_s:.1f} | {wedge_s:.1f} | {rate:.1f} | "
                  f"{rate / base_rate:.2f} | {same} |")
        start_s, wedge_s, results = _run(plan, sizes[-1])
        cached = sum(r["status"] == "cached" for r in results)
        print(f"| {sizes[-1]}, re-run | {start_s:.1f} | {wedge_s:.2f} | "
              f"({cached} of {len(results)} up to date) | | |")
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
