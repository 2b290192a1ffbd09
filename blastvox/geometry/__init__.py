"""Geometry shared by every stage, one module per concept: quaternions (numba and NumPy
faces), rigid transforms of bodies (rest <-> world), up-axis frames, and the face and
corner tables of the hexahedral voxel."""
