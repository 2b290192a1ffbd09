"""Issue 37, item 4: an export is the same bytes from the library and from the CLI,
whatever was imported first and on whichever CPU.

numpy picks its float64 cbrt, exp, log, power, arctan2... loops by the CPU's features
when it is imported: importing blastvox first turns its AVX-512 ones off (the CLI does),
a process that imported numpy first keeps them, and they round differently (SVML). A
profiling run (numpy first) exported the house with other keys and vertices than the
CLI: the rubble's edge came from np.cbrt, the angular velocities from np.arctan2. The
export's arithmetic now goes through :mod:`blastvox.geometry.fixed` (libm) and
:mod:`blastvox.geometry.exact` (fixed-order sums), which the guard below keeps so.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOLDEN = ROOT / "examples" / "golden"
BLASTVOX = [sys.executable, "-m", "blastvox"]

#: what blastvox/__init__.py sets when it is imported before numpy
CLI_DISABLED = "X86_V4 AVX512_ICL AVX512_SPR"
#: numpy's dispatch targets, as the child process prints them
TARGETS = ("from numpy._core import _multiarray_umath as m\n"
           "print(sorted(t for t in m.__cpu_dispatch__ if m.__cpu_features__.get(t)))\n")


def _targets(code: str, env: dict[str, str]) -> str:
    done = subprocess.run([sys.executable, "-c", code + TARGETS], capture_output=True,
                          text=True, env=env, timeout=120, check=True)
    return done.stdout.strip().splitlines()[-1]


def test_the_library_after_numpy_on_other_cpu_features_exports_the_cli_s_bytes(tmp_path):
    """The house golden exported by the CLI, and by ``export()`` in a process that
    imported numpy, scipy and trimesh first with NPY_DISABLE_CPU_FEATURES set to
    something else than blastvox sets (all of numpy's targets on: AVX-512 on this CPU;
    on a CPU without AVX-512, AVX2 off as well), are the same bytes. It failed before
    the export used geometry.fixed: two vertices fewer (np.cbrt under AVX-512)."""
    env = {k: v for k, v in os.environ.items() if k != "NPY_DISABLE_CPU_FEATURES"}
    cli_targets = _targets("import blastvox\n", env)
    other = {**env, "NPY_DISABLE_CPU_FEATURES": ""}
    if _targets("import numpy\n", other) == cli_targets:  # no AVX-512: emulate an older CPU
        other["NPY_DISABLE_CPU_FEATURES"] = "X86_V3 " + CLI_DISABLED
    sim = GOLDEN / "house.sim.npz"
    (tmp_path / "cli").mkdir()
    (tmp_path / "lib").mkdir()
    cli, lib = tmp_path / "cli" / "house.glb", tmp_path / "lib" / "house.glb"
    run = subprocess.run([*BLASTVOX, "export", str(sim), "-o", str(cli), "-q"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    code = ("import numpy, scipy.sparse, trimesh\n"
            "from blastvox.cache import SimCache\n"
            "from blastvox.export.api import export\n"
            f"export(SimCache.load({str(sim)!r}), {str(lib)!r})\n" + TARGETS)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=other, timeout=600)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip().splitlines()[-1] != cli_targets  # numpy dispatched otherwise
    assert lib.read_bytes() == cli.read_bytes()


#: numpy functions whose float64 loops numpy dispatches by CPU (SVML under AVX-512) or
#: hands to BLAS, whose kernels OpenBLAS picks by CPU: not on the export's data
DISPATCHED = {"sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh",
              "tanh", "arcsinh", "arccosh", "arctanh", "exp", "exp2", "expm1", "log", "log2",
              "log10", "log1p", "logaddexp", "logaddexp2", "cbrt", "power", "float_power",
              "hypot", "einsum", "dot", "vdot", "inner", "matmul", "tensordot", "linalg"}
#: the export's modules and what they compute with (the numba kernels in them call libm)
EXPORT_PATH = [*sorted((ROOT / "blastvox" / "export").glob("*.py")),
               *sorted((ROOT / "blastvox" / "geometry").glob("*.py")),
               ROOT / "blastvox" / "particles.py", ROOT / "blastvox" / "damage_look.py"]
COMPILED = {"kernel", "helper", "parallel_kernel", "njit", "jit"}
#: a line may say why its ``@`` is not numpy's (a scipy.sparse product sums in order)
SPARSE_MARK = "# sparse:"


def _compiled(node: ast.AST) -> bool:
    for d in getattr(node, "decorator_list", []):
        target = d.func if isinstance(d, ast.Call) else d
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in COMPILED:
            return True
    return False


def _findings(path: Path) -> list[str]:
    source = path.read_text()
    lines = source.splitlines()
    found: list[str] = []

    def visit(node: ast.AST) -> None:
        if _compiled(node):
            return
        where = f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 0)}"
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id == "np" and node.attr in DISPATCHED):
            found.append(f"{where}: np.{node.attr}")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
            if SPARSE_MARK not in lines[node.lineno - 1]:
                found.append(f"{where}: @")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            # x ** 2 and ** 0.5 are numpy's exact square and sqrt; a literal base is
            # Python's arithmetic (libm), not numpy's
            if not (isinstance(node.left, ast.Constant)
                    or (isinstance(node.right, ast.Constant)
                        and node.right.value in (2, 0.5, 1, -1))):
                found.append(f"{where}: **")
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(source))
    return found


def test_the_export_computes_nothing_with_numpy_s_dispatched_loops_or_blas():
    """Every transcendental function, product and norm of the export path goes through
    blastvox.geometry.fixed (libm in compiled loops) or blastvox.geometry.exact (numpy's
    elementwise operations in a fixed order), or is in a numba kernel (libm): a numpy
    cbrt, exp, arctan2, einsum, np.linalg.norm or ``@`` there could round as the CPU
    numpy dispatched to (or the BLAS kernels OpenBLAS picked) and flip a key."""
    found = [f for path in EXPORT_PATH for f in _findings(path)]
    assert not found, "\n".join(found)
