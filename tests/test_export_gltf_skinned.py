"""glTF ``--layout skinned``: skinned meshes of up to SKIN_JOINTS pieces, a joint per piece.

An importer makes one object of it instead of one per piece (Blender's glTF
importer slows down with the square of the object count). The file must be the
same shot: each piece's vertices, bound to that piece's joint with weight 1, are
the piece's own mesh in piece-local space, and the joints are the piece nodes
with the same animation. Checked against the node-per-piece layout of the same
cache, by the Khronos validator and, in tests/test_blender_import.py, in Blender.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_export_gltf import accessor, read_glb

from blastvox.cache import SimCache
from blastvox.errors import BlastvoxError
from blastvox.export import gltf_meshes
from blastvox.export.api import ExportOptions, export

GOLDEN = Path(__file__).resolve().parents[1] / "examples" / "golden"


@pytest.fixture(scope="module")
def house() -> SimCache:
    return SimCache.load(GOLDEN / "house.sim.npz")


@pytest.fixture(scope="module", params=[512, 10], ids=["one_skin", "skins_of_10"])
def files(house: SimCache, request: pytest.FixtureRequest,
          tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple]:
    """Both layouts of the house; skinned with the default skin size (one skin for its
    72 pieces) and with skins of 10 joints (8 skins)."""
    tmp = tmp_path_factory.mktemp("skinned")
    out = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(gltf_meshes, "SKIN_JOINTS", request.param)
        for layout in ("xforms", "skinned"):
            path = tmp / f"{layout}.glb"
            export(house, path, ExportOptions(layout=layout))
            out[layout] = (path, *read_glb(path.read_bytes()))
    out["skin_joints"] = request.param
    return out


def _skinned_points(doc: dict, blob: bytes) -> dict[int, np.ndarray]:
    """Sorted unique vertex positions per piece of a skinned file: each mesh's JOINTS_0
    indexes the joints of the skin its node names."""
    out: dict[int, list] = {}
    for node in doc["nodes"]:
        if "skin" not in node:
            continue
        joints = np.asarray(doc["skins"][node["skin"]]["joints"])
        for prim in doc["meshes"][node["mesh"]]["primitives"]:
            pos = accessor(doc, blob, prim["attributes"]["POSITION"])
            piece = joints[accessor(doc, blob, prim["attributes"]["JOINTS_0"])[:, 0]]
            for p in np.unique(piece).tolist():
                out.setdefault(p, []).append(pos[piece == p])
    return {p: np.unique(np.concatenate(v), axis=0) for p, v in out.items()}


def _node_points(doc: dict, blob: bytes) -> dict[int, np.ndarray]:
    """The same for a file with a mesh per piece node."""
    out = {}
    for p, node in enumerate(doc["nodes"]):
        if "mesh" in node and node["name"].startswith("piece_"):
            out[p] = np.unique(np.concatenate([
                accessor(doc, blob, prim["attributes"]["POSITION"])
                for prim in doc["meshes"][node["mesh"]]["primitives"]]), axis=0)
    return out


def test_skins_partition_the_pieces_of_each_object(house: SimCache, files: dict) -> None:
    _, doc, blob = files["skinned"]
    n, size = house.piece_count, files["skin_joints"]
    skins = [s["joints"] for s in doc["skins"]]
    assert sorted(j for s in skins for j in s) == list(range(n))
    assert all(1 <= len(s) <= size for s in skins) and len(skins) == -(-n // size)
    objects = [doc["nodes"][p]["extras"]["object"] for p in range(n)]
    assert all(len({objects[j] for j in s}) == 1 for s in skins)
    assert not any("mesh" in doc["nodes"][p] for p in range(n))
    skinned = [i for i, node in enumerate(doc["nodes"]) if "skin" in node]
    assert len(skinned) == len(doc["meshes"]) == len(skins)
    assert set(skinned) <= set(doc["scenes"][0]["nodes"])  # roots: transforms ignored
    for node in (doc["nodes"][i] for i in skinned):
        materials = []
        for prim in doc["meshes"][node["mesh"]]["primitives"]:
            weights = accessor(doc, blob, prim["attributes"]["WEIGHTS_0"])
            joints = accessor(doc, blob, prim["attributes"]["JOINTS_0"])
            np.testing.assert_array_equal(weights, np.tile([1.0, 0, 0, 0], (len(weights), 1)))
            assert np.all(joints[:, 1:] == 0)
            assert joints[:, 0].max() < len(doc["skins"][node["skin"]]["joints"])
            materials.append(prim["material"])
        assert len(materials) == len(set(materials))  # a primitive per material


def test_each_piece_keeps_its_mesh_and_animation(files: dict) -> None:
    _, xdoc, xblob = files["xforms"]
    _, sdoc, sblob = files["skinned"]
    want, got = _node_points(xdoc, xblob), _skinned_points(sdoc, sblob)
    assert sorted(got) == sorted(want)
    for p in want:
        np.testing.assert_array_equal(got[p], want[p])
    # the same animation: the same samplers on the same piece nodes
    xa, sa = xdoc["animations"][0], sdoc["animations"][0]
    assert [c["target"] for c in xa["channels"]] == [c["target"] for c in sa["channels"]]
    for xc, sc in zip(xa["channels"], sa["channels"], strict=True):
        for key in ("input", "output"):
            np.testing.assert_array_equal(
                accessor(xdoc, xblob, xa["samplers"][xc["sampler"]][key]),
                accessor(sdoc, sblob, sa["samplers"][sc["sampler"]][key]))


def test_khronos_validator_passes_skinned(files: dict) -> None:
    from blastvox.export.gltf_validate import validate_gltf, validator_available

    reason = validator_available()
    if reason is not None:
        pytest.skip(f"Khronos glTF Validator unavailable: {reason}")
    issues = validate_gltf(files["skinned"][0])["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:10]


def test_layouts_belong_to_their_format(house: SimCache, tmp_path: Path) -> None:
    with pytest.raises(BlastvoxError, match=r"skinned is glTF only"):
        export(house, tmp_path / "shot.usdc", ExportOptions(layout="skinned"))
    with pytest.raises(BlastvoxError, match=r"instancer is USD only"):
        export(house, tmp_path / "shot.glb", ExportOptions(layout="instancer"))
    assert not list(tmp_path.iterdir())


def test_many_nodes_warn_and_point_to_the_skinned_layout(house: SimCache, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    """Above GLTF_NODE_WARNING pieces a node-per-piece glTF warns (Blender imports it in
    minutes); the skinned layout and USD do not. The house with the threshold
    lowered below its piece count stands in for a 17k-piece shot."""
    import io
    import warnings

    from rich.console import Console

    from blastvox.cli.console import cli_warnings
    from blastvox.errors import ExportWarning
    from blastvox.export import api

    count = int(house.piece_count)
    assert count > 20
    monkeypatch.setattr(api, "GLTF_NODE_WARNING", count - 10)
    with pytest.warns(ExportWarning, match=rf"{count} pieces, a glTF node each.*--layout skinned"):
        export(house, tmp_path / "nodes.glb", ExportOptions())
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExportWarning)
        export(house, tmp_path / "skinned.glb", ExportOptions(layout="skinned"))
        export(house, tmp_path / "shot.usda", ExportOptions())
    monkeypatch.setattr(api, "GLTF_NODE_WARNING", count)  # the threshold itself is fine
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExportWarning)
        export(house, tmp_path / "nodes_at_threshold.glb", ExportOptions())
    monkeypatch.setattr(api, "GLTF_NODE_WARNING", count - 10)
    text = io.StringIO()
    with cli_warnings(Console(file=text, width=10_000)):  # how the CLI prints it
        export(house, tmp_path / "cli.glb", ExportOptions())
    lines = text.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("blastvox: warning: "), lines
    assert f"cli.glb: {count} pieces" in lines[0]
