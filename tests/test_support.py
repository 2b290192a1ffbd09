"""A free body held up by what is left of a structure carries its weight to its supports.

A piece that breaks off a structure and rests on, leans on or hangs from a founded
body used to be a rigid body, whatever its span: a slab that lost its columns could
rest on half its length (issue 34: "freed pieces hang"). Its links are now solved
under its weight on the voxels that touch the ground or a founded body
(:func:`blastvox.simulate.support.support_phase`), against beam theory here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from blastvox.materials import MaterialLibrary
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

LIBRARY = MaterialLibrary.builtin()
PIER_HEIGHT = 2.0


def _beam_on_a_pier(tmp_path: Path, length: float):
    """A free plain concrete beam (length x 0.5 x 0.25 m) lying across the middle of a
    founded 1 x 0.5 x 2 m pier: two cantilevers of (length - 1) / 2 m."""
    pier = trimesh.creation.box(extents=(1.0, 0.5, PIER_HEIGHT))
    pier.apply_translation((0.0, 0.0, PIER_HEIGHT / 2))
    beam = trimesh.creation.box(extents=(length, 0.5, 0.25))
    beam.apply_translation((0.0, 0.0, PIER_HEIGHT + 0.125))
    pier.export(tmp_path / "pier.stl")
    beam.export(tmp_path / "beam.stl")
    return voxelize([ObjectRequest(mesh=tmp_path / "pier.stl", voxel_size=(0.25,) * 3,
                                   material="reinforced_concrete"),
                     ObjectRequest(mesh=tmp_path / "beam.stl", voxel_size=(0.25,) * 3,
                                   material="concrete")],
                    VoxelizeSettings(up_axis="Z", ground="auto", library=LIBRARY))


def _utilization(length: float) -> float:
    """Beam theory: the root moment of a cantilever of (length - 1) / 2 m under its own
    weight, w L^2 / 2, over the section's elastic modulus b h^2 / 6, over concrete's
    tensile strength."""
    concrete = LIBRARY["concrete"]
    w = concrete.density * 0.5 * 0.25 * 9.81
    cantilever = (length - 1.0) / 2.0
    return (w * cantilever ** 2 / 2.0) / (0.5 * 0.25 ** 2 / 6.0) / concrete.tensile_strength


def _run(tmp_path: Path, length: float):
    model = _beam_on_a_pier(tmp_path, length)
    beam = model.voxel_object == 1
    assert not model.voxel_foundation[beam].any() and model.voxel_foundation[~beam].any()
    cache = simulate(model, SimSettings(fps=24.0, duration=0.5))
    return model, beam, cache


def test_a_beam_that_beam_theory_breaks_breaks_on_its_support(tmp_path):
    """A 9 m beam on a 1 m pier: 4 m cantilevers at 1.5 x their cracking moment. It breaks
    over the pier and its ends fall; before, it lay whole on the pier."""
    assert _utilization(9.0) > 1.4
    model, beam, cache = _run(tmp_path, 9.0)
    assert cache.meta["broken_links"] > 0
    pieces = np.unique(cache.voxel_piece[beam])
    assert len(pieces) >= 3  # both cantilevers come off
    drop = cache.piece_position[0, pieces, 2] - cache.piece_position[-1, pieces, 2]
    assert (drop > 0.5).sum() >= 2, drop


def test_a_short_beam_stays_whole_on_its_support(tmp_path):
    """A 3 m beam on the pier: 1 m cantilevers at a tenth of their cracking moment."""
    assert _utilization(3.0) < 0.2
    model, beam, cache = _run(tmp_path, 3.0)
    assert cache.meta["broken_links"] == 0
    assert len(np.unique(cache.voxel_piece[beam])) == 1

