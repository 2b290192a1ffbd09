"""A crafted VoxelModel is refused on load with one line naming the file and the problem."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.errors import ContractError
from blastvox.model import VoxelModel
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize


@pytest.fixture(scope="module")
def model_file(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("model")
    trimesh.creation.box(extents=(1.0, 0.5, 1.0)).export(tmp / "box.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "box.stl", voxel_size=(0.25,) * 3,
                                    material="brick")], VoxelizeSettings(up_axis="Z"))
    path = tmp / "model.npz"
    model.save(path)
    return path


def _crafted(model_file: Path, tmp_path: Path, mutate) -> Path:
    with np.load(model_file, allow_pickle=False) as z:
        arrays = {k: z[k].copy() for k in z.files}
    mutate(arrays)
    path = tmp_path / "crafted.npz"
    np.savez(path, **arrays)
    return path


def _set_up_axis(arrays: dict) -> None:
    meta = json.loads(bytes(arrays["meta"]).decode())
    meta["up_axis"] = "Q"
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)


def test_the_untouched_file_loads(model_file):
    assert VoxelModel.load(model_file).voxel_count > 0


@pytest.mark.parametrize(("mutate", "message"), [
    (_set_up_axis, "up_axis is 'Q'"),
    (lambda a: a["voxel_object"].__setitem__(0, -1), "negative object index"),
    (lambda a: a["link_voxels"].__setitem__((0, 0), 10**9),
     "'link_voxels' refers to voxel 1000000000 of"),
    (lambda a: a["material_link_impulse"].__setitem__(0, np.nan),
     "'material_link_impulse' holds a value that is not a finite number >= 0"),
    (lambda a: a["material_pi_shape"].__setitem__(0, -1.0),
     "'material_pi_shape' holds a value that is not a finite number >= 0"),
    (lambda a: a.__setitem__("material_voxel_impulse", np.zeros((1, 2))),
     "'material_voxel_impulse' has shape"),
])
def test_a_crafted_file_is_refused(model_file, tmp_path, mutate, message):
    path = _crafted(model_file, tmp_path, mutate)
    with pytest.raises(ContractError, match=message) as error:
        VoxelModel.load(path)
    assert str(path) in str(error.value) and "\n" not in str(error.value)
