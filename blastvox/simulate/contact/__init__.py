"""Contacts: fragments against fragments, founded bodies and the ground, in one solve.

A step's contact pipeline, module by module:

- :mod:`~blastvox.simulate.contact.pairs`: the broad phase, spatial hashes of
  boundary voxels (moving bodies each step, resting ones kept);
- :mod:`~blastvox.simulate.contact.fragments`: the narrow phase (voxel boxes,
  face-clipped manifolds) and the fragment contact phase
  (:func:`~blastvox.simulate.contact.fragments.collide_phase`), impacts, resting
  damping, and the parts of a breaking member moving together while a wave passes;
- :mod:`~blastvox.simulate.contact.ground`: the rows' containers (ContactRows,
  ContactMemory, SolverParams), the ground's rows, its balance test and phase;
- :mod:`~blastvox.simulate.contact.solver`: sequential impulses over all rows,
  warm started, with a position pass;
- :mod:`~blastvox.simulate.contact.loads`: what the contacts push into founded
  bodies, carried by their links or punching chunks out.

Sleeping is :func:`blastvox.simulate.kernels.settle`.
"""
