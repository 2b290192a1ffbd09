"""blastvox: connected-voxel blast-wave destruction for asset pipelines.

Stages: :mod:`blastvox.voxelize` (meshes -> VoxelModel), :mod:`blastvox.simulate`
(VoxelModel + scene -> SimCache), :mod:`blastvox.export` (SimCache -> USD/glTF).
Importing this package is cheap; heavy modules are imported by the stages.
"""

__version__ = "0.1.0"
