"""The bundled example shots bake to the committed golden files (what a shot CI checks).

Goldens are small: each example's SimCache (examples/golden/<shot>.sim.npz, every
array of the simulation and of its VoxelModel) and the house's glTF export. A
behaviour change shows up here first; when it is intended, refresh them with
``make goldens`` and say why in the commit.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from blastvox.cache import SimCache

ROOT = Path(__file__).resolve().parent.parent
GOLDEN = ROOT / "examples" / "golden"
BLASTVOX = [sys.executable, "-m", "blastvox"]

pytestmark = pytest.mark.slow


def _bake(tmp_path: Path, shot: str) -> Path:
    """Run examples/<shot>/scene.toml in a copy under tmp_path; its output directory."""
    where = tmp_path / shot
    shutil.copytree(ROOT / "examples" / shot, where)
    scene = (where / "scene.toml").read_text().replace(f"../../out/{shot}/", "out/")
    (where / "scene.toml").write_text(scene)
    run = subprocess.run([*BLASTVOX, "run", "scene.toml", "-q"], cwd=where,
                         capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr
    # the shot stays within every limit of the simulator (a SimulationLimitWarning line)
    assert "blastvox: warning:" not in run.stderr, run.stderr
    return where / "out"


@pytest.fixture(scope="module")
def house_bake(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The house example baked once for this module (:func:`_bake`): its goldens test
    reads it, and the determinism tests simulate its model their own ways and compare
    with the golden cache's bytes. (The model must be ``run``'s: ``voxelize --scene``
    records the scene's settings in full, and the cache holds the model's meta.)"""
    return _bake(tmp_path_factory.mktemp("golden"), "house")


@pytest.fixture
def house(house_bake: Path) -> tuple[str, str]:
    """(model path, scene path) of the baked house."""
    return str(house_bake / "model.npz"), str(house_bake.parent / "scene.toml")


def _meta(cache: SimCache) -> dict:
    """The cache's and its model's meta, less the absolute mesh paths, which name the
    checkout (issue 18)."""
    model = dict(cache.model.meta)
    model["objects"] = [{k: v for k, v in o.items() if k != "source"}
                        for o in model.get("objects", [])]
    return {**cache.meta, "model": model}


def _arrays(cache: SimCache) -> dict[str, np.ndarray]:
    return {**cache.arrays, **{f"model.{k}": v for k, v in cache.model.arrays.items()}}


@pytest.mark.parametrize("shot", ["house", "building", "logo"])
def test_shot_matches_its_goldens(tmp_path: Path, shot: str,
                                  request: pytest.FixtureRequest) -> None:
    out = request.getfixturevalue("house_bake") if shot == "house" else _bake(tmp_path, shot)
    if shot == "house":  # the export layer too, as a shot CI diffs it
        diff = subprocess.run([*BLASTVOX, "diff", str(out / "shot.glb"),
                               str(GOLDEN / "house.glb"), "--atol", "1e-4"],
                              capture_output=True, text=True, timeout=600)
        assert diff.returncode == 0, diff.stdout + diff.stderr
    baked = SimCache.load(out / "sim.npz")
    golden = SimCache.load(GOLDEN / f"{shot}.sim.npz")
    assert _meta(baked) == _meta(golden)
    a, b = _arrays(baked), _arrays(golden)
    assert sorted(a) == sorted(b)
    for name in sorted(a):
        assert a[name].dtype == b[name].dtype and a[name].shape == b[name].shape, name
        if a[name].dtype.kind == "f":
            np.testing.assert_allclose(a[name], b[name], rtol=1e-6, atol=1e-4, err_msg=name)
        else:
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)



def test_blastvox_keeps_numpy_off_its_avx512_loops() -> None:
    """The goldens were baked on an AVX2 machine; numpy's AVX-512 exp, log and power
    round differently, which changed the logo's and building's pieces on an AVX-512
    Xeon. Importing blastvox first disables those dispatch targets (any machine)."""
    import os
    import subprocess
    import sys

    code = ("import blastvox, numpy\n"
            "from numpy._core import _multiarray_umath as m\n"
            "print([t for t in m.__cpu_dispatch__ if m.__cpu_features__.get(t)])\n")
    env = {k: v for k, v in os.environ.items() if k != "NPY_DISABLE_CPU_FEATURES"}
    # -W error: a name numpy does not dispatch would be an ImportWarning
    done = subprocess.run([sys.executable, "-W", "error", "-c", code], capture_output=True,
                          text=True, env=env, timeout=120, check=True)
    enabled = done.stdout.strip()
    assert "AVX512" not in enabled and "X86_V4" not in enabled, enabled


def test_the_library_after_numpy_scipy_and_trimesh_gives_the_cli_s_bytes(tmp_path, house):
    """Issue 37: a process that imported numpy (with scipy and trimesh) before blastvox
    kept numpy's AVX-512 loops, whose cube root and powers round differently: the papers'
    building had 748 pieces at 1 s against the CLI's 586. The simulator's inputs no
    longer go through numpy's dispatched loops (blastvox.blast._numeric), so the house
    simulated through the CLI's own entry point after those imports is the CLI's bytes
    (the golden cache). (On a CPU without AVX-512 both orders run the same loops; the
    test still holds.)"""
    model, scene = house
    first = tmp_path / "first.npz"
    code = ("import numpy, scipy.sparse, trimesh, sys\n"
            "from blastvox.cli.entry import run\n"
            f"sys.exit(run(['simulate', {model!r}, '--scene', {scene!r}, '-o', "
            f"{str(first)!r}, '-q']))\n")
    # OPENBLAS_CORETYPE as the CLI sets it: trimesh loads scipy's BLAS before blastvox
    # could pin its kernels (that case warns: test_simulate_warns_when_scipy_s_blas_...)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=900, env={**__import__("os").environ,
                                           "NPY_DISABLE_CPU_FEATURES": "",
                                           **({"OPENBLAS_CORETYPE": "Haswell"}
                                              if _avx512() else {})})
    assert run.returncode == 0, run.stderr
    assert first.read_bytes() == (GOLDEN / "house.sim.npz").read_bytes()


def test_one_thread_and_two_give_the_same_bytes(tmp_path, house):
    """Kernels that run on every core (numba's parallel loops: the wave's element views,
    blastvox.simulate.fracture.views_ahead, and the contact solve's islands,
    blastvox.simulate.contact.solver) write each iteration's own outputs and reduce
    nothing, so a shot is the same bytes on one core or two; the house dusts most of
    its voxels, so the views worked out again after dust opens the grid are covered
    too, and its rubble piles up on the ground."""
    import os

    model, scene = house
    for threads in ("1", "2"):
        out = tmp_path / f"threads{threads}.npz"
        run = subprocess.run([*BLASTVOX, "simulate", model, "--scene", scene, "-o",
                              str(out), "-q"], capture_output=True, text=True, timeout=900,
                             env={**os.environ, "NUMBA_NUM_THREADS": threads})
        assert run.returncode == 0, run.stderr
        assert out.read_bytes() == (GOLDEN / "house.sim.npz").read_bytes(), threads


def _avx512() -> bool:
    try:
        return "avx512f" in Path("/proc/cpuinfo").read_text()
    except OSError:
        return False


def test_blastvox_sets_its_thread_and_blas_defaults_and_leaves_a_users_alone():
    """Importing blastvox lets numba's OpenMP threads sleep (OMP_WAIT_POLICY=passive) and
    pins OpenBLAS to its Haswell kernels on an x86-64 CPU with AVX2 and FMA; a value the
    user set is kept."""
    import os

    code = ("import os, blastvox\n"
            "print(os.environ.get('OMP_WAIT_POLICY'), os.environ.get('OPENBLAS_CORETYPE'))\n")
    env = {k: v for k, v in os.environ.items()
           if k not in ("OMP_WAIT_POLICY", "OPENBLAS_CORETYPE")}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=120, check=True)
    flags = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").exists() else ""
    pinned = "Haswell" if " avx2" in flags and " fma" in flags else "None"
    assert done.stdout.split() == ["passive", pinned]
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**env, "OMP_WAIT_POLICY": "active", "OPENBLAS_CORETYPE": "Zen"},
                          timeout=120, check=True)
    assert done.stdout.split() == ["active", "Zen"]


@pytest.mark.skipif(not _avx512(), reason="OpenBLAS picks other kernels only on AVX-512")
def test_the_shot_does_not_depend_on_the_blas_kernels_numpy_picked(tmp_path, house):
    """The goldens differed between two AVX-512 EPYC hosts: numpy's and scipy's OpenBLAS
    picked their SkylakeX kernels on one, Haswell or Zen ones on the other, and ``@``,
    np.dot and the stress solver's sparse LU (SuperLU calls BLAS) rounded differently.
    Here numpy is loaded with SkylakeX kernels before blastvox: the shot is still the
    CLI's bytes, the golden cache's (the simulator's products do not go through numpy's
    BLAS, blastvox.geometry.exact; blastvox pins the kernels of the scipy BLAS loaded
    after it)."""
    import os

    model, scene = house
    first = tmp_path / "numpy_first.npz"
    code = ("import os, sys, numpy, numpy.linalg\n"
            "del os.environ['OPENBLAS_CORETYPE']\n"
            "from blastvox.cli.entry import run\n"
            f"sys.exit(run(['simulate', {model!r}, '--scene', {scene!r}, '-o', "
            f"{str(first)!r}, '-q']))\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=900, env={**os.environ, "OPENBLAS_CORETYPE": "SkylakeX"})
    assert run.returncode == 0, run.stderr
    assert first.read_bytes() == (GOLDEN / "house.sim.npz").read_bytes()


def test_simulate_warns_when_scipy_s_blas_came_first():
    """A process that imported scipy.linalg before blastvox (trimesh does) keeps the BLAS
    kernels its CPU picked: simulate() says so with a HostDependenceWarning; imported
    after blastvox, or with OPENBLAS_CORETYPE set by the user, it does not."""
    import os

    code = ("import warnings, {first}\n"
            "import blastvox\n"
            "from blastvox.simulate import engine\n"
            "with warnings.catch_warnings(record=True) as caught:\n"
            "    warnings.simplefilter('always')\n"
            "    engine._warn_if_host_dependent()\n"
            "print([type(w.message).__name__ for w in caught])\n")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}

    def caught(first: str, **extra: str) -> str:
        return subprocess.run([sys.executable, "-c", code.format(first=first)],
                              capture_output=True, text=True, timeout=120, check=True,
                              env={**env, **extra}).stdout.strip()

    assert caught("trimesh, scipy.sparse.linalg") == "['HostDependenceWarning']"
    assert caught("os") == "[]"
    assert caught("scipy.linalg", OPENBLAS_CORETYPE="Zen") == "[]"
