"""glTF ``--layout skinned``: one mesh of all pieces, a joint per piece.

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
from blastvox.export.api import ExportOptions, export

GOLDEN = Path(__file__).resolve().parents[1] / "examples" / "golden"


@pytest.fixture(scope="module")
def house() -> SimCache:
    return SimCache.load(GOLDEN / "house.sim.npz")


@pytest.fixture(scope="module")
def files(house: SimCache, tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple]:
    tmp = tmp_path_factory.mktemp("skinned")
    out = {}
    for layout in ("xforms", "skinned"):
        path = tmp / f"{layout}.glb"
        export(house, path, ExportOptions(layout=layout))
        out[layout] = (path, *read_glb(path.read_bytes()))
    return out


def _piece_points(doc: dict, blob: bytes, prims: list[dict], joint: int | None
                  ) -> dict[int, np.ndarray]:
    """Sorted unique vertex positions per piece, from per-piece meshes (joint None: the
    primitives' piece is given by the caller) or from JOINTS_0."""
    out: dict[int, list] = {}
    for piece, prim in prims:
        pos = accessor(doc, blob, prim["attributes"]["POSITION"])
        if joint is None:
            out.setdefault(piece, []).append(pos)
            continue
        joints = accessor(doc, blob, prim["attributes"]["JOINTS_0"])[:, 0]
        for p in np.unique(joints).tolist():
            out.setdefault(p, []).append(pos[joints == p])
    return {p: np.unique(np.concatenate(v), axis=0) for p, v in out.items()}


def test_one_mesh_skinned_to_the_piece_nodes(house: SimCache, files: dict) -> None:
    _, doc, blob = files["skinned"]
    n = house.piece_count
    assert len(doc["meshes"]) == 1 and doc["skins"] == [{"name": "pieces",
                                                          "joints": list(range(n))}]
    (skinned,) = [i for i, node in enumerate(doc["nodes"]) if "skin" in node]
    assert skinned in doc["scenes"][0]["nodes"]  # a root: its own transform is ignored
    assert not any("mesh" in doc["nodes"][p] for p in range(n))
    for prim in doc["meshes"][0]["primitives"]:
        weights = accessor(doc, blob, prim["attributes"]["WEIGHTS_0"])
        joints = accessor(doc, blob, prim["attributes"]["JOINTS_0"])
        np.testing.assert_array_equal(weights, np.tile([1.0, 0, 0, 0], (len(weights), 1)))
        assert np.all(joints[:, 1:] == 0) and joints[:, 0].max() < n
    # a primitive per material, not per piece
    materials = [p["material"] for p in doc["meshes"][0]["primitives"]]
    assert len(materials) == len(set(materials))


def test_each_piece_keeps_its_mesh_and_animation(files: dict) -> None:
    _, xdoc, xblob = files["xforms"]
    _, sdoc, sblob = files["skinned"]
    per_node = [(p, prim) for p, node in enumerate(xdoc["nodes"]) if "mesh" in node
                and node["name"].startswith("piece_")
                for prim in xdoc["meshes"][node["mesh"]]["primitives"]]
    want = _piece_points(xdoc, xblob, per_node, None)
    got = _piece_points(sdoc, sblob, [(None, p) for p in sdoc["meshes"][0]["primitives"]], 0)
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
