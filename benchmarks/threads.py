"""Threads under load: the papers' building on one and two threads, on an idle machine
and beside one busy process, with numba's OpenMP threads spinning or sleeping.

    python benchmarks/threads.py [--dt 1/240] [--duration 5] [--repeat 1]

Needs ``out/building/model.npz`` (``blastvox run examples/building/scene.toml``).
Each case is a fresh Python process (``OMP_WAIT_POLICY`` and ``NUMBA_NUM_THREADS``
are read once, when numba loads libgomp) that loads numba's cached kernels with a
0.05 s warm-up shot, then times ``engine.simulate`` of the scene's shot (at ``--dt``,
for ``--duration`` s). "busy" runs one CPU-bound Python loop beside it for the whole
case, as a render or a second shot of ``make -j`` would. Every case must give the
same bytes (the sha256 of the pieces' positions is checked).

Why: libgomp's default (``OMP_WAIT_POLICY`` unset: active) spins a thread that waits
for the next parallel loop; with one other busy process on a 2-core machine, the
spinning threads and the other process took turns on the cores and two threads ran
2.5-3x slower than one. blastvox sets ``passive`` unless the user set a policy
(``blastvox/__init__.py``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from _machine import machine  # benchmarks/ is on sys.path when run as a script

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "examples" / "building" / "scene.toml"
MODEL = ROOT / "out" / "building" / "model.npz"

WORKER = """
import hashlib, json, sys, time
from dataclasses import replace
from blastvox.model import VoxelModel
from blastvox.scene import load_scene
from blastvox.simulate import engine
from blastvox.simulate.settings import settings_from_scene
scene, model_path, dt, duration = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
settings = replace(settings_from_scene(load_scene(scene), scene), dt=dt, duration=duration)
model = VoxelModel.load(model_path)
engine.simulate(model, replace(settings, duration=0.05))  # numba's cache, untimed
started = time.perf_counter()
cache = engine.simulate(model, settings)
seconds = time.perf_counter() - started
print(json.dumps({"seconds": seconds, "pieces": int(len(cache.piece_mass)),
                  "sha": hashlib.sha256(cache.piece_position.tobytes()).hexdigest()}))
"""

BUSY = "while True: pass"


def run_case(policy: str, busy: bool, threads: int, dt: float, duration: float) -> dict:
    """One case in a fresh process; its seconds, pieces and sha."""
    env = {**os.environ, "OMP_WAIT_POLICY": policy, "NUMBA_NUM_THREADS": str(threads),
           "PYTHONWARNINGS": "ignore"}
    spinner = subprocess.Popen([sys.executable, "-c", BUSY]) if busy else None
    try:
        done = subprocess.run([sys.executable, "-c", WORKER, str(SCENE), str(MODEL), repr(dt),
                               repr(duration)], env=env, capture_output=True, text=True,
                              check=True, timeout=3600)
    finally:
        if spinner is not None:
            spinner.kill()
            spinner.wait()
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dt", default="1/240", help="step, s, or a fraction (default 1/240)")
    parser.add_argument("--duration", type=float, default=5.0, help="shot length, s")
    parser.add_argument("--repeat", type=int, default=1, help="best of N per case")
    args = parser.parse_args(argv)
    if not MODEL.exists():
        print(f"{MODEL}: missing; run `blastvox run {SCENE}` first", file=sys.stderr)
        return 1
    num, _, den = args.dt.partition("/")
    dt = float(num) / float(den or 1)
    print(machine())
    print(f"\nexamples/building, {args.duration:g} s of shot at dt {args.dt} s, best of "
          f"{args.repeat}; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n")
    print("| OMP_WAIT_POLICY | machine | threads | s | x one thread, same row's machine |")
    print("|---|---|--:|--:|--:|")
    shas, one = set(), {}
    for policy in ("active", "passive"):
        for busy in (False, True):
            for threads in (1, 2):
                results = [run_case(policy, busy, threads, dt, args.duration)
                           for _ in range(args.repeat)]
                best = min(r["seconds"] for r in results)
                shas.update(r["sha"] for r in results)
                one.setdefault((policy, busy), best)
                print(f"| {policy} | {'one busy process' if busy else 'idle'} | {threads} | "
                      f"{best:.2f} | {one[(policy, busy)] / best:.2f} |", flush=True)
    same = len(shas) == 1
    digest = hashlib.sha256("".join(sorted(shas)).encode()).hexdigest()[:12]
    print(f"\nSame bytes in every case: {'yes' if same else 'NO'} ({digest}).")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
