"""numba's kernel cache is keyed on the source of every numba module (blastvox._kernel_cache),
so editing a helper recompiles the kernels that inline it without `make clean`."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from blastvox import _kernel_cache

ROOT = Path(__file__).resolve().parent.parent


def _package(tmp_path: Path, helper_body: str) -> Path:
    pkg = tmp_path / "pkg"
    pkg.mkdir(exist_ok=True)
    (pkg / "helpers.py").write_text(
        "import numba as nb\n\n@nb.njit(cache=True)\ndef twice(x):\n"
        f"    return {helper_body}\n")
    (pkg / "kernels.py").write_text(
        "import numba as nb\nfrom pkg.helpers import twice\n\n"
        "@nb.njit(cache=True)\ndef kernel(x):\n    return twice(x) + 1\n")
    (pkg / "cli.py").write_text("print('plain python')\n")
    return pkg


def test_the_key_changes_with_numba_modules_only(tmp_path):
    pkg = _package(tmp_path, "2 * x")
    key = _kernel_cache.source_hash(pkg)
    (pkg / "cli.py").write_text("print('still plain')\n")
    assert _kernel_cache.source_hash(pkg) == key
    (pkg / "helpers.py").write_text((pkg / "helpers.py").read_text().replace("2 * x", "3 * x"))
    assert _kernel_cache.source_hash(pkg) != key


def test_a_module_a_kernel_imports_is_part_of_the_key(tmp_path):
    # constants such as face tables are frozen into the compiled code
    pkg = _package(tmp_path, "2 * x")
    (pkg / "tables.py").write_text("FACTOR = 2\n")
    kernels = (pkg / "kernels.py").read_text()
    (pkg / "kernels.py").write_text(kernels.replace(
        "from pkg.helpers import twice\n",
        "from pkg.helpers import twice\nfrom pkg import tables\n"))
    key = _kernel_cache.source_hash(pkg)
    (pkg / "tables.py").write_text("FACTOR = 3\n")
    assert _kernel_cache.source_hash(pkg) != key


def test_every_numba_function_of_blastvox_caches_under_the_keyed_directory():
    # a module that decorated with numba before importing blastvox.jit would cache
    # beside its source, where edits of its helpers go unnoticed
    import importlib
    import pkgutil

    import blastvox
    from blastvox.jit import KERNEL_CACHE

    seen = 0
    for info in pkgutil.walk_packages(blastvox.__path__, "blastvox."):
        if info.name.startswith("blastvox.cli") or info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for value in vars(module).values():
            cache = getattr(getattr(value, "_cache", None), "_cache_path", None)
            if cache is not None and getattr(value, "__module__", "") == info.name:
                assert Path(cache).is_relative_to(KERNEL_CACHE), (info.name, cache)
                seen += 1
    assert seen > 30


def test_the_directory_follows_numba_cache_dir(tmp_path):
    pkg = _package(tmp_path, "2 * x")
    key = _kernel_cache.source_hash(pkg)
    assert _kernel_cache.cache_directory(pkg, {"NUMBA_CACHE_DIR": str(tmp_path / "c")}) == \
        tmp_path / "c" / f"blastvox-{key}"
    assert _kernel_cache.cache_directory(pkg, {"XDG_CACHE_HOME": str(tmp_path / "x")}) == \
        tmp_path / "x" / "blastvox" / "numba" / key


def test_a_child_process_shares_its_parents_cache(tmp_path):
    """configure() points NUMBA_CACHE_DIR at the keyed directory. A child process that
    inherits it (a CLI run from a script, a Dask worker of `blastvox wedge`) must use
    that same directory, not nest a second cache inside it and compile everything
    again; a NUMBA_CACHE_DIR set for the child still wins."""
    from blastvox.jit import KERNEL_CACHE

    code = "import blastvox.jit as j; print(j.KERNEL_CACHE)"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    inherited = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                               text=True, timeout=120, check=True).stdout.strip()
    assert Path(inherited) == KERNEL_CACHE
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "mine")
    explicit = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                              text=True, timeout=120, check=True).stdout.strip()
    key = KERNEL_CACHE.name.removeprefix("blastvox-")
    assert Path(explicit) == tmp_path / "mine" / f"blastvox-{key}"


def _run_kernel(pkg: Path, cache: Path) -> str:
    code = ("import sys; from pathlib import Path; from blastvox import _kernel_cache; "
            f"_kernel_cache.configure(Path({str(pkg)!r})); "
            "from pkg.kernels import kernel; print(kernel(5))")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache),
           "PYTHONPATH": os.pathsep.join([str(pkg.parent), str(ROOT)])}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=300, check=True)
    return out.stdout.strip()


@pytest.mark.slow
def test_editing_a_helper_recompiles_the_kernel_that_inlines_it(tmp_path):
    # plain numba would load kernel's stale cached code (it checks kernels.py only)
    pkg = _package(tmp_path, "2 * x")
    cache = tmp_path / "cache"
    assert _run_kernel(pkg, cache) == "11"
    assert _run_kernel(pkg, cache) == "11"  # from the cache
    (pkg / "helpers.py").write_text((pkg / "helpers.py").read_text().replace("2 * x", "3 * x"))
    assert _run_kernel(pkg, cache) == "16"


def test_old_directories_are_pruned(tmp_path):
    parent = tmp_path / "blastvox" / "numba"
    for i in range(6):
        old = parent / f"{i:016x}"
        old.mkdir(parents=True)
        os.utime(old, (i, i))
    current = parent / ("f" * 16)
    _kernel_cache._prune(current)
    left = sorted(p.name for p in parent.iterdir())
    assert left == [f"{4:016x}", f"{5:016x}"]  # with the current one, KEEP in all


def test_a_helper_called_from_python_raises_instead_of_crashing():
    # helpers have no CPython wrapper (faster first runs); numba would segfault
    from blastvox.jit import HelperDispatcher
    from blastvox.simulate.integrate import world_tensor_times

    assert isinstance(world_tensor_times, HelperDispatcher)
    eye = np.eye(3)
    with pytest.raises(TypeError, match="world_tensor_times is compiled for other numba"):
        world_tensor_times(eye, eye, 1.0, 2.0, 3.0)
    assert world_tensor_times.py_func(eye, eye, 1.0, 2.0, 3.0) == (1.0, 2.0, 3.0)


def test_a_constant_argument_compiles_no_copy_of_its_callee(tmp_path):
    # numba types a constant argument as its literal value and compiles the callee once per
    # value (32 copies, 8.5 s of a first run); blastvox.jit compiles one per argument type
    (tmp_path / "calls.py").write_text(
        "from blastvox.jit import helper, kernel\n\n"
        "@helper\ndef scaled(x, k):\n    return x * k\n\n"
        "@kernel\ndef scaled_k(x, k):\n    return x * k\n\n"
        "@kernel\ndef caller(x, k):\n"
        "    return scaled(x, 0) + scaled(x, 1) + scaled(x, k) + scaled_k(x, 2) + scaled_k(x, k)\n")
    code = ("import calls\nprint(calls.caller(2.0, 3))\n"
            "print(len(calls.scaled.signatures), len(calls.scaled_k.signatures))\n"
            "print(any('Literal' in str(s) for s in calls.scaled.signatures))")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=300, check=True, cwd=tmp_path)
    assert out.stdout.split() == ["18.0", "1", "1", "False"]
