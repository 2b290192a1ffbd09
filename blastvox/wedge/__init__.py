"""Wedges: one scene run over a grid of parameter values, each variant a shot, on Dask.

An artist tunes a shot by running it over several values of a few keys (charge
mass, seed, a material strength, voxel size, time step). A wedge expands
``--vary KEY=VALUES`` options (or the scene's ``[wedge]`` table) into the grid of
their values, or a seeded random sample of it (:mod:`blastvox.wedge.plan`), keys
every variant by a content hash of everything that makes its files
(:mod:`blastvox.wedge.digest`), and runs each one as a task on a Dask cluster
(:mod:`blastvox.wedge.cluster`): voxelize, simulate, export and a preview strip
(:mod:`blastvox.wedge.shot`). Finished variants are skipped on a re-run, so an
interrupted wedge resumes. The summary table and a contact sheet of the variants
side by side come from :mod:`blastvox.wedge.report`.

Modules: ``values`` (the VALUES syntax), ``keys`` (KEY paths into the scene file),
``plan``, ``digest``, ``shot`` (what a worker runs), ``cluster``, ``report``.
"""
