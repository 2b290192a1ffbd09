"""Member thickness (simulate/members.py).

The pressure-impulse criteria scale with the thickness of the member the wave
loads: measured through the member, the same at any voxel size and for any
direction of the charge.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.materials import MaterialLibrary
from blastvox.simulate.model import build_model
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

LIBRARY = MaterialLibrary.builtin()


def _model(tmp_path: Path, mesh: trimesh.Trimesh, size: float, name: str = "m.stl"):
    path = tmp_path / name
    mesh.export(path)
    return voxelize([ObjectRequest(mesh=path, voxel_size=(size,) * 3, material="brick")],
                    VoxelizeSettings(up_axis="Z", ground=None, library=LIBRARY))


@pytest.mark.parametrize("size", [0.25, 0.125, 0.1, 1.0 / 12.0, 0.0625])
def test_a_walls_thickness_is_its_own_at_any_voxel_size(tmp_path, size):
    """A 4 x 0.25 x 3 m wall: 0.25 m through it within 5 % whether 1, 2, 2.5, 3 or 4
    voxels span it (0.1 m and 1/12 m do not divide it)."""
    sm = build_model(_model(tmp_path, trimesh.creation.box(extents=(4.0, 0.25, 3.0)), size))
    assert np.median(sm.thickness) == pytest.approx(0.25, rel=0.05)
    assert sm.thickness.max() <= 0.25 * 1.05


def test_thickness_is_through_the_member_not_along_it(tmp_path):
    """An L of two walls (0.25 m and 0.5 m thick): each voxel gets its own wall's
    thickness, not a length, whichever way the walls run."""
    thin = trimesh.creation.box(extents=(4.0, 0.25, 3.0))
    thick = trimesh.creation.box(extents=(0.5, 4.0, 3.0))
    thick.apply_translation((2.25, 1.875, 0.0))
    sm = build_model(_model(tmp_path, trimesh.util.concatenate([thin, thick]), 0.125))
    x, y = sm.voxels.centroid[:, 0], sm.voxels.centroid[:, 1]
    in_thin = (x < 1.5) & (np.abs(y) < 0.125)
    in_thick = (x > 2.0) & (y > 1.0)
    assert np.median(sm.thickness[in_thin]) == pytest.approx(0.25, rel=0.05)
    assert np.median(sm.thickness[in_thick]) == pytest.approx(0.5, rel=0.05)


def test_a_turned_wall_keeps_its_thickness(tmp_path):
    """The wall turned 30 degrees about the vertical: through-thickness within 25 % of
    0.5 m (the grid's 13 directions bound the chord's angle to the normal)."""
    wall = trimesh.creation.box(extents=(4.0, 0.5, 3.0))
    wall.apply_transform(trimesh.transformations.rotation_matrix(math.radians(30),
                                                                 (0, 0, 1)))
    sm = build_model(_model(tmp_path, wall, 0.1))
    assert np.median(sm.thickness) == pytest.approx(0.5, rel=0.25)


def test_a_block_is_thick_inside(tmp_path):
    """A 2 m cube: a voxel 0.5 m or more inside every face is at least 1 m thick (the
    chord across an edge through it); only its edges and corners are thin."""
    sm = build_model(_model(tmp_path, trimesh.creation.box(extents=(2.0, 2.0, 2.0)), 0.25))
    inside = (np.abs(sm.voxels.centroid) <= 0.5 + 1e-9).all(axis=1)
    assert inside.sum() == 64
    assert sm.thickness[inside].min() >= 1.0
    assert np.median(sm.thickness) >= 1.0


def test_a_wall_edge_on_to_a_charge_mostly_stands(tmp_path):
    """A founded 4 x 3 x 0.25 m brick wall with 20 kg of TNT 2 m beyond one end, in its
    plane: the wave sweeps along both faces and squeezes it (UFC 3-340-02's side-wall
    loading); it does not bend it. The line from an element to the charge ran along
    the wall and out through its end, at normal incidence: every chunk interface broke
    (54 % of the links at 0.25 m voxels) and the wall lost its foundation; and the
    end face's reflected load wore the foundation away, so it toppled within a
    second. The same charge face-on throws it (tests/test_contact.py)."""
    from shapes import standing_box

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings

    path = standing_box(tmp_path / "wall.stl", (0.25, 4.0, 3.0))
    model = voxelize([ObjectRequest(mesh=path, voxel_size=(0.25,) * 3, material="brick")],
                     VoxelizeSettings(up_axis="Z", ground="auto", library=LIBRARY))
    cache = simulate(model, SimSettings(fps=24.0, duration=1.0, charges=(
        ChargeSpec((0.0, -4.0, 1.5), 20.0),)))
    founded = np.unique(cache.voxel_piece[model.voxel_foundation])
    standing = np.isin(cache.voxel_piece, founded).mean()
    assert standing > 0.8, standing
    assert cache.meta["broken_links"] < 0.1 * len(model.arrays["link_voxels"])
