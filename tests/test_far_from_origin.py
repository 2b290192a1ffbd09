"""A scene 100 km from the origin keeps sub-millimetre positions (issue 37).

SimCache version 1 stored ``piece_position`` as float32: 2^-24 of 100 km is 6 mm, so a
scene that far out moved in 7.8 mm steps. Version 2 stores float32 offsets from a
float64 ``position_origin`` near the scene (2^-24 of the distance from it; float64
positions cost the building's cache 57 % more, docs/file-formats.md); the exports carry
it too: USD's piece translations are double3, glTF's float32 translations sit under a
root node translated to the scene's origin (:func:`blastvox.export.pieces.export_origin`),
and USD's float32 point arrays (the instancer's positions, the particles') under a
double3 translate of it. The same brick wall, with its charge, simulated at the origin
and 100 km out is the same shot shifted (the simulator is float64; contacts between
pieces are off here: their broad phase's hash cells lie on a grid through the origin,
so a shift that is not a whole number of cells orders the contact solve differently,
which a shot's chaos then grows to millimetres: docs/file-formats.md).
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from pxr import Usd

from blastvox.cache import SimCache
from blastvox.export.gltf import build_gltf
from blastvox.export.options import ExportOptions
from blastvox.export.pieces import ORIGIN_GRID_M, frame_change
from blastvox.export.usd import build_layer
from blastvox.materials import MaterialLibrary
from blastvox.model import VoxelModel
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

SHIFT = np.array([1e5, 0.0, 0.0])  # m: 100 km east (Z-up)
MM = 1e-3
_COORDS = ("vertices", "voxel_centroid", "link_midpoint", "voxel_solid_box",
           "conform_triangles", "surface_triangles")


def _shifted(model: VoxelModel, shift: np.ndarray) -> VoxelModel:
    return VoxelModel(arrays={k: v + shift if k in _COORDS else v
                              for k, v in model.arrays.items()}, meta=model.meta)


@pytest.fixture(scope="module")
def shots(tmp_path_factory) -> tuple[SimCache, SimCache]:
    """(the wall's shot at the origin, the same 100 km out), each saved and loaded."""
    tmp = tmp_path_factory.mktemp("far")
    trimesh.creation.box(extents=(2.0, 0.25, 1.5)).apply_translation((0, 0, 0.75)).export(
        tmp / "wall.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "wall.stl", voxel_size=(0.25,) * 3,
                                    material="brick")],
                     VoxelizeSettings(up_axis="Z", ground=0.0,
                                      library=MaterialLibrary.builtin()))
    out = []
    for shift in (np.zeros(3), SHIFT):
        settings = SimSettings(fps=60.0, duration=0.25, collisions=False, charges=(
            ChargeSpec(tuple(np.array([0.0, -2.0, 1.0]) + shift), 10.0),))
        simulate(_shifted(model, shift), settings).save(tmp / f"{shift[0]:.0f}.npz")
        out.append(SimCache.load(tmp / f"{shift[0]:.0f}.npz"))
    return out[0], out[1]


def test_recorded_positions_far_out_are_those_at_the_origin_shifted(shots):
    near, far = shots
    assert far.piece_position.dtype == np.float64
    assert far.piece_count == near.piece_count > 1
    moved = np.abs(near.piece_position - near.piece_position[0]).max()
    assert moved > 0.1  # the wall came apart and its pieces flew
    error = np.abs(far.piece_position - SHIFT - near.piece_position).max()
    assert error < MM, error
    # what float32 (version 1) made of it: millimetres
    rounded = far.piece_position.astype(np.float32).astype(np.float64)
    assert np.abs(rounded - SHIFT - near.piece_position).max() > MM


def test_the_file_holds_float32_offsets_from_a_float64_origin(shots, tmp_path):
    near, far = shots
    for cache, origin in ((near, 0.0), (far, 98 * ORIGIN_GRID_M)):
        cache.save(tmp_path / "c.npz")
        with np.load(tmp_path / "c.npz") as raw:
            assert raw["piece_position"].dtype == np.float32
            np.testing.assert_array_equal(raw["position_origin"], [origin, 0.0, 0.0])
            # near the origin the offsets are the positions: version 1's bytes
            np.testing.assert_array_equal(
                raw["piece_position"].astype(np.float64) + raw["position_origin"],
                cache.piece_position)
        again = SimCache.load(tmp_path / "c.npz")
        np.testing.assert_array_equal(again.piece_position, cache.piece_position)


def _gltf_translations(doc: dict, blob: bytes, node: int) -> np.ndarray:
    anim = doc["animations"][0]
    sampler = next(anim["samplers"][c["sampler"]] for c in anim["channels"]
                   if c["target"] == {"node": node, "path": "translation"})
    acc = doc["accessors"][sampler["output"]]
    view = doc["bufferViews"][acc["bufferView"]]
    start = view["byteOffset"] + acc.get("byteOffset", 0)
    return np.frombuffer(blob, np.float32, 3 * acc["count"], start).reshape(-1, 3)


def test_gltf_keeps_far_positions_under_a_translated_root(shots):
    near, far = shots
    doc, blob = build_gltf(far)
    root = next(n for n in doc["nodes"] if n["name"] == "blastvox")
    origin = np.array(root["translation"])
    assert origin[0] == pytest.approx(1e5, abs=ORIGIN_GRID_M / 2)
    assert np.all(origin % ORIGIN_GRID_M == 0)  # exact in float32 too
    near_doc, _ = build_gltf(near)
    assert "translation" not in next(n for n in near_doc["nodes"] if n["name"] == "blastvox")
    c = frame_change("Z", "Y")
    expected = (near.piece_position + SHIFT) @ c.T  # (F, P, 3), Y-up
    for p in range(far.piece_count):
        world = origin + _gltf_translations(doc, blob, p).astype(np.float64)
        assert np.abs(world - expected[:, p]).max() < MM


@pytest.mark.parametrize("layout", ["xforms", "instancer"])
def test_usd_keeps_far_positions(shots, layout):
    near, far = shots
    stage = Usd.Stage.Open(build_layer(far, ExportOptions(layout=layout, particles="spheres")))
    c = frame_change("Z", "Y")
    expected = (near.piece_position + SHIFT) @ c.T
    for f in (0, far.frame_count - 1):
        if layout == "xforms":
            world = np.array([
                np.array(stage.GetPrimAtPath(path).GetAttribute("xformOp:translate:start").Get())
                + np.array(stage.GetPrimAtPath(path).GetAttribute("xformOp:translate").Get(f),
                           dtype=np.float64) for path in _piece_paths(stage)])
        else:
            inst = stage.GetPrimAtPath("/Shot/Pieces")
            offset = np.array(inst.GetAttribute("xformOp:translate").Get())
            world = offset + np.array(inst.GetAttribute("positions").Get(f), dtype=np.float64)
        assert np.abs(world - expected[f]).max() < MM


def _piece_paths(stage: Usd.Stage) -> list[str]:
    found = {int(p.GetAttribute("userProperties:piece").Get()): str(p.GetPath())
             for p in stage.Traverse() if p.GetName().startswith("piece_")
             and p.GetAttribute("userProperties:piece")}
    return [found[p] for p in sorted(found)]


def test_a_version_1_cache_is_read_with_its_positions_widened(shots, tmp_path):
    """Old caches (absolute float32 positions) still load, positions float64 in memory."""
    near, _ = shots
    arrays = {k: v for k, v in near.arrays.items() if k != "position_origin"}
    arrays["piece_position"] = near.piece_position.astype(np.float32)
    from blastvox.io.npz import write_npz

    meta = dict(near.meta, schema_version=1, model=near.model.contract_meta())
    members = {**arrays, **{f"model.{k}": v for k, v in near.model.arrays.items()}}
    write_npz(tmp_path / "v1.npz", members, meta)
    old = SimCache.load(tmp_path / "v1.npz")
    assert old.piece_position.dtype == np.float64
    np.testing.assert_array_equal(old.piece_position,
                                  near.piece_position.astype(np.float32).astype(np.float64))
