"""Separate objects resting on each other stay at rest at any voxel size (issue 33).

Each object is voxelized on its own lattice, so where a voxel size does not divide an
object, its boundary cells reach past its mesh (a 0.5 m block in 0.3 m cubes is two
cells, 0.6 m). With contact boxes of whole cells, a block set on a base started up to
0.15 m inside it and was pushed out at the first step: at 0.3 m voxels it jumped
0.1 m and broke links with no charge at all. The contact box is the solid a voxel holds
(``voxel_solid_box``), so what rests on something stays.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.materials import MaterialLibrary
from blastvox.simulate import engine
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

LIBRARY = MaterialLibrary.builtin()
FAR = (ChargeSpec((1e5, 0.0, 0.0), 1e-3),)  # a charge whose wave never arrives
DENSITY = LIBRARY["concrete"].density


def _box(extents, centre) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(centre)
    return mesh


#: a founded base, a block and a slab set on its top face (z = 1 m), 5 cm apart
OBJECTS = {
    "base": _box((2.0, 2.0, 1.0), (0.0, 0.0, 0.5)),
    "block": _box((0.7, 0.7, 0.5), (0.3, 0.2, 1.25)),
    "slab": _box((1.6, 0.6, 0.25), (0.0, -0.5, 1.125)),
}


def _model(tmp_path: Path, size: float):
    requests = []
    for name, mesh in OBJECTS.items():
        path = tmp_path / f"{name}.stl"
        mesh.export(path)
        requests.append(ObjectRequest(mesh=path, voxel_size=(size,) * 3,
                                      material="concrete", chunk_size=0.0))
    return voxelize(requests, VoxelizeSettings(up_axis="Z", ground=0.0, library=LIBRARY))


@pytest.mark.parametrize("size", [0.3, 0.15])
def test_the_solid_box_of_each_object_is_its_mesh_box(tmp_path, size):
    """The voxels' solid boxes span each mesh's bounds, though the cells reach past them."""
    model = _model(tmp_path, size)
    a = model.arrays
    cells = a["vertices"][a["voxel_vertices"]]
    for i, mesh in enumerate(OBJECTS.values()):
        mine = a["voxel_object"] == i
        box = a["voxel_solid_box"][mine]
        np.testing.assert_allclose(box[:, 0].min(axis=0), mesh.bounds[0], atol=1e-6)
        np.testing.assert_allclose(box[:, 1].max(axis=0), mesh.bounds[1], atol=1e-6)
        reach = np.maximum(mesh.bounds[0] - cells[mine].reshape(-1, 3).min(axis=0),
                           cells[mine].reshape(-1, 3).max(axis=0) - mesh.bounds[1])
        assert reach.max() > 0.02  # the size does not divide it: the cells reach past it
        assert a["voxel_mass"][mine].sum() == pytest.approx(mesh.volume * DENSITY, rel=1e-6)


@pytest.mark.parametrize(("size", "dt"), [(0.3, 1 / 240), (0.15, 1 / 240), (0.3, 1 / 2000)])
def test_objects_set_on_each_other_stay_at_rest(tmp_path, size, dt):
    """No charge reaches them: after 0.5 s nothing moved a millimetre, and no link broke
    (at 0.3 m voxels the block jumped 0.1 m and broke links when its contact box was its
    cells)."""
    model = _model(tmp_path, size)
    settings = SimSettings(dt=dt, duration=0.5, charges=FAR, dust=False, fire=False,
                           fireball=False, shock_sphere=False, camera_shake=False)
    run = engine.Run.start(model, settings)
    for n in range(1, round(0.5 / run.dt) + 1):
        engine.step(run, n, 0)
    state = run.state
    assert state.counters.broken_links == 0
    bodies = state.bodies
    for i, name in enumerate(OBJECTS):
        held = np.unique(state.voxels.body[model.arrays["voxel_object"] == i])
        assert len(held) == 1, name
        moved = float(np.linalg.norm(bodies.pos[held[0]] - bodies.com[held[0]]))
        assert moved < 1e-3, (name, moved)
        assert bodies.fixed[held[0]] == (name == "base")
