"""First-run compilation: the forked child of simulate.warmup fills numba's cache with the
late phases, and an interrupted run does not wait for it."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.slow

SCRIPT = """
import sys, time, trimesh
from pathlib import Path
from blastvox.jit import KERNEL_CACHE
from blastvox.simulate.engine import Run
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.simulate.warmup import compile_ahead
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize
tmp = Path(sys.argv[1])
trimesh.creation.box(extents=(1.0, 0.5, 1.0)).export(tmp / "wall.stl")
model = voxelize([ObjectRequest(mesh=tmp / "wall.stl", voxel_size=(0.25,) * 3,
                                material="wood")], VoxelizeSettings(up_axis="Z"))
run = Run.start(model, SimSettings(duration=0.1, charges=(ChargeSpec((0, -2, 0.5), 1.0),)))
finish = compile_ahead(run)
started = time.perf_counter()
finish(cancel=sys.argv[2] == "cancel")
print(round(time.perf_counter() - started, 2))
print(KERNEL_CACHE)
"""


def _run(tmp_path: Path, mode: str) -> tuple[float, Path]:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path), mode], env=env,
                         capture_output=True, text=True, timeout=600, check=True)
    seconds, cache = out.stdout.split()
    return float(seconds), Path(cache)


def _cached(cache: Path, kernel: str) -> bool:
    return next(cache.rglob(f"{kernel}-*.nbi"), None) is not None


def test_the_child_compiles_the_late_phases_into_the_cache(tmp_path):
    seconds, cache = _run(tmp_path, "wait")
    for kernel in ("collide.collide_bodies", "ground.ground_contacts", "kernels.settle",
                   "integrate.integrate_positions", "integrate.integrate_velocities",
                   "fire.burn"):
        assert _cached(cache, kernel), kernel
    assert not _cached(cache, "forces.blast_impulses")  # an early phase: the parent's
    assert seconds > 1.0  # it did compile


def test_an_interrupted_run_does_not_wait_for_the_child(tmp_path):
    started = time.perf_counter()
    seconds, cache = _run(tmp_path, "cancel")
    assert seconds < 2.0
    assert not _cached(cache, "collide.collide_bodies")
    assert time.perf_counter() - started < 120
