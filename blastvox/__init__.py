"""blastvox: connected-voxel blast-wave destruction for asset pipelines.

Stages: :mod:`blastvox.voxelize` (meshes -> VoxelModel), :mod:`blastvox.simulate`
(VoxelModel + scene -> SimCache), :mod:`blastvox.export` (SimCache -> USD/glTF).
Importing this package is cheap; heavy modules are imported by the stages.

Importing it before numpy also keeps numpy off its AVX-512 loops
(``NPY_DISABLE_CPU_FEATURES``, unless already set): their exp, log, power and
trigonometric functions round differently from the AVX2 ones, and a shot's
chaotic fracture turns one ulp into different pieces. The simulator does not rely
on it: its inputs' cube roots, powers and the cues' transcendentals go through
libm (:mod:`blastvox.blast._numeric`), so ``simulate()`` gives the CLI's bytes
after numpy, scipy or trimesh were imported first (``tests/test_golden.py``). Nor does
the export: its transcendental functions go through libm as well
(:mod:`blastvox.geometry.fixed`), its sums and products through
:mod:`blastvox.geometry.exact`, so ``export()`` after numpy gives the CLI's bytes
(``tests/test_export_dispatch.py``).

It also pins OpenBLAS's kernels to its Haswell ones (``OPENBLAS_CORETYPE``, unless
set) on an x86-64 CPU that has AVX2 and FMA, for the BLAS libraries loaded after it:
the stress solver's sparse LU (scipy's SuperLU) calls BLAS, whose kernels OpenBLAS
picks by CPU (SkylakeX on an AVX-512 EPYC, Haswell or Zen on another), and they round
differently. The simulator's own small products do not go through BLAS
(:mod:`blastvox.geometry.exact`). A process that imported scipy.linalg before
blastvox (trimesh does) keeps that library's choice, and ``simulate()`` says so
(:class:`~blastvox.errors.HostDependenceWarning`); the CLI always imports blastvox
first, and so does every benchmark that imports ``benchmarks/_machine.py`` first.

And it lets numba's OpenMP threads sleep between parallel loops
(``OMP_WAIT_POLICY=passive``, unless set): libgomp's default spins them, and on a
2-core machine with one other busy process (a render, a second shot of ``make -j``)
the spinning threads and that process took turns on the cores: the papers' building
ran 1.7x slower on two threads than on one. The price is in small scenes, whose steps
are many tiny parallel loops: 100 pieces' contacts 1.7x slower (docs/benchmarks.md,
"Threads under load"; ``GOMP_SPINCOUNT=10000`` wins that back, not made the default).
"""

import os as _os
import sys as _sys

__version__ = "0.1.0"

#: numpy's AVX-512 dispatch targets, as numpy >= 2.4 names them (a name numpy does not
#: dispatch would be an ImportWarning, hence pyproject's numpy >= 2.4)
AVX512_FEATURES = "X86_V4 AVX512_ICL AVX512_SPR"

#: OpenBLAS's kernels for every x86-64 CPU with AVX2 and FMA (the goldens' rounding)
OPENBLAS_CORE = "Haswell"

if "numpy" not in _sys.modules:
    _os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", AVX512_FEATURES)


def _has_avx2_fma() -> bool:
    """Whether /proc/cpuinfo lists avx2 and fma (False where it cannot be read): the
    Haswell kernels would stop an older CPU with an illegal instruction."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as info:
            for line in info:
                if line.startswith("flags"):
                    flags = set(line.split(":", 1)[1].split())
                    return {"avx2", "fma"} <= flags
    except OSError:
        pass
    return False


_os.environ.setdefault("OMP_WAIT_POLICY", "passive")  # read when numba loads libgomp

#: scipy's BLAS was loaded before blastvox with no OPENBLAS_CORETYPE set: it keeps the
#: kernels its CPU picked, which the stress solver's sparse LU calls (simulate() warns)
SCIPY_BLAS_FIRST = ("OPENBLAS_CORETYPE" not in _os.environ
                    and any(name in _sys.modules
                            for name in ("scipy.linalg", "scipy.sparse.linalg")))

if _sys.platform.startswith("linux") and _has_avx2_fma():
    _os.environ.setdefault("OPENBLAS_CORETYPE", OPENBLAS_CORE)
