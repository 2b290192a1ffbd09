"""Geometry shared by every stage: quaternions and rigid transforms, up-axis frames,
voxel face and corner tables. NumPy faces for Python callers, numba faces for kernels."""
