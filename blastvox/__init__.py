"""blastvox: connected-voxel blast-wave destruction for asset pipelines.

Stages: :mod:`blastvox.voxelize` (meshes -> VoxelModel), :mod:`blastvox.simulate`
(VoxelModel + scene -> SimCache), :mod:`blastvox.export` (SimCache -> USD/glTF).
Importing this package is cheap; heavy modules are imported by the stages.
"""

from pathlib import Path as _Path

from blastvox import _kernel_cache

__version__ = "0.1.0"

#: numba's compiled kernels of this source tree (see :mod:`blastvox._kernel_cache`)
KERNEL_CACHE = _kernel_cache.configure(_Path(__file__).resolve().parent)
