"""glTF 2.0 export: read the written .glb/.gltf back (GLB chunks / JSON + .bin with numpy)
and check geometry, materials, animation, vanishing, determinism and the Khronos validator.

The shot is small and real: a 2 x 0.5 x 2 m brick wall (0.25 m voxels, Z-up) voxelized and
blown up by a 2 kg charge for half a second, so most voxels turn to dust at frame 1 (pieces
that vanish) and some pieces fly off and tumble.
"""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from blastvox import __version__
from blastvox.cache import SimCache
from blastvox.export.api import ExportOptions, export
from blastvox.export.gltf import glb_bytes, write_gltf
from blastvox.export.gltf_validate import validate_gltf, validator_available
from blastvox.export.pieces import animation, frame_change, piece_meshes

Doc = dict[str, Any]
_COMPONENTS = {5126: "<f4", 5125: "<u4", 5123: "<u2", 5121: "u1"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


@pytest.fixture(scope="module")
def shot(tmp_path_factory: pytest.TempPathFactory) -> tuple[SimCache, Path]:
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("gltf_shot")
    trimesh.creation.box(extents=(2, 0.5, 2)).export(tmp / "wall.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "wall.stl", voxel_size=(0.25,) * 3,
                                    material="brick")], VoxelizeSettings(up_axis="Z"))
    # 10 kg 0.75 m off the face: the wall breaks through, and its face crushes to dust
    # (brick crushes above 7 MPa)
    cache = simulate(model, SimSettings(duration=0.5, fps=24,
                                        charges=(ChargeSpec((0, -1.0, 1.0), 10.0),)))
    assert (cache.piece_end_frame < cache.frame_count).any(), "the shot needs vanished pieces"
    moved = np.linalg.norm(cache.piece_position[-1] - cache.piece_position[0], axis=-1)
    assert moved.max() > 0.05, "the shot needs a moving piece"
    sim = tmp / "sim.npz"
    cache.save(sim)
    return SimCache.load(sim), sim


@pytest.fixture(scope="module")
def glb(shot: tuple[SimCache, Path], tmp_path_factory: pytest.TempPathFactory
        ) -> tuple[Path, Doc, bytes]:
    path = tmp_path_factory.mktemp("glb") / "shot.glb"
    write_gltf(shot[0], path, ExportOptions(shock=True))
    doc, blob = read_glb(path.read_bytes())
    return path, doc, blob


@pytest.fixture(scope="module")
def gltf(shot: tuple[SimCache, Path], tmp_path_factory: pytest.TempPathFactory
         ) -> tuple[Path, Doc, bytes]:
    path = tmp_path_factory.mktemp("gltf") / "shot.gltf"
    write_gltf(shot[0], path, ExportOptions(shock=True))
    doc = json.loads(path.read_text())
    return path, doc, (path.parent / doc["buffers"][0]["uri"]).read_bytes()


def read_glb(data: bytes) -> tuple[Doc, bytes]:
    magic, version, length = struct.unpack_from("<III", data, 0)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    json_len, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A and json_len % 4 == 0
    doc = json.loads(data[20:20 + json_len])
    bin_len, bin_type = struct.unpack_from("<II", data, 20 + json_len)
    assert bin_type == 0x004E4942 and bin_len % 4 == 0
    blob = data[28 + json_len:28 + json_len + bin_len]
    assert 28 + json_len + bin_len == len(data)
    return doc, blob


def accessor(doc: Doc, blob: bytes, index: int) -> np.ndarray:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    dtype = np.dtype(_COMPONENTS[acc["componentType"]])
    width = _WIDTH[acc["type"]]
    stride = view.get("byteStride", dtype.itemsize * width)
    start = view["byteOffset"] + acc.get("byteOffset", 0)
    assert start % dtype.itemsize == 0
    assert acc.get("byteOffset", 0) + stride * (acc["count"] - 1) + dtype.itemsize * width \
        <= view["byteLength"]
    rows = [np.frombuffer(blob, dtype, width, start + i * stride) for i in range(acc["count"])] \
        if stride != dtype.itemsize * width else \
        [np.frombuffer(blob, dtype, width * acc["count"], start)]
    out = np.concatenate(rows).reshape(acc["count"], width)
    if acc.get("normalized"):  # unsigned integers as fractions of their maximum
        out = out.astype(np.float64) / np.iinfo(dtype).max
    return out[:, 0] if width == 1 else out


def channels(doc: Doc, node: int) -> dict[str, dict[str, Any]]:
    anim = doc["animations"][0]
    return {c["target"]["path"]: anim["samplers"][c["sampler"]] for c in anim["channels"]
            if c["target"]["node"] == node}


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a (w, x, y, z) unit quaternion."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def most_moved(cache: SimCache) -> int:
    alive = cache.piece_end_frame == cache.frame_count
    moved = np.linalg.norm(cache.piece_position[-1] - cache.piece_position[0], axis=-1)
    return int(np.argmax(np.where(alive, moved, -1.0)))


# --- structure -------------------------------------------------------------------------------

def test_nodes_meshes_and_scene(shot: tuple[SimCache, Path], glb: tuple[Path, Doc, bytes]
                                ) -> None:
    cache, _ = shot
    _, doc, _ = glb
    n_pieces, n_charges = cache.piece_count, len(cache.charge_tnt_kg)
    nodes = doc["nodes"]
    assert doc["asset"] == {"version": "2.0", "generator": f"blastvox {__version__}"}
    n_objects = len(cache.model.meta["objects"])
    assert len(nodes) == n_pieces + n_charges + n_objects + 1
    assert [n["name"] for n in nodes[:n_pieces]] == [f"piece_{p:05d}" for p in range(n_pieces)]
    shock = n_pieces + n_charges
    assert [n["name"] for n in nodes[n_pieces:shock]] == [f"shock_{c:02d}"
                                                          for c in range(n_charges)]
    # pieces hang under a node per source object; shock fronts hang under the root
    objects = nodes[shock:-1]
    assert [n["name"] for n in objects] == [o["name"] for o in cache.model.meta["objects"]]
    assert sorted(c for n in objects for c in n["children"]) == list(range(n_pieces))
    root = nodes[-1]
    assert doc["scenes"][doc["scene"]]["nodes"] == [len(nodes) - 1]
    assert root["children"] == list(range(shock, len(nodes) - 1)) + list(range(n_pieces,
                                                                               shock))
    assert not any(k in root for k in ("translation", "rotation", "scale", "matrix"))
    meshes = {n["mesh"] for n in nodes[:n_pieces]}
    assert len(meshes) == n_pieces  # a mesh of its own per piece
    for node in nodes[:n_pieces]:
        assert "matrix" not in node
        assert set(node) <= {"name", "mesh", "translation", "rotation", "scale", "extras"}
        for prim in doc["meshes"][node["mesh"]]["primitives"]:
            assert prim["mode"] == 4 and set(prim["attributes"]) == {"POSITION", "NORMAL",
                                                                  "TEXCOORD_0"}
            pos = doc["accessors"][prim["attributes"]["POSITION"]]
            assert len(pos["min"]) == 3 and len(pos["max"]) == 3


def test_positions_normals_and_bounds(glb: tuple[Path, Doc, bytes]) -> None:
    _, doc, blob = glb
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            acc = doc["accessors"][prim["attributes"]["POSITION"]]
            pos = accessor(doc, blob, prim["attributes"]["POSITION"])
            assert pos.min(axis=0).tolist() == acc["min"]
            assert pos.max(axis=0).tolist() == acc["max"]
            nrm = accessor(doc, blob, prim["attributes"]["NORMAL"])
            np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-5)
            idx = accessor(doc, blob, prim["indices"]).reshape(-1, 3)
            assert idx.max() < len(pos)
            tri = pos[idx]
            face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            # counter-clockwise winding agrees with the stored (flat) normal
            assert (np.einsum("ij,ij->i", face, nrm[idx[:, 0]]) > 0).all()


def test_primitives_match_piece_meshes(shot: tuple[SimCache, Path],
                                       glb: tuple[Path, Doc, bytes]) -> None:
    cache, _ = shot
    _, doc, blob = glb
    pm = piece_meshes(cache, "Y")
    names = cache.model.meta["materials"]
    mat_names = [m["name"] for m in doc["materials"]]
    damage_total = 0
    for p in range(cache.piece_count):
        sl = slice(pm.offsets[p], pm.offsets[p + 1])
        expected: dict[tuple[str, bool], int] = {}
        solid = np.any(pm.normals[sl] != 0, axis=1)  # zero-area triangles are left out
        for m, d in zip(pm.material[sl][solid], pm.damage[sl][solid], strict=True):
            key = (names[m] + ("_damage" if d else ""), bool(d))
            expected[key] = expected.get(key, 0) + 1
        got: dict[tuple[str, bool], int] = {}
        area_got = 0.0
        for prim in doc["meshes"][doc["nodes"][p]["mesh"]]["primitives"]:
            name = mat_names[prim["material"]]
            got[(name, name.endswith("_damage"))] = doc["accessors"][prim["indices"]]["count"] // 3
            tri = accessor(doc, blob, prim["attributes"]["POSITION"])[
                accessor(doc, blob, prim["indices"]).reshape(-1, 3)]
            area_got += 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0],
                                                      tri[:, 2] - tri[:, 0]), axis=1).sum()
        assert got == expected, f"piece {p}"
        v = pm.vertices[sl]
        area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum()
        assert area_got == pytest.approx(area, rel=1e-5)
        damage_total += sum(n for (_, d), n in got.items() if d)
    assert damage_total == int((pm.damage & np.any(pm.normals != 0, axis=1)).sum()) > 0


def test_material_colours(shot: tuple[SimCache, Path], glb: tuple[Path, Doc, bytes]) -> None:
    cache, _ = shot
    _, doc, _ = glb
    a = cache.model.arrays
    by_name = {m["name"]: m for m in doc["materials"]}
    for i, name in enumerate(cache.model.meta["materials"]):
        for suffix, rgb in (("", a["material_color"][i]), ("_damage",
                                                           a["material_damage_color"][i])):
            pbr = by_name[name + suffix]["pbrMetallicRoughness"]
            if "baseColorTexture" in pbr:  # a damage texture carries the colour itself
                assert suffix == "_damage"
                rgb = (1.0, 1.0, 1.0)
            np.testing.assert_allclose(pbr["baseColorFactor"], [*rgb, 1.0])
            assert pbr["metallicFactor"] == 0.0 and pbr["roughnessFactor"] == pytest.approx(0.8)
    assert by_name["brick"]["pbrMetallicRoughness"]["baseColorFactor"] != \
        by_name["brick_damage"]["pbrMetallicRoughness"]["baseColorFactor"]


# --- animation -------------------------------------------------------------------------------

def test_moving_piece_keys_match_animation(shot: tuple[SimCache, Path], tmp_path: Path) -> None:
    """Without keyframe reduction (tolerances 0) every frame is a LINEAR key
    (tests/test_export_keys.py checks the reduced default)."""
    cache, _ = shot
    write_gltf(cache, tmp_path / "exact.glb", ExportOptions(key_tolerance_m=0.0,
                                                             key_tolerance_deg=0.0))
    doc, blob = read_glb((tmp_path / "exact.glb").read_bytes())
    anim = animation(cache, "Y")
    p = most_moved(cache)
    ch = channels(doc, p)
    assert ch["translation"]["interpolation"] == "LINEAR"
    assert ch["rotation"]["interpolation"] == "LINEAR"
    times = accessor(doc, blob, ch["translation"]["input"])
    np.testing.assert_array_equal(times, cache.frame_time.astype(np.float32))
    t_acc = doc["accessors"][ch["translation"]["input"]]
    assert t_acc["min"] == [float(times[0])] and t_acc["max"] == [float(times[-1])]
    trans = accessor(doc, blob, ch["translation"]["output"])
    rot = accessor(doc, blob, ch["rotation"]["output"])  # (x, y, z, w)
    assert trans.shape == (cache.frame_count, 3) and rot.shape == (cache.frame_count, 4)
    late = cache.frame_count - 1
    np.testing.assert_allclose(trans[late], anim.position[late, p], atol=1e-6)
    wxyz = rot[late, [3, 0, 1, 2]]
    sign = np.sign(np.dot(wxyz, anim.orientation[late, p]))
    np.testing.assert_allclose(sign * wxyz, anim.orientation[late, p], atol=1e-6)
    # the node's rest TRS is the first frame
    node = doc["nodes"][p]
    np.testing.assert_allclose(node["translation"], trans[0])
    np.testing.assert_allclose(node["rotation"], rot[0])

    # independent of pieces.animation: the glTF world vertices at the last frame are the
    # cache's rigid transform of the rest geometry, turned from Z-up to Y-up
    c = frame_change("Z", "Y")
    r_gl = quat_matrix(wxyz)
    r_cache = quat_matrix(cache.piece_orientation[late, p].astype(np.float64))
    for prim in doc["meshes"][node["mesh"]]["primitives"]:
        local = accessor(doc, blob, prim["attributes"]["POSITION"]).astype(np.float64)
        world_gl = local @ r_gl.T + trans[late]
        rest_model = local @ c  # C^-1 = C^T: piece-local offsets in the model frame
        world_model = rest_model @ r_cache.T + cache.piece_position[late, p]
        np.testing.assert_allclose(world_gl, world_model @ c.T, atol=1e-4)


def test_rotation_keys_unit_and_sign_continuous(shot: tuple[SimCache, Path],
                                                glb: tuple[Path, Doc, bytes]) -> None:
    cache, _ = shot
    _, doc, blob = glb
    for p in range(cache.piece_count):
        rot = accessor(doc, blob, channels(doc, p)["rotation"]["output"]).astype(np.float64)
        np.testing.assert_allclose(np.linalg.norm(rot, axis=1), 1.0, atol=1e-6)
        assert (np.einsum("ij,ij->i", rot[1:], rot[:-1]) >= 0).all(), f"piece {p}"


def test_sign_flip_keeps_interpolation_short(tmp_path: Path, shot: tuple[SimCache, Path]
                                             ) -> None:
    """Keys that jump to the opposite hemisphere (q and -q: the same rotation) are written
    continuous, so LINEAR interpolation does not spin the piece the long way round."""
    cache, _ = shot
    ori = cache.piece_orientation.copy()
    ori[1::2] *= -1.0
    flipped = SimCache(arrays={**cache.arrays, "piece_orientation": ori}, model=cache.model,
                       meta=cache.meta)
    write_gltf(cache, tmp_path / "a.glb")
    write_gltf(flipped, tmp_path / "b.glb")
    assert (tmp_path / "a.glb").read_bytes() == (tmp_path / "b.glb").read_bytes()


def test_vanished_pieces_step_to_zero_scale(shot: tuple[SimCache, Path],
                                            glb: tuple[Path, Doc, bytes]) -> None:
    cache, _ = shot
    _, doc, blob = glb
    end, times = cache.piece_end_frame, cache.frame_time.astype(np.float32)
    assert (end < cache.frame_count).sum() > 0
    for p in range(cache.piece_count):
        ch = channels(doc, p)
        if end[p] >= cache.frame_count:
            assert "scale" not in ch and "scale" not in doc["nodes"][p]
            continue
        s = ch["scale"]
        assert s["interpolation"] == "STEP"
        key_t = accessor(doc, blob, s["input"])
        key_s = accessor(doc, blob, s["output"])
        if end[p] == 0:
            assert key_s.tolist() == [[0.0, 0.0, 0.0]]
        else:
            assert key_t.tolist() == [times[0], times[end[p]]]
            assert key_s.tolist() == [[1.0] * 3, [0.0] * 3]
        acc = doc["accessors"][s["input"]]
        assert acc["min"] == [float(key_t.min())] and acc["max"] == [float(key_t.max())]


def test_piece_nodes_carry_index_mass_and_object(shot: tuple[SimCache, Path],
                                                  glb: tuple[Path, Doc, bytes]) -> None:
    cache, _ = shot
    _, doc, _ = glb
    for p in range(cache.piece_count):
        extras = doc["nodes"][p]["extras"]
        assert extras["piece"] == p and extras["mass_kg"] == float(cache.piece_mass[p])
        assert extras["object"] == cache.model.meta["objects"][0]["name"]


def test_no_shock_spheres_unless_asked(shot: tuple[SimCache, Path], tmp_path: Path) -> None:
    """A renderer draws them, and they grow past the camera."""
    write_gltf(shot[0], tmp_path / "shot.glb", ExportOptions())
    doc, _ = read_glb((tmp_path / "shot.glb").read_bytes())
    assert not any(n["name"].startswith("shock") for n in doc["nodes"])
    assert len(doc["nodes"]) == shot[0].piece_count + 2  # pieces, their object, the root


def test_shock_spheres(shot: tuple[SimCache, Path], glb: tuple[Path, Doc, bytes]) -> None:
    cache, _ = shot
    _, doc, blob = glb
    c = frame_change("Z", "Y")
    for i in range(len(cache.charge_tnt_kg)):
        n = cache.piece_count + i
        node = doc["nodes"][n]
        np.testing.assert_allclose(node["translation"], c @ cache.charge_position[i], atol=1e-6)
        ch = channels(doc, n)
        assert set(ch) == {"scale"} and ch["scale"]["interpolation"] == "LINEAR"
        scale = accessor(doc, blob, ch["scale"]["output"])
        np.testing.assert_allclose(scale, np.repeat(cache.shock_radius[:, i:i + 1], 3, axis=1),
                                   rtol=1e-6)
        assert node["scale"] == scale[0].tolist()
        prim = doc["meshes"][node["mesh"]]["primitives"][0]
        pos = accessor(doc, blob, prim["attributes"]["POSITION"])
        np.testing.assert_allclose(np.linalg.norm(pos, axis=1), 1.0, atol=1e-6)  # unit sphere
        assert doc["materials"][prim["material"]]["alphaMode"] == "BLEND"


# --- files -----------------------------------------------------------------------------------

def test_deterministic_glb_and_gltf(tmp_path: Path, shot: tuple[SimCache, Path]) -> None:
    cache, sim = shot
    again = SimCache.load(sim)
    for name in ("one", "two"):
        write_gltf(cache if name == "one" else again, tmp_path / name / "shot.glb")
        write_gltf(cache if name == "one" else again, tmp_path / name / "shot.gltf")
    for f in ("shot.glb", "shot.gltf", "shot.bin"):
        assert (tmp_path / "one" / f).read_bytes() == (tmp_path / "two" / f).read_bytes(), f
    assert sorted(p.name for p in (tmp_path / "one").iterdir()) == \
        ["shot.bin", "shot.glb", "shot.gltf"]  # no temporary files left
    # same document and buffer whichever container
    doc_glb, blob = read_glb((tmp_path / "one" / "shot.glb").read_bytes())
    doc_gltf = json.loads((tmp_path / "one" / "shot.gltf").read_text())
    assert doc_gltf["buffers"] == [{"byteLength": len(blob), "uri": "shot.bin"}]
    assert doc_glb["buffers"] == [{"byteLength": len(blob)}]
    assert (tmp_path / "one" / "shot.bin").read_bytes() == blob
    doc_glb.pop("buffers")
    doc_gltf.pop("buffers")
    assert doc_glb == doc_gltf


def test_always_y_up(tmp_path: Path, shot: tuple[SimCache, Path]) -> None:
    cache, _ = shot
    export(cache, tmp_path / "y.glb", ExportOptions(up_axis="Y"))
    export(cache, tmp_path / "z.glb", ExportOptions(up_axis="Z"))
    assert (tmp_path / "y.glb").read_bytes() == (tmp_path / "z.glb").read_bytes()


def test_failed_write_leaves_previous_output(tmp_path: Path, shot: tuple[SimCache, Path],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    cache, _ = shot
    out = tmp_path / "shot.glb"
    out.write_bytes(b"previous")

    def boom(doc: Doc, blob: bytes) -> bytes:
        raise RuntimeError("disk full")

    monkeypatch.setattr("blastvox.export.gltf.glb_bytes", boom)
    with pytest.raises(RuntimeError):
        write_gltf(cache, out)
    assert out.read_bytes() == b"previous"
    assert [p.name for p in tmp_path.iterdir()] == ["shot.glb"]


def test_glb_padding() -> None:
    data = glb_bytes({"asset": {"version": "2.0"}}, b"\x01\x02\x03")
    doc, blob = read_glb(data)
    assert doc == {"asset": {"version": "2.0"}} and blob == b"\x01\x02\x03\x00"


def test_cli_export_glb(tmp_path: Path, shot: tuple[SimCache, Path],
                        glb: tuple[Path, Doc, bytes]) -> None:
    _, sim = shot
    out = tmp_path / "out.glb"
    from blastvox.cli.app import app

    assert "export" in {c.name for c in app.registered_commands}
    proc = subprocess.run([sys.executable, "-m", "blastvox", "export", str(sim), "-o",
                           str(out), "--shock", "-q"], capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes() == glb[0].read_bytes()  # the fixture's glb asked for shock too


# --- Khronos glTF Validator -------------------------------------------------------------------

def _validate(path: Path) -> dict[str, Any]:
    reason = validator_available()
    if reason is not None:
        pytest.skip(f"Khronos glTF Validator unavailable: {reason}")
    return validate_gltf(path)


@pytest.mark.parametrize("which", ["glb", "gltf"])
def test_khronos_validator_clean(which: str, request: pytest.FixtureRequest,
                                 shot: tuple[SimCache, Path]) -> None:
    path, doc, _ = request.getfixturevalue(which)
    assert (shot[0].piece_end_frame < shot[0].frame_count).any()
    report = _validate(path)
    issues = report["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, \
        json.dumps(issues["messages"][:20], indent=1)
    info = report["info"]
    assert info["animationCount"] == 1
    assert info["totalTriangleCount"] == sum(
        doc["accessors"][p["indices"]]["count"] // 3 for m in doc["meshes"]
        for p in m["primitives"])
    storages = [r["storage"] for r in info["resources"]]
    assert storages[0] == ("glb" if which == "glb" else "external")
    assert storages[1:] == ["buffer-view"] * len(doc.get("images", []))  # embedded PNGs


def test_validator_helper_reports_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.gltf"
    bad.write_text(json.dumps({"asset": {"version": "2.0"}, "nodes": [{"mesh": 3}]}))
    report = _validate(bad)
    assert report["issues"]["numErrors"] > 0


def test_validator_unavailable_is_clear(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from blastvox.errors import BlastvoxError

    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(BlastvoxError, match="node"):
        validate_gltf(tmp_path / "x.glb")


# --- edge cases, each also through the validator -------------------------------------------------

def _edit(cache: SimCache, **arrays: np.ndarray) -> SimCache:
    return SimCache(arrays={**cache.arrays, **arrays}, model=cache.model, meta=cache.meta)


@pytest.fixture(scope="module")
def small() -> SimCache:
    from blastvox.export.gltf import bench_cache

    return bench_cache(pieces=8, frames=6)


def test_edge_cases_valid(tmp_path: Path, small: SimCache,
                          monkeypatch: pytest.MonkeyPatch) -> None:
    end = small.piece_end_frame.copy()
    end[:3] = (0, 1, small.frame_count - 1)  # hidden from the start, gone at 1, gone at last
    cases = {
        "ends": _edit(small, piece_end_frame=end),
        "one_frame": _edit(small, **{k: small.arrays[k][:1] for k in (
            "frame_time", "piece_position", "piece_orientation", "shock_radius")},
            piece_end_frame=np.minimum(end, 1)),
        "no_charge": _edit(small, charge_position=np.zeros((0, 3)), charge_tnt_kg=np.zeros(0),
                           charge_time=np.zeros(0),
                           shock_radius=np.zeros((small.frame_count, 0))),
    }
    for name, cache in cases.items():
        for suffix in (".glb", ".gltf"):
            out = tmp_path / f"{name}{suffix}"
            write_gltf(cache, out, ExportOptions(shock=True))
            if suffix == ".glb":
                doc, blob = read_glb(out.read_bytes())
                assert len(doc["nodes"]) == cache.piece_count + len(cache.charge_tnt_kg) + 2
                if name == "ends":
                    assert doc["nodes"][0]["scale"] == [0.0, 0.0, 0.0]
                    assert accessor(doc, blob, channels(doc, 0)["scale"]["output"]).tolist() \
                        == [[0.0] * 3]
            if validator_available() is None:
                issues = validate_gltf(out)["issues"]
                assert issues["numErrors"] == issues["numWarnings"] == 0, (name, issues)

    # 32-bit indices where a primitive has too many vertices for 16 bits
    monkeypatch.setattr("blastvox.export.gltf_meshes.U16_VERTEX_LIMIT", 10)
    out = tmp_path / "u32.glb"
    write_gltf(small, out)
    doc, blob = read_glb(out.read_bytes())
    prim = doc["meshes"][0]["primitives"][0]
    assert doc["accessors"][prim["indices"]]["componentType"] == 5125
    assert accessor(doc, blob, prim["indices"]).max() < doc["accessors"][
        prim["attributes"]["POSITION"]]["count"]
    if validator_available() is None:
        issues = validate_gltf(out)["issues"]
        assert issues["numErrors"] == issues["numWarnings"] == 0, issues


def test_bench_gltf_small(small: SimCache) -> None:
    from blastvox.export.gltf import bench_gltf

    result = bench_gltf(cache=small, repeat=1)
    assert result["pieces"] == 8 and result["frames"] == 6
    assert result["seconds"] > 0 and result["bytes"] > 0
