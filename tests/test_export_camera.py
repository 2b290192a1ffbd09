"""The scene camera, with its blast shake, reaches both USD and glTF."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh
from pxr import Gf, Usd, UsdGeom

from blastvox.export.api import ExportOptions, export
from blastvox.export.pieces import frame_change
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

CAMERA = ((0.0, -20.0, 2.0), (0.0, 0.0, 1.0), 50.0)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cam")
    trimesh.creation.box(extents=(1, 0.5, 1)).export(tmp / "w.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "w.stl", voxel_size=(0.25,) * 3,
                                    material="brick")], VoxelizeSettings(up_axis="Z"))
    return simulate(model, SimSettings(fps=50.0, duration=0.2, camera=CAMERA,
                                       charges=(ChargeSpec((0, -3.0, 0.5), 2.0),)))


def test_usd_camera_translation_carries_the_shake(cache, tmp_path):
    assert np.abs(cache.camera_offset).max() > 0
    path = tmp_path / "shot.usda"
    export(cache, path, ExportOptions(up_axis="Y"))
    stage = Usd.Stage.Open(str(path))
    cam = UsdGeom.Camera(stage.GetPrimAtPath("/Shot/Camera"))
    # UsdGeomCamera's lens and filmback are in tenths of a scene unit: on this metre
    # stage a 50 mm lens is 0.5 and a 36 x 20.25 mm (16:9) filmback 0.36 x 0.2025
    # (Blender read 50 as a 5000 mm lens); the field of view is the one of 50 mm on
    # 36 mm film
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert cam and cam.GetFocalLengthAttr().Get() == pytest.approx(0.5)
    assert cam.GetHorizontalApertureAttr().Get() == pytest.approx(0.36)
    assert cam.GetVerticalApertureAttr().Get() == pytest.approx(0.2025)
    fov = cam.GetCamera(0).GetFieldOfView(Gf.Camera.FOVHorizontal)
    assert fov == pytest.approx(np.degrees(2 * np.arctan(18.0 / 50.0)), rel=1e-5)
    change = frame_change("Z", "Y")
    for f in (0, cache.frame_count - 1, int(np.argmax(np.abs(cache.camera_offset).sum(1)))):
        m = UsdGeom.Xformable(cam).ComputeLocalToWorldTransform(f)
        want = (np.asarray(CAMERA[0]) + cache.camera_offset[f]) @ change.T
        np.testing.assert_allclose(np.array(m.ExtractTranslation()), want, atol=1e-9)
        # it looks at the target: -Z of the camera points from position to look_at
        forward = -np.array(m.TransformDir((0, 0, 1)))
        aim = (np.asarray(CAMERA[1]) - np.asarray(CAMERA[0])) @ change.T
        np.testing.assert_allclose(forward, aim / np.linalg.norm(aim), atol=1e-9)


def test_gltf_camera_node(cache, tmp_path):
    path = tmp_path / "shot.glb"
    export(cache, path)
    data = path.read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + length])
    node = next(n for n in doc["nodes"] if n.get("name") == "camera")
    lens = doc["cameras"][node["camera"]]
    assert lens["type"] == "perspective"
    # the USD export's frame: 36 mm wide at 16:9 behind a 50 mm lens
    assert lens["perspective"]["aspectRatio"] == pytest.approx(16 / 9)
    half_width = lens["perspective"]["aspectRatio"] * np.tan(lens["perspective"]["yfov"] / 2)
    assert half_width == pytest.approx(18.0 / CAMERA[2])
    change = frame_change("Z", "Y")
    np.testing.assert_allclose(node["translation"],
                               (np.asarray(CAMERA[0]) + cache.camera_offset[0]) @ change.T,
                               atol=1e-6)
    x, y, z, w = node["rotation"]
    forward = -np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    aim = (np.asarray(CAMERA[1]) - np.asarray(CAMERA[0])) @ change.T
    np.testing.assert_allclose(forward, aim / np.linalg.norm(aim), atol=1e-6)
