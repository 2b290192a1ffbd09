"""Smooth normals (issue 16, item 1): a curved input shades smoothly in both exports.

The input is an icosphere of radius 1 m (1,280 flat triangles, about 7 degrees
apart). Its corner normals interpolated over a conform face must stay within a
degree of the true sphere's radial normal, where the flat face normals of the
same triangles are off by up to 5.5 degrees; a box keeps its flat faces; fracture
faces keep flat normals. The exports are read back with pxr and the glTF JSON,
and the Khronos validator must pass the .glb (it checks NORMAL for unit length).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from pxr import Usd, UsdGeom
from test_export_gltf import accessor, read_glb

from blastvox.errors import ContractError
from blastvox.export.api import ExportOptions, export
from blastvox.export.gltf_validate import validate_gltf, validator_available
from blastvox.export.pieces import piece_meshes
from blastvox.export.uv import face_uvs
from blastvox.geometry.normals import corner_normals
from blastvox.model import VoxelModel
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

CENTRE = np.array([0.0, 0.0, 1.0])  # the sphere's centre, model frame (Z up)


def _angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between unit vectors (..., 3)."""
    return np.degrees(np.arccos(np.clip(np.einsum("...j,...j->...", a, b), -1.0, 1.0)))


def test_corner_normals_are_smooth_on_a_sphere_and_sharp_on_a_box() -> None:
    sphere = trimesh.creation.icosphere(subdivisions=3)
    exact = sphere.vertices[sphere.faces]  # unit sphere: the radial normal is the point
    smooth = corner_normals(sphere.vertices, sphere.faces)
    flat = np.repeat(sphere.face_normals[:, None, :], 3, axis=1)
    assert _angles(smooth, exact).max() < 1.0
    assert _angles(flat, exact).max() > 4.0
    # split vertices (seams) are matched by position: the same normals
    split = sphere.copy()
    split.unmerge_vertices()
    np.testing.assert_allclose(corner_normals(split.vertices, split.faces), smooth, atol=1e-12)
    box = trimesh.creation.box()
    np.testing.assert_allclose(corner_normals(box.vertices, box.faces),
                               np.repeat(box.face_normals[:, None, :], 3, axis=1), atol=1e-12)


def test_a_degenerate_triangle_gets_no_nan() -> None:
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0.0]])
    normals = corner_normals(vertices, np.array([[0, 1, 2], [0, 1, 3]]))  # second: a line
    assert np.isfinite(normals).all()
    np.testing.assert_allclose(normals[0], [[0, 0, 1]] * 3)


@pytest.fixture(scope="module")
def ball(tmp_path_factory: pytest.TempPathFactory):
    """A concrete icosphere of radius 1 m (conform, 0.25 m voxels) broken by 20 kg at 2 m."""
    tmp = tmp_path_factory.mktemp("ball")
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    sphere.apply_translation(CENTRE)
    sphere.export(tmp / "ball.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "ball.stl", voxel_size=(0.25,) * 3,
                                    shape="conform", material="concrete")],
                     VoxelizeSettings(up_axis="Z"))
    cache = simulate(model, SimSettings(duration=0.1, fps=24.0, dust=False, fire=False,
                                        fireball=False,
                                        charges=(ChargeSpec((0.0, -2.0, 1.0), 20.0),)))
    assert cache.piece_count > 5, "the ball must break: fracture faces are checked too"
    return tmp, model, cache


def test_voxelize_keeps_the_smooth_input_s_normals_and_adds_nothing_for_a_box(ball,
                                                                              tmp_path):
    _, model, _ = ball
    a = model.arrays
    assert a["surface_normals"].dtype == np.float32
    assert a["surface_normals"].shape == a["surface_triangles"].shape
    np.testing.assert_allclose(np.linalg.norm(a["surface_normals"], axis=2), 1.0, atol=1e-6)
    assert not model.textures  # smooth but untextured: normals only
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(tmp_path / "box.stl")
    box = voxelize([ObjectRequest(mesh=tmp_path / "box.stl", voxel_size=(0.5,) * 3,
                                  material="concrete")], VoxelizeSettings(up_axis="Z"))
    assert "surface_normals" not in box.arrays


def test_outside_faces_take_the_sphere_s_normals_and_fracture_faces_stay_flat(ball) -> None:
    _, _, cache = ball
    meshes = piece_meshes(cache, "Z")  # the model's own frame: no change
    normals = face_uvs(cache, meshes).normal
    rest = meshes.rest
    on_sphere = np.abs(np.linalg.norm(rest - CENTRE, axis=2) - 1.0).max(axis=1) < 1e-3
    outside = ~meshes.damage & on_sphere
    radial = rest[outside] - CENTRE
    radial /= np.linalg.norm(radial, axis=2, keepdims=True)
    assert outside.sum() > 100
    assert _angles(normals[outside], radial).max() < 1.0
    flat = np.repeat(meshes.normals[:, None, :], 3, axis=1)
    assert meshes.damage.sum() > 10
    np.testing.assert_allclose(normals[meshes.damage], flat[meshes.damage], atol=1e-6)


def _surface_errors(triangles: np.ndarray, normals: np.ndarray, centre: np.ndarray
                    ) -> np.ndarray:
    """Degrees between the corner normals (T, 3, 3) of the triangles (T, 3, 3) that lie
    on the unit sphere about ``centre`` (every corner on it, facing outwards: not a
    fracture face) and the radial direction at each corner."""
    offset = triangles - centre
    flat = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    flat /= np.maximum(np.linalg.norm(flat, axis=1, keepdims=True), 1e-300)
    on = (np.abs(np.linalg.norm(offset, axis=2) - 1.0).max(axis=1) < 1e-3) & (
        np.einsum("tj,tj->t", flat, offset.mean(axis=1)) > 0.95)
    radial = offset[on] / np.linalg.norm(offset[on], axis=2, keepdims=True)
    return _angles(normals[on], radial).ravel()


def _usd_corner_errors(path: Path) -> np.ndarray:
    """:func:`_surface_errors` of every piece mesh of a USD export at frame 0 (Y up)."""
    centre = np.array([CENTRE[0], CENTRE[2], -CENTRE[1]])  # Z-up model -> Y-up export
    stage = Usd.Stage.Open(str(path))
    errors = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh) or "piece_" not in prim.GetName():
            continue
        mesh = UsdGeom.Mesh(prim)
        assert mesh.GetNormalsInterpolation() == UsdGeom.Tokens.faceVarying
        assert set(mesh.GetFaceVertexCountsAttr().Get(0)) == {3}
        matrix = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(0))
        points = np.array(mesh.GetPointsAttr().Get(0))
        corners = (points @ matrix[:3, :3] + matrix[3, :3])[
            np.array(mesh.GetFaceVertexIndicesAttr().Get(0))]
        normals = np.array(mesh.GetNormalsAttr().Get(0)) @ matrix[:3, :3]
        errors.append(_surface_errors(corners.reshape(-1, 3, 3), normals.reshape(-1, 3, 3),
                                      centre))
    return np.concatenate(errors)


@pytest.mark.parametrize("suffix", [".usda", ".usdc"])
def test_usd_normals_follow_the_sphere(ball, tmp_path: Path, suffix: str) -> None:
    _, _, cache = ball
    path = tmp_path / f"ball{suffix}"
    export(cache, path, ExportOptions())
    errors = _usd_corner_errors(path)
    assert len(errors) > 300 and errors.max() < 1.0


def test_gltf_normals_follow_the_sphere_and_validate(ball, tmp_path: Path) -> None:
    _, _, cache = ball
    path = tmp_path / "ball.glb"
    export(cache, path, ExportOptions())
    doc, blob = read_glb(path.read_bytes())
    centre = np.array([CENTRE[0], CENTRE[2], -CENTRE[1]])
    errors = []
    for node in doc["nodes"]:
        if "mesh" not in node:
            continue
        translation = np.array(node.get("translation", [0.0, 0.0, 0.0]))
        for prim in doc["meshes"][node["mesh"]]["primitives"]:
            points = accessor(doc, blob, prim["attributes"]["POSITION"]) + translation
            normals = accessor(doc, blob, prim["attributes"]["NORMAL"]).astype(np.float64)
            np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
            index = accessor(doc, blob, prim["indices"]).astype(np.int64)
            errors.append(_surface_errors(points[index].reshape(-1, 3, 3),
                                          normals[index].reshape(-1, 3, 3), centre))
    errors = np.concatenate(errors)
    assert len(errors) > 100 and errors.max() < 1.0
    if validator_available() is None:
        issues = validate_gltf(path)["issues"]
        assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:10]


@pytest.mark.parametrize("value, message", [
    (np.nan, "surface_normals.*finite"),
    (2.0, "surface_normals.*length 3.46"),
])
def test_a_crafted_normal_is_refused_in_one_line(ball, tmp_path: Path, value, message) -> None:
    _, model, _ = ball
    arrays = dict(model.arrays)
    normals = arrays["surface_normals"].copy()
    normals[3, 1] = value
    arrays["surface_normals"] = normals
    VoxelModel(arrays=arrays, meta=model.meta).save(tmp_path / "bad.npz")
    with pytest.raises(ContractError, match=message) as raised:
        VoxelModel.load(tmp_path / "bad.npz")
    assert "\n" not in str(raised.value) and "bad.npz" in str(raised.value)
