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
after numpy, scipy or trimesh were imported first (``tests/test_golden.py``).
"""

import os as _os
import sys as _sys

__version__ = "0.1.0"

#: numpy's AVX-512 dispatch targets, as numpy >= 2.4 names them (a name numpy does not
#: dispatch would be an ImportWarning, hence pyproject's numpy >= 2.4)
AVX512_FEATURES = "X86_V4 AVX512_ICL AVX512_SPR"

if "numpy" not in _sys.modules:
    _os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", AVX512_FEATURES)
