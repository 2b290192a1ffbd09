"""The source look: an input's UVs and base colour texture reach the USD and glTF exports.

The input is a 1 m cube whose UVs are the top view, u = x + 0.5 and v = y + 0.5,
with a 4 x 4 texture of distinct colours, written as a .glb by trimesh (so read
back through the same loader as any glTF asset). Conform voxels keep pieces of
the input triangles, so their outside faces must carry exactly those UVs; the
exports must carry the UVs, the texture file and a material that uses it, and
read back with the real libraries (USD, the glTF JSON, Pillow).
"""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image
from pxr import Sdf, Usd, UsdGeom, UsdShade

from blastvox.errors import ContractError
from blastvox.export.api import ExportOptions, export
from blastvox.export.pieces import piece_meshes, piece_objects
from blastvox.export.usd_specs import piece_prim_paths
from blastvox.export.usd_validate import validate_usd
from blastvox.export.uv import face_uvs
from blastvox.model import VoxelModel
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize
from blastvox.voxelize.requests import transform_matrix

PIXELS = np.arange(4 * 4 * 3, dtype=np.uint8).reshape(4, 4, 3) * 5


def top_view_uv(points: np.ndarray) -> np.ndarray:
    """The cube's UVs at (..., 3) points: u = x + 0.5, v = y + 0.5."""
    return points[..., :2] + 0.5


@pytest.fixture(scope="module")
def textured(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, VoxelModel]:
    tmp = tmp_path_factory.mktemp("look")
    cube = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    cube.apply_translation((0.0, 0.0, 0.5))
    cube.visual = trimesh.visual.TextureVisuals(
        uv=top_view_uv(np.asarray(cube.vertices)),
        image=Image.fromarray(PIXELS, "RGB"))
    path = tmp / "cube.glb"
    cube.export(path)
    model = voxelize([ObjectRequest(mesh=path, voxel_size=(0.25,) * 3, material="concrete",
                                    shape="conform")], VoxelizeSettings(up_axis="Z"))
    return tmp, model


@pytest.fixture(scope="module")
def cache(textured):
    return simulate(textured[1], SimSettings(duration=0.05, fps=20.0, charges=()))


def test_voxelize_keeps_uvs_and_texture(textured) -> None:
    _, model = textured
    assert [t["name"] for t in model.textures] == ["cube_0"]
    image = Image.open(io.BytesIO(model.texture_file(0)))
    assert image.format == "PNG" and np.array_equal(np.asarray(image.convert("RGB")), PIXELS)
    a = model.arrays
    assert len(a["surface_triangles"]) == 12 and (a["surface_texture"] == 0).all()
    np.testing.assert_allclose(a["surface_uv"], top_view_uv(a["surface_triangles"]),
                               atol=1e-6)


def test_an_untextured_input_adds_no_look(tmp_path: Path) -> None:
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(tmp_path / "cube.stl")
    model = voxelize([ObjectRequest(mesh=tmp_path / "cube.stl", voxel_size=(0.5,) * 3,
                                    material="concrete")], VoxelizeSettings(up_axis="Z"))
    assert "surface_triangles" not in model.arrays and not model.textures


def test_conform_faces_take_the_source_uvs_exactly(cache) -> None:
    meshes = piece_meshes(cache, "Y")
    uvs = face_uvs(cache, meshes)
    outside = ~meshes.damage
    assert (uvs.texture[outside] == 0).all()  # every outside face lies on the input
    np.testing.assert_allclose(uvs.uv[outside], top_view_uv(meshes.rest[outside]), atol=1e-5)
    # inside (fracture) faces: box UVs, the rest coordinates across their normal's axis
    assert (uvs.texture[~outside] == -1).all()


def test_the_model_keeps_its_look_through_a_file(textured, tmp_path: Path) -> None:
    _, model = textured
    model.save(tmp_path / "m.npz")
    again = VoxelModel.load(tmp_path / "m.npz")
    assert again.texture_file(0) == model.texture_file(0)
    arrays = dict(model.arrays)
    arrays["texture_offsets"] = arrays["texture_offsets"] + 1  # bytes past the end
    VoxelModel(arrays=arrays, meta=model.meta).save(tmp_path / "bad.npz")
    with pytest.raises(ContractError, match="texture_offsets"):
        VoxelModel.load(tmp_path / "bad.npz")


def test_usd_carries_st_the_texture_and_its_material(cache, tmp_path: Path) -> None:
    path = tmp_path / "shot.usda"
    export(cache, path, ExportOptions())
    texture = tmp_path / "shot_textures" / "cube_0.png"
    assert texture.read_bytes() == cache.model.texture_file(0)
    stage = Usd.Stage.Open(str(path))
    piece = piece_prim_paths(piece_objects(cache))[0]
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{piece}/piece_00000"))
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == "faceVarying"
    assert len(st.Get()) == len(mesh.GetFaceVertexIndicesAttr().Get())
    # the textured faces' subset, or the mesh itself where all its faces are textured
    subset = mesh.GetPrim().GetChild("textured_cube_0")
    bound = subset if subset else mesh.GetPrim()
    material, _ = UsdShade.MaterialBindingAPI(bound).ComputeBoundMaterial()
    assert material.GetPath() == "/Shot/Materials/texture_cube_0"
    surface = material.ComputeSurfaceSource()[0]
    source = surface.GetInput("diffuseColor").GetConnectedSources()[0][0].source
    reader = UsdShade.Shader(source.GetPrim())
    assert reader.GetIdAttr().Get() == "UsdUVTexture"
    asset = reader.GetInput("file").Get()
    assert Path(Sdf.ComputeAssetPathRelativeToLayer(stage.GetRootLayer(), asset.path)) \
        .resolve() == texture.resolve()
    assert validate_usd(path) == []


def read_glb(path: Path) -> tuple[dict, bytes]:
    data = path.read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + length])
    return doc, data[20 + length + 8:]


def test_gltf_embeds_the_texture_and_flips_v(cache, tmp_path: Path) -> None:
    path = tmp_path / "shot.glb"
    export(cache, path, ExportOptions())
    doc, blob = read_glb(path)
    (image,) = doc["images"]
    view = doc["bufferViews"][image["bufferView"]]
    start = view.get("byteOffset", 0)
    assert blob[start:start + view["byteLength"]] == cache.model.texture_file(0)
    textured = [i for i, m in enumerate(doc["materials"])
                if "baseColorTexture" in m["pbrMetallicRoughness"]]
    assert len(textured) == 1
    # the intact cube is piece 0, unrotated at frame 0: world = local + translation;
    # glTF is Y-up, (x, y, z) of the Z-up model is (X, -Z, Y) there, and glTF's v runs
    # down the image: (u, v) = (x + 0.5, 1 - (y + 0.5)) = (X + 0.5, 0.5 + Z)
    node = doc["nodes"][0]
    np.testing.assert_allclose(node["rotation"], [0, 0, 0, 1], atol=1e-6)
    prims = [p for p in doc["meshes"][node["mesh"]]["primitives"] if p["material"] in textured]
    assert prims
    for prim in prims:
        uv = _accessor(doc, blob, prim["attributes"]["TEXCOORD_0"])
        world = _accessor(doc, blob, prim["attributes"]["POSITION"]) + node["translation"]
        np.testing.assert_allclose(uv, np.stack([world[:, 0] + 0.5, world[:, 2] + 0.5], 1),
                                   atol=1e-5)


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_khronos_validator_passes_a_textured_export(cache, tmp_path: Path, suffix: str) -> None:
    from blastvox.export.gltf_validate import validate_gltf, validator_available

    reason = validator_available()
    if reason is not None:
        pytest.skip(f"Khronos glTF Validator unavailable: {reason}")
    path = tmp_path / f"shot{suffix}"
    export(cache, path, ExportOptions())
    issues = validate_gltf(path)["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:10]


def _accessor(doc: dict, blob: bytes, index: int) -> np.ndarray:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    width = {"VEC2": 2, "VEC3": 3}[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return np.frombuffer(blob, dtype="<f4", count=acc["count"] * width,
                         offset=start).reshape(-1, width)


def test_a_missing_texture_is_one_warning_and_the_base_colour(tmp_path: Path) -> None:
    """An OBJ whose .mtl names a texture that is not there: one warning line naming the
    file, the texture and the material; the model is written, without a look."""
    import subprocess
    import sys

    (tmp_path / "tet.obj").write_text(
        "mtllib tet.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\n"
        "usemtl skin\nf 1/1 3/3 2/2\nf 1/1 2/2 4/3\nf 1/1 4/3 3/2\nf 2/2 3/3 4/1\n")
    (tmp_path / "tet.mtl").write_text("newmtl skin\nKd 0.8 0.2 0.2\nmap_Kd gone.png\n")
    done = subprocess.run([sys.executable, "-m", "blastvox", "voxelize", "tet.obj", "-o",
                           "tet.npz", "--voxel-size", "0.25", "--material", "brick"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600,
                          check=False)
    assert done.returncode == 0, done.stderr
    warnings = [line for line in done.stderr.splitlines() if "gone.png" in line]
    assert warnings == ["blastvox: warning: tet.obj: texture 'gone.png' of material 'skin' "
                        "not found; the base colour is used"]
    assert not VoxelModel.load(tmp_path / "tet.npz").textures


def test_material_map_entries_that_set_nothing_warn() -> None:
    """'Chrome' names no material of the file: one warning, naming the entry and
    listing the file's materials. 'glass' (an open part: a sheet) sets voxels: none."""
    from pathlib import Path as _Path

    said: list[str] = []
    truck = _Path(__file__).parent / "data" / "CesiumMilkTruck.glb"
    voxelize([ObjectRequest(mesh=truck, voxel_size=(0.3,) * 3, material="steel",
                            material_map={"glass": "glass", "Chrome": "steel",
                                          "truck": "steel"})],
             VoxelizeSettings(up_axis="Y"), warn=said.append)
    entries = [line for line in said if "material_map" in line]
    assert len(entries) == 1, said
    assert "entry 'Chrome' matches no part's material" in entries[0]
    assert "'truck'" in entries[0]  # the file's materials are listed


def test_a_multi_primitive_gltf_gives_the_same_model_every_time(tmp_path: Path) -> None:
    """trimesh names the nodes of a multi-primitive glTF mesh at random ("0_3a8c99");
    parts were sorted and named by them, so two runs on the truck gave two models."""
    import subprocess
    import sys

    truck = Path(__file__).parent / "data" / "CesiumMilkTruck.glb"
    outputs = []
    for run in range(2):
        out = tmp_path / f"truck{run}.npz"
        done = subprocess.run([sys.executable, "-m", "blastvox", "voxelize", str(truck), "-o",
                               str(out), "--voxel-size", "0.3", "--material", "steel"],
                              capture_output=True, text=True, timeout=600, check=False)
        assert done.returncode == 0, done.stderr
        assert "part 'Cesium_Milk_Truck_1'" in done.stderr  # the glass, by a stable name
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1]


def test_slivers_of_a_turned_real_mesh_map_no_texture_coordinates(data_dir: Path,
                                                                    tmp_path: Path) -> None:
    """wallhole.obj has textured triangles with collinear corners. Turned 33 degrees they
    are no longer exactly zero-area, their barycentric coordinates blew up and both
    exports carried NaN/inf UVs (with numpy overflow warnings). Slivers now map nothing:
    every UV is finite and within the source's UV range, and a warning is an error."""
    model = voxelize([ObjectRequest(mesh=data_dir / "wallhole.obj", voxel_size=(0.5,) * 3,
                                    material="concrete",
                                    transform=transform_matrix((0, 0, 0), (0, 0, 33), 1.0))],
                     VoxelizeSettings(up_axis="Z"))
    cache = simulate(model, SimSettings(duration=0.05, fps=20.0, charges=()))
    with np.errstate(all="raise"):
        uvs = face_uvs(cache, piece_meshes(cache, "Y"))
    textured = uvs.texture >= 0
    assert textured.sum() > 100
    source = model.arrays["surface_uv"]
    span = source.max() - source.min()
    assert np.isfinite(uvs.uv).all()
    assert (np.abs(uvs.uv[textured]) <= np.abs(source).max() + 3 * span).all()
