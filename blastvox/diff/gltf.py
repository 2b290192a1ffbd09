"""``blastvox diff`` of glTF 2.0 files (.glb/.gltf): the JSON document, every accessor, and
the animations by their values at the frames (:mod:`blastvox.diff.gltf_anim`)."""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np

from blastvox.diff.common import (
    Difference,
    DiffError,
    _Collector,
)
from blastvox.diff.gltf_anim import (
    animation_accessors,
    diff_animations,
    without_animation_keys,
)
from blastvox.errors import MeshError
from blastvox.io.mesh_checks import check_gltf_nodes
from blastvox.io.references import ReferencePolicy, ReferenceRefused

_COMPONENT = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTH = {"SCALAR": (1, 1), "VEC2": (1, 2), "VEC3": (1, 3), "VEC4": (1, 4),
          "MAT2": (2, 2), "MAT3": (3, 3), "MAT4": (4, 4)}  # (columns, rows)
_NORMALIZE = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0, 5125: 4294967295.0}
_GLB_MAGIC, _GLB_JSON, _GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


def _load_gltf(path: Path, policy: ReferencePolicy) -> tuple[dict[str, Any], list[bytes]]:
    """The document and every buffer's bytes of a .glb or a .gltf (with its files)."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise DiffError(f"{path}: cannot read ({exc.strerror or exc})") from None
    glb_bin: bytes | None = None
    if path.suffix.lower() == ".glb" or data[:4] == b"glTF":
        try:
            magic, version, length = struct.unpack_from("<III", data, 0)
            if magic != _GLB_MAGIC:
                raise ValueError("bad magic")
            if version != 2:
                raise ValueError(f"GLB version {version}")
            if length > len(data):
                raise ValueError(f"truncated: header says {length} bytes, file has {len(data)}")
            pos, chunks = 12, []
            while pos + 8 <= length:
                size, kind = struct.unpack_from("<II", data, pos)
                if pos + 8 + size > length:
                    raise ValueError("truncated chunk")
                chunks.append((kind, data[pos + 8:pos + 8 + size]))
                pos += 8 + size
            if not chunks or chunks[0][0] != _GLB_JSON:
                raise ValueError("first chunk is not JSON")
            text = chunks[0][1]
            glb_bin = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _GLB_BIN else None
        except (struct.error, ValueError) as exc:
            raise DiffError(f"{path}: not a valid .glb ({exc})") from None
    else:
        text = data
    try:
        doc = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DiffError(f"{path}: not a valid glTF JSON document ({exc})") from None
    except RecursionError:
        raise DiffError(f"{path}: its JSON is nested too deep to read") from None
    if not isinstance(doc, dict):
        raise DiffError(f"{path}: not a glTF document (the JSON is not an object)")
    asset = doc.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    if not isinstance(version, str) or not version.startswith("2."):
        raise DiffError(f"{path}: not a glTF 2.0 document (asset.version is "
                        f"{version!r}; the specification requires it)")
    try:  # a node its own ancestor, two parents, absurd depth: one line, as voxelize says
        check_gltf_nodes(str(path), doc)
    except MeshError as exc:
        raise DiffError(str(exc)) from None
    buffers = []
    for i, buf in enumerate(_list(doc, "buffers")):
        uri = buf.get("uri") if isinstance(buf, dict) else None
        if uri is None:
            if glb_bin is None:
                raise DiffError(f"{path}: buffers[{i}] has no uri and there is no GLB BIN chunk")
            buffers.append(glb_bin)
        elif uri.startswith("data:"):
            try:
                buffers.append(base64.b64decode(uri.split(",", 1)[1], validate=True))
            except (IndexError, ValueError) as exc:
                raise DiffError(f"{path}: buffers[{i}] has a bad data uri ({exc})") from None
        else:  # a side file, under the reader policy (no device, FIFO, URL or escape)
            try:
                buffers.append(policy.read(path, unquote(uri), kind=f"buffers[{i}]"))
            except ReferenceRefused as exc:
                raise DiffError(str(exc)) from None
            except OSError as exc:
                raise DiffError(f"{path}: buffers[{i}] file {path.parent / unquote(uri)} "
                                f"cannot be read ({exc.strerror or exc})") from None
    return doc, buffers


def _list(doc: dict[str, Any], key: str) -> list[Any]:
    value = doc.get(key, [])
    return value if isinstance(value, list) else []


def _view_bytes(path: Path, doc: dict[str, Any], buffers: list[bytes], index: int) -> tuple[
        bytes, int, int, int | None]:
    """(buffer bytes, view start, view length, byteStride) of bufferViews[index]."""
    try:
        view = doc["bufferViews"][index]
        data = buffers[view["buffer"]]
        start = int(view.get("byteOffset", 0))
        length = int(view["byteLength"])
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise DiffError(f"{path}: bufferViews[{index}] is invalid ({exc!r})") from None
    if start < 0 or start + length > len(data):
        raise DiffError(f"{path}: bufferViews[{index}] lies outside its buffer "
                        f"({start}+{length} > {len(data)} bytes)")
    return data, start, length, view.get("byteStride")


def _read(path: Path, doc: dict[str, Any], buffers: list[bytes], view: int, offset: int,
          component: int, count: int, columns: int, rows: int, where: str) -> np.ndarray:
    """(count, columns, rows) components of ``component`` type from a buffer view."""
    data, start, length, stride = _view_bytes(path, doc, buffers, view)
    dtype = np.dtype(_COMPONENT[component])
    size = dtype.itemsize
    column_stride = (rows * size + 3) // 4 * 4 if columns > 1 else rows * size
    element = column_stride * (columns - 1) + rows * size
    stride = int(stride) if stride else column_stride * columns
    if count and offset + (count - 1) * stride + element > length:
        raise DiffError(f"{path}: {where} reads past the end of bufferViews[{view}]")
    if count == 0:
        return np.zeros((0, columns, rows), dtype=dtype)
    arr = np.ndarray((count, columns, rows), dtype=dtype, buffer=data, offset=start + offset,
                     strides=(stride, column_stride, size))
    return arr.copy()


def _accessor(path: Path, doc: dict[str, Any], buffers: list[bytes], index: int) -> np.ndarray:
    """accessors[index] decoded: (count,) or (count, n) (matrices column-major, flattened);
    normalized integers as floats."""
    where = f"accessors[{index}]"
    try:
        acc = doc["accessors"][index]
        component, kind, count = int(acc["componentType"]), acc["type"], int(acc["count"])
        columns, rows = _WIDTH[kind]
        dtype = np.dtype(_COMPONENT[component])
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise DiffError(f"{path}: {where} is invalid ({exc!r})") from None
    if "bufferView" in acc:
        arr = _read(path, doc, buffers, int(acc["bufferView"]), int(acc.get("byteOffset", 0)),
                    component, count, columns, rows, where)
    else:
        arr = np.zeros((count, columns, rows), dtype=dtype)
    sparse = acc.get("sparse")
    if isinstance(sparse, dict):
        try:
            n = int(sparse["count"])
            ind, val = sparse["indices"], sparse["values"]
            idx = _read(path, doc, buffers, int(ind["bufferView"]), int(ind.get("byteOffset", 0)),
                        int(ind["componentType"]), n, 1, 1, where + ".sparse.indices")
            values = _read(path, doc, buffers, int(val["bufferView"]),
                           int(val.get("byteOffset", 0)), component, n, columns, rows,
                           where + ".sparse.values")
            idx = idx.reshape(-1).astype(np.int64)
            if idx.size and (idx.min() < 0 or idx.max() >= count):
                raise ValueError("sparse index out of range")
            arr[idx] = values
        except (KeyError, TypeError, ValueError) as exc:
            raise DiffError(f"{path}: {where}.sparse is invalid ({exc!r})") from None
    if acc.get("normalized") and component in _NORMALIZE:
        arr = np.maximum(arr.astype(np.float64) / _NORMALIZE[component], -1.0)
    return arr.reshape(count) if columns * rows == 1 else arr.reshape(count, columns * rows)


def _accessor_uses(doc: dict[str, Any]) -> dict[int, tuple[str, str | None, int | None]]:
    """Accessor index -> (the first JSON path that refers to it, what it animates (an
    output's channel target, e.g. "piece_00003.rotation") or None, entries per animation
    key or None when it is not an animation sampler's)."""
    uses: dict[int, tuple[str, str | None, int | None]] = {}

    def use(acc: Any, where: str, per_key: int | None = None, target: str | None = None
            ) -> None:
        if isinstance(acc, int) and acc not in uses:
            uses[acc] = (where, target, per_key)

    accessors, nodes = _list(doc, "accessors"), _list(doc, "nodes")
    for a, anim in enumerate(_list(doc, "animations")):
        if not isinstance(anim, dict):
            continue
        targets: dict[int, str] = {}
        for channel in anim.get("channels", []):
            try:
                node, prop = channel["target"].get("node"), channel["target"]["path"]
                name = nodes[node].get("name") if isinstance(node, int) else None
                targets.setdefault(int(channel["sampler"]),
                                   f"{name or f'nodes[{node}]'}.{prop}")
            except (KeyError, IndexError, TypeError, ValueError, AttributeError):
                continue
        for s, sampler in enumerate(anim.get("samplers", [])):
            if not isinstance(sampler, dict):
                continue
            base = f"animations[{a}].samplers[{s}]"
            use(sampler.get("input"), f"{base}.input", 1)
            per_key = 1
            try:
                keys = int(accessors[sampler["input"]]["count"])
                outs = int(accessors[sampler["output"]]["count"])
                per_key = max(1, outs // keys) if keys else 1
            except (KeyError, IndexError, TypeError, ValueError):
                pass
            use(sampler.get("output"), f"{base}.output", per_key, targets.get(s))
    for m, mesh in enumerate(_list(doc, "meshes")):
        for p, prim in enumerate(mesh.get("primitives", []) if isinstance(mesh, dict) else []):
            if not isinstance(prim, dict):
                continue
            base = f"meshes[{m}].primitives[{p}]"
            use(prim.get("indices"), f"{base}.indices")
            for name, acc in sorted((prim.get("attributes") or {}).items()):
                use(acc, f"{base}.attributes.{name}")
            for t, target in enumerate(prim.get("targets") or []):
                for name, acc in sorted(target.items() if isinstance(target, dict) else []):
                    use(acc, f"{base}.targets[{t}].{name}")
    for s, skin in enumerate(_list(doc, "skins")):
        if isinstance(skin, dict):
            use(skin.get("inverseBindMatrices"), f"skins[{s}].inverseBindMatrices")
    return uses


def _gltf_skip(path: str) -> bool:
    """JSON paths not compared: buffer layout and the writer's version."""
    if path == "asset.generator" or path == "buffers" or path.startswith("buffers["):
        return True
    last = path.rsplit(".", 1)[-1]
    if path.startswith("bufferViews[") and last in ("byteOffset", "byteLength", "byteStride"):
        return True
    return path.startswith("accessors[") and last == "byteOffset"


def _diff_gltf(a: Path, b: Path, out: _Collector, policy: ReferencePolicy) -> None:
    doc_a, buf_a = _load_gltf(a, policy)
    doc_b, buf_b = _load_gltf(b, policy)
    # decode first, so an unreadable file is an error (exit 2), not a difference
    acc_a = [_accessor(a, doc_a, buf_a, i) for i in range(len(_list(doc_a, "accessors")))]
    acc_b = [_accessor(b, doc_b, buf_b, i) for i in range(len(_list(doc_b, "accessors")))]
    # animations by their values at the frames (their keys may differ): gltf_anim
    anim_a, anim_b = animation_accessors(doc_a), animation_accessors(doc_b)
    out.values(without_animation_keys(doc_a, anim_a), without_animation_keys(doc_b, anim_b),
               "", skip=_gltf_skip)
    uses = _accessor_uses(doc_a)
    rest_a = [i for i in range(len(acc_a)) if i not in anim_a]
    rest_b = [i for i in range(len(acc_b)) if i not in anim_b]
    diff_animations(doc_a, doc_b, acc_a.__getitem__, acc_b.__getitem__, out)
    for i, j in zip(rest_a, rest_b, strict=False):
        where, target, per_key = uses.get(i, (f"accessors[{i}]", None, None))
        attribute = f"accessors[{i}]" if where != f"accessors[{i}]" else None
        if attribute and target:
            attribute += f" ({target})"
        out.arrays(acc_a[i], acc_b[j], where, attribute, frame_axis=per_key is not None,
                   key_size=per_key or 1)
    for i, (ia, ib) in enumerate(zip(_list(doc_a, "images"), _list(doc_b, "images"),
                                     strict=False)):
        if isinstance(ia, dict) and isinstance(ib, dict) and "bufferView" in ia \
                and "bufferView" in ib:
            da, sa, la, _ = _view_bytes(a, doc_a, buf_a, int(ia["bufferView"]))
            db, sb, lb, _ = _view_bytes(b, doc_b, buf_b, int(ib["bufferView"]))
            if da[sa:sa + la] != db[sb:sb + lb]:
                out.add(Difference(f"images[{i}]", "bufferView", None, f"{la} bytes",
                                   f"{lb} bytes", "image data"))

