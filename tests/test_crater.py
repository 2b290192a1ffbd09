"""Close-in charges crater thick members (:func:`blastvox.simulate.criteria.crushes`).

A 2 m reinforced concrete block: a member thicker than the stress wave crosses
during a close-in load (c t_d ~ 1.5 m) never reached its breach asymptote, which
grows with that thickness, so a 10 kg charge 0.2 m from it did nothing at all. Its
loaded surface now crushes where the face load passes the material's crush pressure
and the reference element's impulse, layer by layer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.blast.kingery_bulmash import AIR, burst_parameters
from blastvox.materials import MaterialLibrary
from blastvox.simulate import engine
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

HALF = 1.0  # m: half the block's edge; its loaded face is at x = HALF


def _block(tmp_path: Path, size: float):
    path = tmp_path / f"block_{size}.stl"
    trimesh.creation.box(extents=(2 * HALF,) * 3).apply_translation((0, 0, HALF)).export(path)
    return voxelize([ObjectRequest(mesh=path, voxel_size=(size,) * 3,
                                   material="reinforced_concrete")],
                    VoxelizeSettings(up_axis="Z", ground=0.0,
                                     library=MaterialLibrary.builtin()))


def _crater(model, kg: float, standoff: float) -> tuple[np.ndarray, int]:
    """(the voxels the charge crushed (N,) bool, links broken) after 10 ms."""
    charge = ChargeSpec((HALF + standoff, 0.0, HALF), kg, "TNT", 0.0)
    settings = SimSettings(dt=1 / 960, duration=0.01, charges=(charge,), collisions=False,
                           dust=False, fire=False, fireball=False)
    run = engine.Run.start(model, settings)
    for n in range(1, round(0.01 / run.dt) + 1):
        engine.step(run, n, 0)
    return ~run.state.voxels.alive, int((~run.state.links.alive).sum())


@pytest.mark.parametrize("size", [0.2, 0.1])
def test_a_contact_range_charge_craters_a_thick_concrete_block(tmp_path, size):
    """10 kg 0.2 m off the face (Z = 0.09 m/kg^(1/3), Pr ~ 400 MPa against 30): a crater
    0.1-0.35 m in radius and one to two layers deep, whatever the voxel size, and no
    voxel crushed beyond it."""
    model = _block(tmp_path, size)
    crushed, broken = _crater(model, 10.0, 0.2)
    c = model.arrays["voxel_centroid"][crushed]
    assert crushed.sum() > 0 and broken > 0
    radius = np.sqrt(c[:, 1] ** 2 + (c[:, 2] - HALF) ** 2).max() + size / 2
    depth = HALF - (c[:, 0] - size / 2).min()
    assert 0.1 <= radius <= 0.35, radius
    assert 0.1 <= depth <= 0.4, depth


def test_a_reflected_pressure_below_the_compressive_strength_crushes_nothing(tmp_path):
    """1 kg at 1 m: Kingery-Bulmash's normally reflected peak, 5.0 MPa, is a sixth of
    concrete's 30 MPa compressive strength, and the block (metres of concrete) is far
    from its breach asymptote: nothing crushes or cracks."""
    reflected = float(burst_parameters(1.0, AIR)[4])  # Z = 1 m/kg^(1/3)
    assert reflected < 30e6 / 5
    crushed, broken = _crater(_block(tmp_path, 0.2), 1.0, 1.0)
    assert crushed.sum() == 0 and broken == 0
