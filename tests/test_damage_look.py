"""Damage textures: fracture faces show a generated texture per material.

The generator (blastvox.damage_look) is checked for what the exporters rely on:
the same bytes every time, a tile that repeats without a seam, and a mean linear
colour equal to the material's damage colour. The exports are read back with pxr
and as glTF JSON: the damage material's texture is the generated PNG, USD through
a UsdUVTexture beside the file and glTF embedded; ``damage_textures=False`` keeps
the flat colour and writes no file. The materials file picks a pattern by name,
and a typo is one line.
"""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from pxr import Sdf, Usd, UsdShade

from blastvox.cache import SimCache
from blastvox.damage_look import PATTERNS, damage_image, damage_png, pattern_for
from blastvox.errors import ContractError, MaterialError
from blastvox.export.api import ExportOptions, export
from blastvox.export.usd_validate import validate_usd
from blastvox.materials import MaterialLibrary
from blastvox.model import VoxelModel


def _linear(srgb8: np.ndarray) -> np.ndarray:
    c = srgb8.astype(np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


# ----------------------------------------------------------------------------- generator

@pytest.mark.parametrize("pattern", sorted(PATTERNS))
def test_a_pattern_is_deterministic_tileable_and_has_the_damage_colour(pattern: str) -> None:
    color = (0.30, 0.12, 0.07)
    image = damage_image(pattern, color)
    assert image.shape == (256, 256, 3) and image.dtype == np.uint8
    assert damage_png(pattern, color) == damage_png(pattern, list(color))
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(damage_png(pattern, color)))), image)
    # the mean linear colour is the damage colour (clipping of bright pixels aside)
    np.testing.assert_allclose(_linear(image).mean(axis=(0, 1)), color, rtol=0.06)
    # the tile repeats without a seam: the pair of rows (columns) across the wrap differs
    # no more than the most different pair of neighbouring rows (columns) inside it
    g = image.astype(float).mean(axis=2)
    for a in (g, g.T):
        inside = np.abs(np.diff(a, axis=0)).mean(axis=1)
        assert np.abs(a[0] - a[-1]).mean() <= inside.max(), (pattern, inside.max())
    # while two unrelated rows differ far more (what a seam would look like)
    assert np.abs(g[0] - g[128]).mean() > np.median(inside)
    assert g.std() > 2.0  # a texture, not a flat colour


def test_patterns_differ_and_unknown_ones_are_refused() -> None:
    images = {p: damage_image(p, (0.5, 0.5, 0.5)) for p in PATTERNS}
    for a in PATTERNS:
        for b in PATTERNS:
            if a < b:
                assert not np.array_equal(images[a], images[b]), (a, b)
    with pytest.raises(ValueError, match="unknown damage pattern 'wod'"):
        damage_image("wod", (0.5, 0.5, 0.5))


@pytest.mark.parametrize(("material", "chosen", "pattern"), [
    ("concrete", "", "concrete"), ("reinforced_concrete", "", "concrete"),
    ("steel", "", "metal"), ("drywall", "", "plaster"), ("thatch", "", "fibre"),
    ("weak_brick", "", "brick"), ("unobtainium", "", "rubble"), ("concrete", "wood", "wood"),
])
def test_pattern_follows_the_name_unless_chosen(material: str, chosen: str, pattern: str
                                                ) -> None:
    assert pattern_for(material, chosen) == pattern


def test_every_builtin_material_has_its_own_pattern() -> None:
    lib = MaterialLibrary.builtin()
    assert all(pattern_for(name) != "rubble" for name in lib)


# ----------------------------------------------------------------------------- materials file

def test_the_materials_file_chooses_a_pattern(tmp_path: Path) -> None:
    path = tmp_path / "m.toml"
    path.write_text('[wall]\nbase = "brick"\ndamage_pattern = "stone"\n')
    assert MaterialLibrary.load(path)["wall"].damage_pattern == "stone"
    path.write_text('[wall]\nbase = "brick"\ndamage_pattern = "stnoe"\n')
    with pytest.raises(MaterialError, match=r"wall.*unknown damage pattern 'stnoe' .*"
                                            r"did you mean 'stone'\?$"):
        MaterialLibrary.load(path)


def test_a_crafted_model_with_an_unknown_pattern_is_refused(shot: SimCache,
                                                            tmp_path: Path) -> None:
    arrays = dict(shot.model.arrays)
    arrays["material_damage_pattern"] = np.array(["moon rock"], dtype=np.str_)
    bad = tmp_path / "bad.npz"
    VoxelModel(arrays=arrays, meta=shot.model.meta).save(bad)
    with pytest.raises(ContractError, match=r"bad\.npz.*material_damage_pattern\[0\] is "
                                            r"'moon rock'"):
        VoxelModel.load(bad)


# ----------------------------------------------------------------------------- exports

@pytest.fixture(scope="module")
def shot(shattered_slab: SimCache) -> SimCache:
    return shattered_slab


def _expected_png(cache: SimCache) -> bytes:
    color = tuple(cache.model.arrays["material_damage_color"][0])
    return damage_png("concrete", color)


@pytest.mark.parametrize("stem", ["shot", "shot@v2", "x@@@y"])
def test_usd_binds_the_damage_texture_beside_the_file(shot: SimCache, tmp_path: Path,
                                                      stem: str) -> None:
    """An output name may hold '@', the usda asset delimiter (it crashed the export)."""
    path = tmp_path / f"{stem}.usda"
    export(shot, path, ExportOptions())
    texture = tmp_path / f"{stem}_textures" / "damage_concrete.png"
    assert texture.read_bytes() == _expected_png(shot)
    stage = Usd.Stage.Open(str(path))
    material = UsdShade.Material(stage.GetPrimAtPath("/Shot/Materials/concrete_damage"))
    surface = material.ComputeSurfaceSource()[0]
    source = surface.GetInput("diffuseColor").GetConnectedSources()[0][0].source
    reader = UsdShade.Shader(source.GetPrim())
    assert reader.GetIdAttr().Get() == "UsdUVTexture"
    assert reader.GetInput("wrapS").Get() == "repeat"
    asset = reader.GetInput("file").Get()
    assert Path(Sdf.ComputeAssetPathRelativeToLayer(stage.GetRootLayer(), asset.path)) \
        .resolve() == texture.resolve()
    # the outside faces keep their flat material colour
    outside = UsdShade.Material(stage.GetPrimAtPath("/Shot/Materials/concrete"))
    assert not outside.ComputeSurfaceSource()[0].GetInput("diffuseColor").HasConnectedSource()
    assert validate_usd(path) == []


def test_flat_damage_writes_no_texture(shot: SimCache, tmp_path: Path) -> None:
    path = tmp_path / "shot.usdc"
    export(shot, path, ExportOptions(damage_textures=False))
    assert not (tmp_path / "shot_textures").exists()
    stage = Usd.Stage.Open(str(path))
    material = UsdShade.Material(stage.GetPrimAtPath("/Shot/Materials/concrete_damage"))
    color = material.ComputeSurfaceSource()[0].GetInput("diffuseColor").Get()
    np.testing.assert_allclose(color, shot.model.arrays["material_damage_color"][0], atol=1e-6)
    doc, _ = _read_glb(_glb(shot, tmp_path / "flat.glb", damage_textures=False))
    assert "images" not in doc


def _glb(cache: SimCache, path: Path, **options) -> Path:
    export(cache, path, ExportOptions(**options))
    return path


def _read_glb(path: Path) -> tuple[dict, bytes]:
    data = path.read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    return json.loads(data[20:20 + length]), data[20 + length + 8:]


def test_gltf_embeds_the_damage_texture(shot: SimCache, tmp_path: Path) -> None:
    doc, blob = _read_glb(_glb(shot, tmp_path / "shot.glb"))
    (material,) = [m for m in doc["materials"] if m["name"] == "concrete_damage"]
    pbr = material["pbrMetallicRoughness"]
    assert pbr["baseColorFactor"] == [1.0, 1.0, 1.0, 1.0]
    texture = doc["textures"][pbr["baseColorTexture"]["index"]]
    image = doc["images"][texture["source"]]
    assert image["name"] == "damage_concrete" and image["mimeType"] == "image/png"
    view = doc["bufferViews"][image["bufferView"]]
    start = view.get("byteOffset", 0)
    assert blob[start:start + view["byteLength"]] == _expected_png(shot)
    assert doc["samplers"][texture["sampler"]]["wrapS"] == 10497  # REPEAT


def test_khronos_validator_passes_damage_textures(shot: SimCache, tmp_path: Path) -> None:
    from blastvox.export.gltf_validate import validate_gltf, validator_available

    reason = validator_available()
    if reason is not None:
        pytest.skip(f"Khronos glTF Validator unavailable: {reason}")
    issues = validate_gltf(_glb(shot, tmp_path / "shot.glb"))["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:10]


def test_exports_stay_byte_deterministic(shot: SimCache, tmp_path: Path) -> None:
    for n in (1, 2):
        export(shot, tmp_path / f"{n}" / "shot.usdc", ExportOptions()) if (
            tmp_path / f"{n}").mkdir() is None else None
    assert (tmp_path / "1" / "shot.usdc").read_bytes() == \
        (tmp_path / "2" / "shot.usdc").read_bytes()
    assert (tmp_path / "1" / "shot_textures" / "damage_concrete.png").read_bytes() == \
        (tmp_path / "2" / "shot_textures" / "damage_concrete.png").read_bytes()
    assert _glb(shot, tmp_path / "a.glb").read_bytes() == \
        _glb(shot, tmp_path / "b.glb").read_bytes()
