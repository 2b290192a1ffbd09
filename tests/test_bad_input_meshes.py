"""Mesh files whose structure lies (issue 36, item 2): a glTF node hierarchy with a
cycle, two parents, absurd depth or indices that name no node; a PLY whose header
counts more or fewer vertices or faces than its data holds. Each is one line naming
the file and the problem, in voxelize and in diff, never a traceback ("ValueError:
Iteration limit exceeded") or the wrong words ("contains no triangles")."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import trimesh
from bad_input import assert_clean_failure, deadline, run_blastvox, unchanged

#: (nodes, scene roots) of a one-box glTF, and words the refusal must say
HIERARCHIES = {
    "self-child": ([{"mesh": 0, "children": [0]}], [0], ["node 0 is its own child"]),
    "cycle": ([{"mesh": 0, "children": [1]}, {"mesh": 0, "children": [0]}], [0],
              ["cycle", "own ancestor"]),
    "unreachable cycle": ([{"mesh": 0}, {"mesh": 0, "children": [2]}, {"children": [1]}], [0],
                          ["cycle"]),
    "two parents": ([{"children": [1, 2]}, {"children": [3]}, {"children": [3]}, {"mesh": 0}],
                    [0], ["node 3 is a child of nodes 1 and 2"]),
    "deep": ([{"children": [i + 1]} for i in range(3000)] + [{"mesh": 0}], [0],
             ["more than 1,000 levels deep"]),
    "child not a node": ([{"mesh": 0, "children": [5]}], [0], ["names node 5", "1 node"]),
    "root not a node": ([{"mesh": 0}], [7], ["scenes[0].nodes names node 7"]),
    "root is a child": ([{"children": [1]}, {"mesh": 0}], [0, 1], ["a child of node 0"]),
    "mesh not a mesh": ([{"mesh": 9}], [0], ["nodes[0].mesh names mesh 9", "1 mesh"]),
}


def _gltf(folder: Path, name: str, nodes: list | None = None, roots: list | None = None,
          binary: bool = False) -> Path:
    box = trimesh.creation.box()
    path = folder / name
    if binary:
        data = trimesh.exchange.gltf.export_glb(trimesh.Scene(box))
        doc = json.loads(data[20:20 + int.from_bytes(data[12:16], "little")])
    else:
        files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(box))
        doc = json.loads(files.pop("model.gltf"))
        for other, content in files.items():
            (folder / other).write_bytes(content)
    if nodes is not None:
        doc["nodes"], doc["scenes"][0]["nodes"] = nodes, roots
    text = json.dumps(doc).encode()
    if binary:
        text += b" " * (-len(text) % 4)
        rest = data[20 + int.from_bytes(data[12:16], "little"):]
        body = len(text).to_bytes(4, "little") + b"JSON" + text + rest
        path.write_bytes(b"glTF" + (2).to_bytes(4, "little")
                         + (12 + len(body)).to_bytes(4, "little") + body)
    else:
        path.write_bytes(text)
    return path


@pytest.mark.parametrize("binary", [False, True], ids=["gltf", "glb"])
@pytest.mark.parametrize("case", sorted(HIERARCHIES))
def test_voxelize_refuses_a_node_hierarchy_that_is_not_a_tree(tmp_path, case, binary):
    """A cycle was "ValueError: Iteration limit exceeded" (a traceback) or silently
    dropped; two parents instanced a subtree twice (a diamond 30 deep: 2^30 copies)."""
    nodes, roots, words = HIERARCHIES[case]
    mesh = _gltf(tmp_path, "bad.glb" if binary else "bad.gltf", nodes, roots, binary)
    with deadline(10.0), unchanged(tmp_path, [mesh]):
        outcome = run_blastvox("voxelize", mesh.name, "-o", "m.npz", "--resolution", "8",
                               "-q", cwd=tmp_path)
    assert_clean_failure(outcome, [mesh.name], words=words, seconds=10.0)


@pytest.mark.parametrize("case", ["cycle", "two parents", "deep", "child not a node"])
def test_diff_refuses_a_node_hierarchy_that_is_not_a_tree(tmp_path, case):
    nodes, roots, words = HIERARCHIES[case]
    _gltf(tmp_path, "a.gltf")
    _gltf(tmp_path, "b.gltf", nodes, roots)
    with deadline(10.0):
        outcome = run_blastvox("diff", "a.gltf", "b.gltf", cwd=tmp_path)
    assert_clean_failure(outcome, ["b.gltf"], code=2, words=words, seconds=10.0)


@pytest.mark.parametrize("command", ["voxelize", "diff"])
def test_json_nested_past_the_parser_is_one_line(tmp_path, command):
    path = _gltf(tmp_path, "deep.gltf")
    path.write_text(path.read_text()[:-1] + ', "extras": ' + "[" * 100_000 + "]" * 100_000
                    + "}")
    args = (("voxelize", "deep.gltf", "-o", "m.npz", "--resolution", "8") if command ==
            "voxelize" else ("diff", "deep.gltf", "deep.gltf"))
    outcome = run_blastvox(*args, cwd=tmp_path)
    assert_clean_failure(outcome, ["deep.gltf"], code=1 if command == "voxelize" else 2,
                         words=["nested too deep"])


def test_a_tree_still_loads(tmp_path):
    """A deep but valid chain (the root's transform applies down it) is read."""
    nodes = [{"children": [i + 1], "translation": [0.0, 0.0, 0.0]} for i in range(200)]
    _gltf(tmp_path, "chain.gltf", nodes + [{"mesh": 0}], [0])
    outcome = run_blastvox("voxelize", "chain.gltf", "-o", "m.npz", "--resolution", "8", "-q",
                           cwd=tmp_path)
    assert outcome.code == 0, outcome.stderr


def _ply(encoding: str, vertices: int | None = None, faces: int | None = None) -> bytes:
    data = trimesh.exchange.ply.export_ply(trimesh.creation.box(), encoding=encoding)
    if vertices is not None:
        data = data.replace(b"element vertex 8\n", f"element vertex {vertices}\n".encode(), 1)
    if faces is not None:
        data = data.replace(b"element face 12\n", f"element face {faces}\n".encode(), 1)
    return data


@pytest.mark.parametrize("encoding", ["ascii", "binary"])
@pytest.mark.parametrize("vertices, faces, words", [
    (None, 0, ["0 faces", "holds 12 faces"]),
    (None, 3, ["3 faces", "holds 12 faces"]),
    (None, 1000, ["1,000 faces", "ends after 12 faces"]),
    (100, None, ["100 vertices", "ends after"]),
    (2, None, ["2 vertices and 12 faces"]),
])
def test_a_ply_whose_header_counts_lie_says_so(tmp_path, encoding, vertices, faces, words):
    """"contains no triangles" of a file holding 12 (face count 0), or garbage read
    on: now the header's counts and what the data holds, in one line."""
    (tmp_path / "lie.ply").write_bytes(_ply(encoding, vertices, faces))
    with unchanged(tmp_path, [tmp_path / "lie.ply"]):
        outcome = run_blastvox("voxelize", "lie.ply", "-o", "m.npz", "--resolution", "8",
                               cwd=tmp_path)
    line = assert_clean_failure(outcome, ["lie.ply", "PLY header says"], words=words)
    assert "no triangles" not in line


@pytest.mark.parametrize("name", ["bunny.ply", "suzanne.ply"])
def test_real_plys_pass_the_count_check(data_dir, name):
    from blastvox.io.mesh_checks import check_ply_counts

    check_ply_counts(name, (data_dir / name).read_bytes())
    for encoding in ("ascii", "binary"):
        check_ply_counts("box.ply", _ply(encoding))


# --- budgets before work: triangles and objects (issue 36) ------------------------

def _box_files(folder: Path) -> None:
    box = trimesh.creation.box()
    box.export(folder / "box.stl")
    (folder / "quads.obj").write_text(  # a cube of 6 quads: 12 triangles once read
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
        "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n")


def test_a_mesh_over_the_triangle_budget_is_refused_before_it_is_parsed(tmp_path,
                                                                       monkeypatch):
    """A 5.2 M-triangle STL took 65 s and 4 GB at --resolution 8: what a file says it
    holds (a binary STL's header, a PLY's or OFF's face count, an OBJ's face lines, a
    glTF's primitives) is refused before the parser runs."""
    _box_files(tmp_path)
    import blastvox.voxelize.mesh_io as mesh_io

    def never(*args, **kwargs):
        raise AssertionError("parsed a mesh over its budget")

    monkeypatch.setattr(mesh_io, "_load_surface", never)
    with unchanged(tmp_path, [tmp_path / "box.stl"]):
        outcome = run_blastvox("voxelize", "box.stl", "-o", "m.npz", "--resolution", "8",
                               "--max-triangles", "5", cwd=tmp_path)
    assert_clean_failure(outcome, ["box.stl", "12 triangles", "--max-triangles"],
                         words=["says it holds", "5 one voxelize reads"], seconds=10.0)


def test_the_triangles_held_are_counted_after_parsing_and_across_objects(tmp_path):
    """An OBJ's 6 quad lines are 12 triangles once read; two meshes share one budget."""
    _box_files(tmp_path)
    outcome = run_blastvox("voxelize", "quads.obj", "-o", "m.npz", "--resolution", "8",
                           "--max-triangles", "8", cwd=tmp_path)
    assert_clean_failure(outcome, ["quads.obj", "holds 12 triangles"])
    outcome = run_blastvox("voxelize", "box.stl", "quads.obj", "-o", "m.npz",
                           "--resolution", "8", "--max-triangles", "20", cwd=tmp_path)
    assert_clean_failure(outcome, ["quads.obj", "the objects before it hold 12"])
    assert run_blastvox("voxelize", "box.stl", "quads.obj", "-o", "m.npz", "--resolution",
                        "8", "--max-triangles", "24", "-q", cwd=tmp_path).code == 0


@pytest.mark.parametrize("command", ["voxelize", "run"])
def test_a_scene_over_the_object_budget_is_refused_before_any_is_read(tmp_path, command):
    """10,000 objects of one mesh ran past 300 s with no budget line."""
    _box_files(tmp_path)
    objects = "".join(f'[[objects]]\nname = "b{i}"\nmesh = "box.stl"\nvoxel_size = 0.5\n'
                      f'transform.translate = [{2 * i}, 0, 0]\n' for i in range(2001))
    (tmp_path / "scene.toml").write_text(
        objects + '[[charges]]\nposition = [0, -2, 0.5]\nmass_kg = 1\n[simulation]\n'
        'duration = 0.05\n[output]\nmodel = "o/m.npz"\ncache = "o/s.npz"\n')
    args = (("voxelize", "--scene", "scene.toml", "-q") if command == "voxelize"
            else ("run", "scene.toml", "-q"))
    with unchanged(tmp_path, [tmp_path / "scene.toml"]):
        outcome = run_blastvox(*args, cwd=tmp_path)
    hint = "--max-objects, up to" if command == "voxelize" else "voxelize --scene scene.toml"
    assert_clean_failure(outcome, ["scene.toml", "2,001 objects", "2,000", hint],
                         seconds=15.0)
