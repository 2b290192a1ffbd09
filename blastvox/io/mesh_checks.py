"""Header and structure checks of mesh files, before a parser trusts them (issue 36).

Each check reads what a file says about itself (a glTF's node hierarchy, a PLY's
element counts) and refuses, in one :class:`~blastvox.errors.MeshError` line naming
the file and the problem, what would make a parser loop, recurse, index past its
data or read the wrong bytes silently: a glTF node that is its own ancestor
(trimesh: "ValueError: Iteration limit exceeded"), a node with two parents, a
hierarchy deeper than :data:`MAX_NODE_DEPTH`, a child or scene root that is not a
node; a PLY whose header counts more (or fewer) vertices or faces than its data
holds ("contains no triangles", or garbage read as coordinates).
"""

from __future__ import annotations

import contextlib
import json
import struct
from typing import Any

import numpy as np

from blastvox.errors import MeshError

#: The deepest glTF node hierarchy read: a rig is a few dozen levels; each level costs
#: a transform product per instance below it.
MAX_NODE_DEPTH = 1000
_GLB_MAGIC, _GLB_JSON = 0x46546C67, 0x4E4F534A


def gltf_document(shown: str, data: bytes) -> dict[str, Any] | None:
    """The JSON document of a .glb or .gltf's bytes, or None if it is not one (the
    loader then says what is wrong with it). JSON nested deeper than Python's parser
    recurses is a MeshError."""
    try:
        if data[:4] == b"glTF":
            magic, _, _ = struct.unpack_from("<III", data, 0)
            size, kind = struct.unpack_from("<II", data, 12)
            if magic != _GLB_MAGIC or kind != _GLB_JSON:
                return None
            data = data[20:20 + size]
        doc = json.loads(data)
    except RecursionError:
        raise MeshError(f"{shown}: its JSON is nested too deep to read") from None
    except (struct.error, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def check_gltf_nodes(shown: str, doc: dict[str, Any]) -> None:
    """Refuse a glTF whose nodes are not disjoint trees of at most :data:`MAX_NODE_DEPTH`
    levels (the specification's rule), or whose children and scene roots are not nodes."""
    nodes = doc.get("nodes", [])
    if not isinstance(nodes, list):
        raise MeshError(f"{shown}: 'nodes' is not a list")
    count = len(nodes)
    parent = np.full(count, -1, dtype=np.int64)
    for i, node in enumerate(nodes):
        if not isinstance(node, dict):
            raise MeshError(f"{shown}: nodes[{i}] is not an object")
        children = node.get("children", [])
        if not isinstance(children, list):
            raise MeshError(f"{shown}: nodes[{i}].children is not a list")
        for child in children:
            _node_index(shown, f"nodes[{i}].children", child, count)
            if child == i:
                raise MeshError(f"{shown}: node {i} is its own child; glTF nodes form trees")
            if parent[child] >= 0:
                raise MeshError(f"{shown}: node {child} is a child of nodes {parent[child]} and "
                                f"{i}; glTF nodes form trees (one parent each)")
            parent[child] = i
        mesh = node.get("mesh")
        meshes = doc.get("meshes", [])
        if mesh is not None and not (isinstance(mesh, int) and not isinstance(mesh, bool)
                                     and isinstance(meshes, list) and 0 <= mesh < len(meshes)):
            held = len(meshes) if isinstance(meshes, list) else 0
            raise MeshError(f"{shown}: nodes[{i}].mesh names mesh {mesh!r}, but the file "
                            f"has {held:,} mesh{'' if held == 1 else 'es'}")
    _check_depth(shown, parent)
    scenes = doc.get("scenes", [])
    for s, scene in enumerate(scenes if isinstance(scenes, list) else []):
        roots = scene.get("nodes", []) if isinstance(scene, dict) else None
        if not isinstance(roots, list):
            raise MeshError(f"{shown}: scenes[{s}].nodes is not a list")
        for root in roots:
            _node_index(shown, f"scenes[{s}].nodes", root, count)
            if parent[root] >= 0:
                raise MeshError(f"{shown}: scenes[{s}].nodes lists node {root}, a child of "
                                f"node {parent[root]}; a scene lists root nodes")


def _node_index(shown: str, where: str, value: Any, count: int) -> None:
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < count:
        raise MeshError(f"{shown}: {where} names node {value!r}, but the file has {count:,} "
                        f"node{'' if count == 1 else 's'} (0 to {count - 1:,})")


def _check_depth(shown: str, parent: np.ndarray) -> None:
    """Refuse a cycle (a node its own ancestor) or a chain deeper than MAX_NODE_DEPTH:
    each node's depth from its parent's, each node visited once."""
    depth = np.full(len(parent), -1, dtype=np.int64)  # -2: on the chain being walked
    for start in range(len(parent)):
        chain, node = [], start
        while node >= 0 and depth[node] < 0:
            chain.append(node)
            depth[node] = -2
            node = int(parent[node])
            if node >= 0 and depth[node] == -2:
                loop = chain[chain.index(node):]  # child to parent, back to node
                said = " -> ".join(str(n) for n in [*reversed(loop), loop[-1]][:9])
                raise MeshError(f"{shown}: the node hierarchy has a cycle (node {node} is "
                                f"its own ancestor: {said}); glTF nodes form trees")
        base = -1 if node < 0 else int(depth[node])
        for level, member in enumerate(reversed(chain), start=base + 1):
            depth[member] = level
        if base + len(chain) >= MAX_NODE_DEPTH:
            raise MeshError(f"{shown}: the node hierarchy is more than {MAX_NODE_DEPTH:,} "
                            f"levels deep (node {start} is at level {base + len(chain) + 1:,})")


#: PLY scalar types and their sizes in bytes.
_PLY_SIZES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2,
              "ushort": 2, "uint16": 2, "int": 4, "int32": 4, "uint": 4, "uint32": 4,
              "float": 4, "float32": 4, "double": 8, "float64": 8}
_PLY_COUNT = {1: "B", 2: "H", 4: "I"}  # unsigned codes of list counts by size


class _Lie(Exception):
    """The data does not hold what the header says (the message's tail)."""


def check_ply_counts(shown: str, data: bytes) -> None:
    """Refuse a PLY whose header's element counts are not what its data holds (a face
    count of 1,000 over 12 faces read as "contains no triangles", a vertex count of 100
    over 8 as garbage). A header this cannot parse is left to the loader."""
    header = _ply_header(data)
    if header is None:
        return
    fmt, elements, start = header
    summary = " and ".join(f"{count:,} {_plural(name, count)}" for name, count, _ in elements)
    body: Any
    if fmt == "ascii":
        end = len(data)
        while end > start and data[end - 1] in b" \t\r\n":
            end -= 1
        if data.count(b"\n", start, end) + 1 == sum(count for _, count, _ in elements) and (
                data.find(b"\n\n", start, end) < 0 and data.find(b"\n\r\n", start, end) < 0):
            return  # a record a line, as every writer does: the counts hold
        body = data[start:].split()  # else judge value by value
        sizes = dict.fromkeys(_PLY_SIZES, 1)
    else:
        body = memoryview(data)[start:]
        sizes = _PLY_SIZES
    try:
        held = _walk(elements, body, sizes, fmt)
    except _Lie as lie:
        raise MeshError(f"{shown}: PLY header says {summary}, but {lie}; re-export "
                        "it") from None
    extra = len(body) - held
    if extra > 0:
        unit = "values" if fmt == "ascii" else "bytes"
        name, count, props = elements[-1]
        more = _more_records(props, body, sizes, held, fmt)
        said = (f"the file holds {count + more:,} {_plural(name, 2)}" if more else
                f"the file holds {extra:,} {unit} more than those")
        raise MeshError(f"{shown}: PLY header says {summary}, but {said}; re-export it")


def _more_records(props: list[tuple], body: Any, sizes: dict[str, int], pos: int,
                  fmt: str) -> int | None:
    """How many more records like the last element's the data past ``pos`` holds
    exactly (same list lengths as the first of them), or None."""
    extra = len(body) - pos
    lists = [i for i, p in enumerate(props) if p[0] == "list"]
    if not lists:
        record = _fixed_size(props, sizes)
        return extra // record if record and extra % record == 0 else None
    if len(lists) > 1:
        return None
    at = sum(sizes[p[0]] for p in props[:lists[0]])
    size, item = sizes[props[lists[0]][1]], sizes[props[lists[0]][2]]
    if pos + at + size > len(body):
        return None
    try:
        k = (int(body[pos + at]) if fmt == "ascii" else struct.unpack_from(
            (">" if fmt == "binary_big_endian" else "<") + _PLY_COUNT.get(size, "Q"),
            body, pos + at)[0])
    except ValueError:
        return None
    record = sum(sizes[p[0]] for i, p in enumerate(props) if i != lists[0]) + size + k * item
    if not record or extra % record or not _same_lengths(body, pos + at, record,
                                                         extra // record, size, k, fmt):
        return None
    return extra // record


def _plural(name: str, count: int) -> str:
    if count == 1:
        return name
    return name[:-2] + "ices" if name.endswith("ex") else name + "s"


def _ply_header(data: bytes) -> tuple[str, list[tuple[str, int, list[tuple]]], int] | None:
    """(format, [(element, count, properties)], where the data starts), or None."""
    if not data.startswith(b"ply"):
        return None
    end = data.find(b"end_header", 0, 1 << 20)
    if end < 0:
        return None
    start = data.find(b"\n", end)
    if start < 0:
        return None
    fmt, elements = None, []
    try:
        for line in data[:end].decode("ascii").splitlines()[1:]:
            words = line.split()
            if not words or words[0] in ("comment", "obj_info"):
                continue
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property" and words[1] == "list":
                elements[-1][2].append(("list", words[2], words[3]))
            elif words[0] == "property":
                elements[-1][2].append((words[1],))
            else:
                return None
        if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
            return None
        if any(count < 0 or any(t not in _PLY_SIZES for p in props for t in p[1:] if
                                p[0] == "list") or any(p[0] not in _PLY_SIZES for p in props
                                                       if p[0] != "list")
               for _, count, props in elements):
            return None
    except (UnicodeDecodeError, IndexError, ValueError):
        return None
    return fmt, elements, start + 1


def _fixed_size(props: list[tuple], sizes: dict[str, int]) -> int:
    """A record's size, or 0 if it has a list (its size varies)."""
    if any(p[0] == "list" for p in props):
        return 0
    return sum(sizes[p[0]] for p in props)


def _walk(elements: list[tuple[str, int, list[tuple]]], body: Any, sizes: dict[str, int],
          fmt: str) -> int:
    """Where the data the header describes ends in ``body`` (bytes, or ASCII values);
    raises _Lie where it runs out first."""
    total, pos = len(body), 0
    order = ">" if fmt == "binary_big_endian" else "<"

    def count_at(at: int, size: int) -> int:
        if fmt == "ascii":
            try:
                return int(body[at])
            except ValueError:
                raise _Lie(f"its data has {body[at][:20].decode('latin-1')!r} where a list "
                           "length is") from None
        return struct.unpack_from(order + _PLY_COUNT.get(size, "Q"), body, at)[0]

    for name, count, props in elements:
        fixed = _fixed_size(props, sizes)
        if fixed or not props:
            if fixed and count * fixed > total - pos:
                raise _Lie(f"the file ends after {(total - pos) // fixed:,} "
                           f"{_plural(name, 2)}")
            pos += count * fixed
            continue
        pos = _walk_lists(name, count, props, body, sizes, pos, count_at, fmt)
    return pos


def _walk_lists(name: str, count: int, props: list[tuple], body: Any,
                sizes: dict[str, int], pos: int, count_at: Any, fmt: str) -> int:
    """_walk over an element with list properties: all records at once when they are
    the same length (triangles), else record by record."""
    total = len(body)
    lists = [i for i, p in enumerate(props) if p[0] == "list"]
    if count == 0:
        return pos
    if len(lists) == 1:  # one list: try every record as long as the first
        at = sum(sizes[p[0]] for p in props[:lists[0]])
        size, item = sizes[props[lists[0]][1]], sizes[props[lists[0]][2]]
        if pos + at + size <= total:
            k = count_at(pos + at, size)
            record = sum(sizes[p[0]] for i, p in enumerate(props) if i != lists[0]) \
                + size + k * item
            if record and count * record <= total - pos and _same_lengths(
                    body, pos + at, record, count, size, k, fmt):
                return pos + count * record
    for done in range(count):
        for prop in props:
            if prop[0] != "list":
                pos += sizes[prop[0]]
                continue
            size, item = sizes[prop[1]], sizes[prop[2]]
            if pos + size > total:
                raise _Lie(f"the file ends after {done:,} {_plural(name, 2)}")
            pos += size + count_at(pos, size) * item
        if pos > total:
            raise _Lie(f"the file ends after {done:,} {_plural(name, 2)}")
    return pos


def _same_lengths(body: Any, first: int, record: int, count: int, size: int, k: int,
                  fmt: str) -> bool:
    """Do all ``count`` records (``record`` apart from ``first``) have list length k?"""
    if fmt == "ascii":
        expected = body[first]
        return all(v == expected for v in body[first:first + count * record:record])
    dtype = np.dtype(("<" if fmt == "binary_little_endian" else ">") + f"u{size}")
    view = np.ndarray((count,), dtype=dtype, buffer=body, offset=first,
                      strides=(record,))
    return bool(np.all(view == k))


def triangle_estimate(suffix: str, data: bytes) -> int | None:
    """At least how many triangles a mesh file's bytes hold, read from what it says of
    itself before any parsing (so a budget refuses a huge file without loading it): a
    binary STL's header count, an ASCII STL's facets, a PLY's or OFF's face count, an
    OBJ's face lines, a glTF's triangle primitives (each mesh once); None for others."""
    suffix = suffix.lower()
    if suffix == ".stl":
        if data[:5].lower() == b"solid" and b"facet" in data[:1024]:
            return data.count(b"facet normal")
        return int.from_bytes(data[80:84], "little") if len(data) >= 84 else None
    if suffix == ".ply":
        header = _ply_header(data)
        return (next((count for name, count, _ in header[1] if name == "face"), 0)
                if header is not None else None)
    if suffix == ".obj":
        return data.count(b"\nf ") + data.startswith(b"f ")
    if suffix == ".off":
        words = data[:4096].split()  # "OFF", vertices, faces, edges
        if words and words[0].upper().endswith(b"OFF"):
            with contextlib.suppress(IndexError, ValueError):
                return int(words[2])
        return None
    if suffix in (".gltf", ".glb"):
        try:
            doc = gltf_document("", data)
        except MeshError:
            return None
        return _gltf_triangles(doc) if doc is not None else None
    return None


def _gltf_triangles(doc: dict[str, Any]) -> int:
    accessors = doc.get("accessors") if isinstance(doc.get("accessors"), list) else []
    total = 0
    for mesh in doc.get("meshes") or []:
        for primitive in (mesh.get("primitives") or []) if isinstance(mesh, dict) else []:
            if not isinstance(primitive, dict) or primitive.get("mode", 4) != 4:
                continue
            index = primitive.get("indices")
            if index is None:
                attributes = primitive.get("attributes")
                index = attributes.get("POSITION") if isinstance(attributes, dict) else None
            if isinstance(index, int) and 0 <= index < len(accessors) and isinstance(
                    accessors[index], dict) and isinstance(accessors[index].get("count"), int):
                total += max(0, accessors[index]["count"]) // 3
    return total
