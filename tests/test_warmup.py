"""First-run compilation: the forked child of simulate.warmup fills numba's cache with the
late phases, and an interrupted run does not wait for it."""

from __future__ import annotations

import os
import subprocess
import sys
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
deadline = time.monotonic() + 300  # the child's first late phase reaches the cache
while not any(KERNEL_CACHE.rglob("integrate.integrate_velocities-*.nbi")):
    assert time.monotonic() < deadline, "the child compiled nothing"
    time.sleep(0.02)
started = time.perf_counter()
finish(cancel=True)  # as Ctrl-C does: stop the child half-way through the late phases
print(round(time.perf_counter() - started, 2))
print(KERNEL_CACHE)
"""


def _cached(cache: Path, kernel: str) -> bool:
    return next(cache.rglob(f"{kernel}-*.nbi"), None) is not None


def test_the_child_compiles_the_late_phases_and_a_cancel_stops_it(tmp_path):
    """On a cold cache (its own NUMBA_CACHE_DIR) the forked child compiles the late phases
    first-needed first into the cache, never an early phase (the parent's, which here
    compiles nothing), and a cancelled run stops it at once instead of waiting."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path)], env=env,
                         capture_output=True, text=True, timeout=600, check=True)
    seconds, cache = out.stdout.split()
    cache = Path(cache)
    assert float(seconds) < 2.0
    assert _cached(cache, "integrate.integrate_velocities")
    # the next: the contact solver (the longest, compiled first), stopped half-way
    assert not _cached(cache, "solver._solve_islands")
    assert not _cached(cache, "broadphase._search")
    assert not _cached(cache, "forces.blast_impulses")  # an early phase: the parent's


def test_the_late_phases_run_on_a_run_with_every_effect(tmp_path):
    """compile_late_phases calls each late phase the way a step does (in-process, on the
    session's warm cache: a wrong call in the child would only show as its exit code 1)."""
    import numpy as np
    import trimesh

    from blastvox.simulate.engine import Run
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.simulate.warmup import compile_late_phases
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    trimesh.creation.box(extents=(1.0, 0.5, 1.0)).export(tmp_path / "wall.stl")
    model = voxelize([ObjectRequest(mesh=tmp_path / "wall.stl", voxel_size=(0.25,) * 3,
                                    material="wood")], VoxelizeSettings(up_axis="Z"))
    run = Run.start(model, SimSettings(duration=0.1, charges=(ChargeSpec((0, -2, 0.5), 1.0),)))
    assert run.settings.collisions and run.ground is not None and run.fire is not None
    compile_late_phases(run)
    assert np.isfinite(run.state.bodies.pos).all() and np.isfinite(run.state.bodies.lin).all()
    # the solver compiled on a stand-in memory first; the phases then made the real one
    assert len(run.state.contacts.memory.half) == model.voxel_count
