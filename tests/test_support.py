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



def _beam_on_a_block(tmp_path: Path, length: float):
    """The beam of :func:`_beam_on_a_pier` laid on a free 1 x 0.5 x 0.5 m reinforced
    concrete block that sits on the pier: the beam touches nothing founded."""
    pier = trimesh.creation.box(extents=(1.0, 0.5, PIER_HEIGHT))
    pier.apply_translation((0.0, 0.0, PIER_HEIGHT / 2))
    block = trimesh.creation.box(extents=(1.0, 0.5, 0.5))
    block.apply_translation((0.0, 0.0, PIER_HEIGHT + 0.25))
    beam = trimesh.creation.box(extents=(length, 0.5, 0.25))
    beam.apply_translation((0.0, 0.0, PIER_HEIGHT + 0.625))
    requests = []
    for name, mesh, material in (("pier", pier, "reinforced_concrete"),
                                 ("block", block, "reinforced_concrete"),
                                 ("beam", beam, "concrete")):
        mesh.export(tmp_path / f"{name}.stl")
        requests.append(ObjectRequest(mesh=tmp_path / f"{name}.stl", voxel_size=(0.25,) * 3,
                                      material=material))
    return voxelize(requests, VoxelizeSettings(up_axis="Z", ground="auto", library=LIBRARY))


def test_a_beam_on_a_free_block_breaks_as_on_its_pier(tmp_path):
    """Issue 34 ("the lintel hangs"): a piece held up by another free piece carries its
    weight there as on a founded one. The 9 m beam laid on a free block on the pier
    breaks over the block (its moment, w L^2 / 2 of a 4 m cantilever, is the same all
    across the block) and its ends fall; before, a beam held up by free pieces was
    never solved (a cracked lintel's middle hung on its neighbour's ledge), and the
    3 m beam stays whole."""
    for length, breaks in ((9.0, True), (3.0, False)):
        model = _beam_on_a_block(tmp_path, length)
        beam = model.voxel_object == 2
        assert not model.voxel_foundation[model.voxel_object >= 1].any()
        cache = simulate(model, SimSettings(fps=24.0, duration=0.5))
        pieces = np.unique(cache.voxel_piece[beam])
        if not breaks:
            assert len(pieces) == 1
            continue
        assert len(pieces) >= 2  # it breaks over the block (hogging all across it)
        drop = cache.piece_position[0, pieces, 2] - cache.piece_position[-1, pieces, 2]
        assert (drop > 0.5).sum() >= 2, drop  # and both ends come down


def test_a_support_a_body_stood_on_is_not_judged_again_until_it_tilts():
    """A pile's contacts come and go from step to step: a body judged standing on a set
    of supporting voxels is not solved again when that set comes back, unless it has
    tilted by more than SAME_TILT since (its levers changed)."""
    from types import SimpleNamespace

    from blastvox.simulate.support import SAME_TILT, _stood_before

    stress = SimpleNamespace(judged={})
    down = np.array([0.0, 0.0, -9.81])
    on_two = np.array([3, 7]).tobytes()
    assert not _stood_before(stress, 5, on_two, down)
    stress.judged[5] = {on_two: [down]}
    assert _stood_before(stress, 5, on_two, down)
    assert not _stood_before(stress, 5, np.array([3]).tobytes(), down)  # lost a support
    assert not _stood_before(stress, 6, on_two, down)  # another body

    def tilted(angle: float) -> np.ndarray:
        return 9.81 * np.array([np.sin(angle), 0.0, -np.cos(angle)])

    assert _stood_before(stress, 5, on_two, tilted(0.5 * SAME_TILT))
    assert not _stood_before(stress, 5, on_two, tilted(1.5 * SAME_TILT))
