"""The kernel manifest behind first-run parallel compilation."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from blastvox.simulate.precompile import (
    FEATURES,
    Kernel,
    argument_types,
    dispatcher,
    ensure_compiled,
    load_manifest,
    partition,
)

# the kernels the reference scenes call from Python, seen from a fresh process
# with a warm cache (where only calls from Python load anything)
_SEEN = textwrap.dedent("""
    import json, tempfile
    from pathlib import Path
    from blastvox.simulate.precompile import called_kernels, reference_runs
    with tempfile.TemporaryDirectory() as tmp:
        print(json.dumps(sorted(called_kernels(reference_runs(Path(tmp))))))
""")


def _python(code: str) -> str:
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, "PYTHONHASHSEED": "0"})
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_manifest_names_real_kernels_and_types():
    kernels = load_manifest()
    assert kernels
    for kernel in kernels:
        assert kernel.feature in FEATURES
        disp = dispatcher(kernel.name)
        assert hasattr(disp, "compile"), kernel.name
        args = argument_types(kernel.signature)
        assert str(args) == kernel.signature  # reads back to what numba printed


def test_manifest_covers_what_the_simulator_compiles():
    # warm the cache for the manifest (a no-op when it is warm), then run the
    # reference scenes in a fresh process: what they load from Python must be
    # exactly the manifest, or a first run would compile kernels one by one
    _python("from blastvox.simulate.precompile import FEATURES, ensure_compiled; "
            "ensure_compiled(set(FEATURES))")
    seen = {tuple(pair) for pair in json.loads(_python(_SEEN).splitlines()[-1])}
    listed = {(k.name, k.signature) for k in load_manifest()}
    assert seen - listed == set(), "compiled but not in the manifest: re-record it"
    assert listed - seen == set(), "in the manifest but not compiled: re-record it"


def test_partition_balances_and_is_deterministic():
    kernels = [Kernel("core", s, f"m.k{i}", "()") for i, s in
               enumerate([9.0, 7.0, 5.0, 4.0, 3.0, 2.0, 1.0, 1.0])]
    shares = partition(kernels, 2)
    assert sorted(k.name for share in shares for k in share) == sorted(k.name for k in kernels)
    loads = [sum(k.seconds for k in share) for share in shares]
    assert abs(loads[0] - loads[1]) <= 1.0  # 32 s of work split 16 / 16
    assert partition(kernels, 2) == shares
    assert partition(kernels, 1) == [sorted(kernels, key=lambda k: -k.seconds)]


@pytest.mark.parametrize("fork", [True, False], ids=["forked", "new-interpreter"])
def test_workers_fill_the_cache_a_later_process_loads(tmp_path, fork):
    # the fire and damage kernels (a probe, then one for this process and one for
    # a worker) compiled into an empty cache: a fresh process then loads every
    # one of them, compiling none. Workers are forked on Linux; elsewhere (or in a
    # process with threads) they are new interpreters.
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    code = ("import blastvox.simulate.precompile as p; "
            f"p._can_fork = lambda: {fork}; "
            "print(p.ensure_compiled({'fire', 'damage'}, processes=2))")
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env=env)
    assert first.returncode == 0, first.stderr
    assert first.stdout.strip() == "True"
    check = textwrap.dedent("""
        from blastvox.simulate.precompile import compile_kernels, load_manifest
        print(compile_kernels([k for k in load_manifest() if k.feature in ('fire', 'damage')]))
    """)
    second = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True,
                            env=env)
    assert second.returncode == 0, second.stderr
    assert second.stdout.strip() == "0"


def test_a_warm_cache_compiles_nothing():
    ensure_compiled({"fire"})  # warm (in this process or on disk)
    assert ensure_compiled({"fire"}) is False


def test_simulate_passes_the_first_run_notice_to_its_progress(monkeypatch, tmp_path):
    # what `blastvox run` and `blastvox simulate` print while a cold cache compiles
    import trimesh

    from blastvox.simulate import run as simrun
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    def cold(features, notify=None, processes=None):
        notify(f"compiling {sorted(features)}")
        return True

    monkeypatch.setattr(simrun, "ensure_compiled", cold)
    mesh = tmp_path / "cube.stl"
    trimesh.creation.box(extents=(1, 1, 1)).export(mesh)
    model = voxelize([ObjectRequest(mesh=mesh, voxel_size=(0.5,) * 3, material="brick")],
                     VoxelizeSettings(up_axis="Z"))
    lines: list[str] = []
    settings = SimSettings(duration=0.05, collisions=False,
                           charges=(ChargeSpec((0.0, -3.0, 0.0), 1.0),))
    simrun.simulate(model, settings, progress=simrun.Progress(notes=lines.append))
    assert lines == ["compiling ['core', 'ground']"]


def test_a_helper_called_from_python_raises_instead_of_crashing():
    # helpers have no CPython wrapper (faster first runs); numba would segfault
    from blastvox.jit import HelperDispatcher
    from blastvox.simulate.integrate import world_tensor_times

    assert isinstance(world_tensor_times, HelperDispatcher)
    eye = np.eye(3)
    with pytest.raises(TypeError, match="world_tensor_times is compiled for other numba"):
        world_tensor_times(eye, eye, 1.0, 2.0, 3.0)
    assert world_tensor_times.py_func(eye, eye, 1.0, 2.0, 3.0) == (1.0, 2.0, 3.0)
