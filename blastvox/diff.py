"""Compare two blastvox outputs within tolerances: the golden-file check for CI.

:func:`diff_files` compares two files of the same kind and returns their
differences (empty when they agree):

* blastvox ``.npz`` (VoxelModel or SimCache): meta (JSON, ``tool_version``
  ignored) and every array: names, shapes, dtypes and values;
* OpenUSD (``.usd``/``.usda``/``.usdc``; a .usda may be compared with a .usdc):
  stage metadata (upAxis, metersPerUnit, timeCodesPerSecond, framesPerSecond,
  start/end time codes, defaultPrim, customLayerData except ``creator``), prim
  paths, types and applied schemas, every authored attribute (type, default
  value and the value at every time code sampled in either file, so a sample
  one file holds implicitly by interpolation still compares equal),
  connections, ``interpolation``/``elementSize`` metadata, and relationship
  targets (material bindings);
* glTF 2.0 (``.glb``/``.gltf``; a .glb may be compared with a .gltf): the JSON
  document except where buffers are laid out (``bufferViews[*].byteOffset``/
  ``byteLength``/``byteStride``, ``accessors[*].byteOffset``, ``buffers[*]``
  and ``asset.generator``), then every accessor decoded to numpy
  (componentType, type, normalized, byteStride, sparse) and compared by value.

Floating-point values agree when ``|a - b| <= atol + rtol * |b|`` (NaN equals
NaN, infinities must match); integers, booleans and strings must be equal.
Each array or value that differs gives one :class:`Difference` that names the
first element that differs, how many do, and the largest deviation.

Anything that prevents a comparison (a missing or unreadable file, two
different kinds of file) raises :class:`DiffError`, whose exit code is 2.
"""

from __future__ import annotations

import base64
import json
import math
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np

from blastvox.errors import BlastvoxError

NPZ_SUFFIXES = (".npz",)
USD_SUFFIXES = (".usd", ".usda", ".usdc")
GLTF_SUFFIXES = (".glb", ".gltf")
KINDS = {**{s: "npz" for s in NPZ_SUFFIXES}, **{s: "usd" for s in USD_SUFFIXES},
         **{s: "gltf" for s in GLTF_SUFFIXES}}
KIND_NAMES = {"npz": "blastvox .npz", "usd": "USD", "gltf": "glTF"}
DEFAULT_ATOL = 1e-6
DEFAULT_RTOL = 1e-6
_ABSENT = "<absent>"

#: SimCache arrays whose first axis is the output frame.
FRAME_MAJOR = frozenset({"frame_time", "piece_position", "piece_orientation", "shock_radius",
                         "shock_opacity", "camera_offset"})


class DiffError(BlastvoxError):
    """The files cannot be compared (missing, unreadable, different kinds): exit code 2."""

    exit_code = 2


@dataclass(frozen=True)
class Difference:
    """One difference between A and B.

    ``path``: a prim path (USD), a JSON path (glTF, npz meta) or an array name
    (npz); ``attribute``: the attribute, accessor or property that differs (or
    None); ``frame``: the time code (USD), animation key index (glTF) or frame
    index (SimCache frame-major arrays), None where there is none; ``value_a``
    and ``value_b``: the differing values (for arrays, the first differing
    element); ``note``: where in the value and how much (element index, count,
    largest deviation), or what kind of difference (shape, dtype, absent).
    """

    path: str
    attribute: str | None = None
    frame: float | int | None = None
    value_a: Any = None
    value_b: Any = None
    note: str = ""

    def format(self) -> str:
        """One line: ``path attribute @ frame N (note): A=... B=...``."""
        out = self.path
        if self.attribute:
            out += f" {self.attribute}"
        if self.frame is not None:
            frame = self.frame
            if isinstance(frame, float) and frame.is_integer():
                frame = int(frame)
            out += f" @ frame {frame}"
        if self.note:
            out += f" ({self.note})"
        return f"{out}: A={_show(self.value_a)} B={_show(self.value_b)}"


def kind_of(path: str | Path) -> str | None:
    """"npz", "usd" or "gltf" by suffix; None for anything else."""
    return KINDS.get(Path(path).suffix.lower())


def diff_files(a: str | Path, b: str | Path, atol: float = DEFAULT_ATOL,
               rtol: float = DEFAULT_RTOL, limit: int | None = 20) -> list[Difference]:
    """The differences between files ``a`` and ``b`` (at most ``limit``; None: all).

    Raises :class:`DiffError` (one line) if either file is missing or unreadable,
    if they are of different kinds, or if a tolerance is negative.
    """
    a, b = Path(a), Path(b)
    for name, tol in (("atol", atol), ("rtol", rtol)):
        if not (isinstance(tol, int | float) and math.isfinite(tol) and tol >= 0):
            raise DiffError(f"--{name} must be a finite number >= 0 (got {tol!r})")
    kinds = []
    for p in (a, b):
        kind = kind_of(p)
        if kind is None:
            raise DiffError(f"{p}: unknown format {p.suffix or '(no suffix)'!r}; diff compares "
                            f"{', '.join(NPZ_SUFFIXES + USD_SUFFIXES + GLTF_SUFFIXES)} files")
        kinds.append(kind)
    if kinds[0] != kinds[1]:
        raise DiffError(f"cannot compare {a} ({KIND_NAMES[kinds[0]]}) with {b} "
                        f"({KIND_NAMES[kinds[1]]}): different kinds of file")
    for p in (a, b):
        if not p.is_file():
            raise DiffError(f"{p}: no such file")
    out = _Collector(atol, rtol, limit)
    compare = {"npz": _diff_npz, "usd": _diff_usd, "gltf": _diff_gltf}[kinds[0]]
    try:
        compare(a, b, out)
    except _Full:
        pass
    except BlastvoxError as exc:
        if isinstance(exc, DiffError):
            raise
        raise DiffError(str(exc)) from None
    return out.items


# ----------------------------------------------------------------------------- values

class _Full(Exception):
    """Raised by the collector once it holds ``limit`` differences."""


class _Collector:
    def __init__(self, atol: float, rtol: float, limit: int | None) -> None:
        self.atol, self.rtol = float(atol), float(rtol)
        self.limit = limit
        self.items: list[Difference] = []

    def add(self, diff: Difference) -> None:
        self.items.append(diff)
        if self.limit is not None and len(self.items) >= self.limit:
            raise _Full

    def floats_close(self, a: float, b: float) -> bool:
        if a == b or (math.isnan(a) and math.isnan(b)):
            return True
        return abs(a - b) <= self.atol + self.rtol * abs(b)

    def arrays(self, a: np.ndarray, b: np.ndarray, path: str, attribute: str | None = None,
               frame: float | int | None = None, frame_axis: bool = False,
               key_size: int = 1) -> None:
        """Compare two arrays (shape, then values) and add at most one difference.

        ``frame_axis``: the first axis is the frame (reported as ``frame``);
        ``key_size``: with ``frame_axis``, rows per key (glTF CUBICSPLINE: 3).
        """
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            self.add(Difference(path, attribute, frame, a.shape, b.shape, "shape"))
            return
        bad = _mismatch(a, b, self.atol, self.rtol)
        if bad is None:
            self.add(Difference(path, attribute, frame, str(a.dtype), str(b.dtype),
                                "incomparable types"))
            return
        if not bad.any():
            return
        first = np.unravel_index(int(np.flatnonzero(bad)[0]), bad.shape)
        count = int(bad.sum())
        rows = bad.reshape(bad.shape[0], -1).any(axis=1) if bad.ndim else bad
        row = first[0] if bad.ndim else ()
        # the vector that holds the first difference (a whole short 1-D value, e.g. a Gf vector)
        if bad.ndim > 1:
            element = first[:-1]
        elif bad.ndim == 1 and bad.size <= 4 and not frame_axis:
            element = (slice(None),)
        else:
            element = first
        note = f"[{', '.join(str(int(i)) for i in first)}]" if bad.ndim else ""
        if frame_axis and bad.ndim:
            frame = int(row) // key_size
            note = f"[{', '.join(str(int(i)) for i in first[1:])}]" if bad.ndim > 1 else ""
        if bad.ndim:
            what = "rows" if bad.ndim > 1 else "elements"
            parts = [f"{int(rows.sum())} of {bad.shape[0]} {what} differ"]
            if bad.ndim > 1 and count > 1:
                parts.append(f"{count} values")
            dev = _max_deviation(a, b, bad)
            if dev is not None:
                parts.append(f"max |A-B| {dev:.3g}")
            note = ", ".join(p for p in [note, *parts] if p)
        self.add(Difference(path, attribute, frame, _plain(a[element]), _plain(b[element]),
                            note))

    def values(self, a: Any, b: Any, path: str, attribute: str | None = None,
               frame: float | int | None = None,
               skip: Callable[[str], bool] | None = None) -> None:
        """Compare JSON-like values (dicts, lists, numbers, strings, arrays) recursively."""
        if isinstance(a, dict) and isinstance(b, dict):
            for key in sorted(set(a) | set(b), key=str):
                sub = f"{path}.{key}" if path else str(key)
                if skip is not None and skip(sub):
                    continue
                if key not in b:
                    self.add(Difference(sub, attribute, frame, a[key], _ABSENT, "only in A"))
                elif key not in a:
                    self.add(Difference(sub, attribute, frame, _ABSENT, b[key], "only in B"))
                else:
                    self.values(a[key], b[key], sub, attribute, frame, skip)
            return
        if isinstance(a, list | tuple) and isinstance(b, list | tuple):
            if len(a) != len(b):
                self.add(Difference(path, attribute, frame, len(a), len(b), "length"))
            for i, (x, y) in enumerate(zip(a, b, strict=False)):
                self.values(x, y, f"{path}[{i}]", attribute, frame, skip)
            return
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            self.arrays(np.asarray(a), np.asarray(b), path, attribute, frame)
            return
        if _is_number(a) and _is_number(b):
            if isinstance(a, float) or isinstance(b, float):
                same = self.floats_close(float(a), float(b))
            else:
                same = a == b
        else:
            same = type(a) is type(b) and a == b
        if not same:
            self.add(Difference(path, attribute, frame, a, b))


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float | np.integer | np.floating) and not isinstance(
        x, bool | np.bool_)


def _mismatch(a: np.ndarray, b: np.ndarray, atol: float, rtol: float) -> np.ndarray | None:
    """Boolean mask of elements that differ (same shapes); None if not comparable."""
    ka, kb = a.dtype.kind, b.dtype.kind
    if ka in "fc" or kb in "fc":
        if ka not in "biufc" or kb not in "biufc":
            return None
        x = a.astype(np.complex128 if "c" in (ka, kb) else np.float64)
        y = b.astype(x.dtype)
        with np.errstate(invalid="ignore", over="ignore"):
            close = (x == y) | (np.abs(x - y) <= atol + rtol * np.abs(y))
        return ~(close | (np.isnan(x) & np.isnan(y)))
    if (ka in "biu") != (kb in "biu"):
        return None
    return a != b


def _max_deviation(a: np.ndarray, b: np.ndarray, bad: np.ndarray) -> float | None:
    if a.dtype.kind not in "biufc" or b.dtype.kind not in "biufc" or a.dtype.kind == "b":
        return None
    with np.errstate(invalid="ignore", over="ignore"):
        dev = np.abs(a[bad].astype(np.complex128 if "c" in (a.dtype.kind, b.dtype.kind)
                                   else np.float64) - b[bad])
    dev = dev[np.isfinite(dev)]
    return float(dev.max()) if dev.size else None


def _plain(x: Any) -> Any:
    """numpy scalars and arrays as Python values for display."""
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


def _show(x: Any, width: int = 100) -> str:
    """A short one-line rendering of a value (floats with 9 significant digits)."""
    def fmt(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.9g}"
        if isinstance(v, list | tuple):
            inner = ", ".join(fmt(i) for i in v)
            return f"[{inner}]" if isinstance(v, list) else f"({inner})"
        if isinstance(v, str):
            return v if v == _ABSENT else json.dumps(v)
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(str(k))}: {fmt(i)}" for k, i in v.items()) + "}"
        return str(v)

    text = " ".join(fmt(_plain(x)).split())
    return text if len(text) <= width else text[:width - 3] + "..."


# ----------------------------------------------------------------------------- npz

def _load_npz(path: Path) -> tuple[str, dict[str, Any], dict[str, np.ndarray]]:
    """(schema, meta, arrays) of a VoxelModel or SimCache, loaded without pickles."""
    from blastvox import cache, model
    from blastvox.io.npz import META_KEY, read_npz

    schema = None
    try:
        with np.load(path, allow_pickle=False) as data:
            if META_KEY in data.files:
                meta = json.loads(data[META_KEY].tobytes().decode("utf-8"))
                schema = meta.get("schema") if isinstance(meta, dict) else None
    except Exception:  # truncated, foreign, pickled...: read_npz gives the precise error
        schema = None
    versions = {model.SCHEMA: model.SCHEMA_VERSION, cache.SCHEMA: cache.SCHEMA_VERSION}
    if isinstance(schema, str) and schema not in versions:
        raise DiffError(f"{path}: expected a {model.SCHEMA} or {cache.SCHEMA} file, "
                        f"found {schema!r}")
    schema = schema if schema in versions else model.SCHEMA
    meta, arrays = read_npz(path, schema, versions[schema], what="blastvox file")
    return schema, meta, arrays


def _diff_npz(a: Path, b: Path, out: _Collector) -> None:
    schema_a, meta_a, arrays_a = _load_npz(a)
    schema_b, meta_b, arrays_b = _load_npz(b)
    if schema_a != schema_b:
        raise DiffError(f"cannot compare {a} ({schema_a}) with {b} ({schema_b}): "
                        f"different kinds of file")
    out.values(meta_a, meta_b, "meta", skip=lambda p: p.rsplit(".", 1)[-1] == "tool_version")
    from blastvox.cache import SCHEMA as CACHE_SCHEMA

    n_frames = len(arrays_a.get("frame_time", ()))
    for name in sorted(set(arrays_a) | set(arrays_b)):
        if name not in arrays_b:
            out.add(Difference(name, None, None, _shape(arrays_a[name]), _ABSENT, "only in A"))
            continue
        if name not in arrays_a:
            out.add(Difference(name, None, None, _ABSENT, _shape(arrays_b[name]), "only in B"))
            continue
        x, y = arrays_a[name], arrays_b[name]
        if x.dtype != y.dtype:
            out.add(Difference(name, "dtype", None, str(x.dtype), str(y.dtype), "dtype"))
            continue
        frame_axis = (schema_a == CACHE_SCHEMA and name in FRAME_MAJOR and x.ndim >= 1
                      and len(x) == n_frames)
        out.arrays(x, y, name, frame_axis=frame_axis)


def _shape(x: np.ndarray) -> str:
    return f"{x.dtype}{list(x.shape)}"


# ----------------------------------------------------------------------------- USD

def _open_stage(path: Path) -> Any:
    try:
        from pxr import Tf, Usd
    except ImportError:
        raise DiffError("comparing USD files needs the USD Python bindings "
                        "(pip install usd-core)") from None
    try:
        stage = Usd.Stage.Open(str(path), Usd.Stage.LoadAll)
    except Tf.ErrorException as exc:
        raise DiffError(f"{path}: not a readable USD file ({_first_line(exc)})") from None
    if stage is None:
        raise DiffError(f"{path}: not a readable USD file")
    return stage


def _first_line(exc: BaseException) -> str:
    """The first USD error's own message, one line, without the C++ source location."""
    first = str(exc.args[0]) if exc.args else str(exc)
    message = first.split(" : ", 1)[1] if " : " in first else first
    message = " ".join(message.split()).strip("'\" ")
    return re.sub(r" matching .*? at '", " at '", message) or type(exc).__name__


def _usd_value(v: Any) -> Any:
    """A USD value as something :meth:`_Collector.values` compares: numpy arrays for
    numeric data, lists of strings for token/string/path arrays, dicts, scalars."""
    from pxr import Gf, Sdf

    if v is None or isinstance(v, bool | int | float | str):
        return v
    if isinstance(v, Sdf.Path):
        return str(v)
    if isinstance(v, Sdf.AssetPath):
        return v.path
    if isinstance(v, Gf.Quatd | Gf.Quatf | Gf.Quath):
        return np.array([v.real, *v.imaginary], dtype=np.float64)
    if isinstance(v, dict):
        return {str(k): _usd_value(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_usd_value(x) for x in v]
    try:
        arr = np.asarray(v)
    except Exception:
        arr = None
    if arr is not None and arr.dtype.kind in "biufc":
        return arr
    try:  # token, string, path and asset arrays
        return [str(_usd_value(x)) for x in v]
    except TypeError:
        return repr(v)


def _diff_usd(a: Path, b: Path, out: _Collector) -> None:
    sa, sb = _open_stage(a), _open_stage(b)
    _usd_stage_metadata(sa, sb, out)
    prims_a = {str(p.GetPath()): p for p in sa.TraverseAll()}
    prims_b = {str(p.GetPath()): p for p in sb.TraverseAll()}
    for path in sorted(set(prims_a) | set(prims_b)):
        pa, pb = prims_a.get(path), prims_b.get(path)
        if pb is None:
            out.add(Difference(path, None, None, pa.GetTypeName() or "prim", _ABSENT,
                               "prim only in A"))
            continue
        if pa is None:
            out.add(Difference(path, None, None, _ABSENT, pb.GetTypeName() or "prim",
                               "prim only in B"))
            continue
        if pa.GetTypeName() != pb.GetTypeName():
            out.add(Difference(path, "type", None, pa.GetTypeName(), pb.GetTypeName(),
                               "prim type"))
        if list(pa.GetAppliedSchemas()) != list(pb.GetAppliedSchemas()):
            out.add(Difference(path, "apiSchemas", None, list(pa.GetAppliedSchemas()),
                               list(pb.GetAppliedSchemas())))
        if pa.IsActive() != pb.IsActive():
            out.add(Difference(path, "active", None, pa.IsActive(), pb.IsActive()))
        _usd_properties(pa, pb, path, out)


def _usd_stage_metadata(sa: Any, sb: Any, out: _Collector) -> None:
    def meta(stage: Any) -> dict[str, Any]:
        layer_data = dict(stage.GetRootLayer().customLayerData)
        layer_data.pop("creator", None)  # the tool version, like the npz tool_version
        default = stage.GetDefaultPrim()
        return {
            "upAxis": stage.GetMetadata("upAxis") if stage.HasAuthoredMetadata("upAxis")
            else None,
            "metersPerUnit": stage.GetMetadata("metersPerUnit")
            if stage.HasAuthoredMetadata("metersPerUnit") else None,
            "timeCodesPerSecond": stage.GetTimeCodesPerSecond(),
            "framesPerSecond": stage.GetFramesPerSecond(),
            "startTimeCode": stage.GetStartTimeCode(),
            "endTimeCode": stage.GetEndTimeCode(),
            "defaultPrim": str(default.GetPath()) if default else None,
            "customLayerData": _usd_value(layer_data),
        }

    ma, mb = meta(sa), meta(sb)
    for key in ma:
        if key == "customLayerData":
            out.values(ma[key], mb[key], "/customLayerData")
        else:
            out.values(ma[key], mb[key], "/", key)


def _usd_properties(pa: Any, pb: Any, path: str, out: _Collector) -> None:
    attrs_a = {x.GetName(): x for x in pa.GetAuthoredAttributes()}
    attrs_b = {x.GetName(): x for x in pb.GetAuthoredAttributes()}
    rels_a = {x.GetName(): x for x in pa.GetAuthoredRelationships()}
    rels_b = {x.GetName(): x for x in pb.GetAuthoredRelationships()}
    for name in sorted(set(attrs_a) | set(attrs_b)):
        xa, xb = attrs_a.get(name), attrs_b.get(name)
        if xb is None:
            out.add(Difference(path, name, None, str(xa.GetTypeName()), _ABSENT,
                               "attribute only in A"))
            continue
        if xa is None:
            out.add(Difference(path, name, None, _ABSENT, str(xb.GetTypeName()),
                               "attribute only in B"))
            continue
        _usd_attribute(xa, xb, path, name, out)
    for name in sorted(set(rels_a) | set(rels_b)):
        ra, rb = rels_a.get(name), rels_b.get(name)
        ta = [str(t) for t in ra.GetTargets()] if ra is not None else _ABSENT
        tb = [str(t) for t in rb.GetTargets()] if rb is not None else _ABSENT
        if ta != tb:
            note = ("relationship only in A" if rb is None else
                    "relationship only in B" if ra is None else "targets")
            out.add(Difference(path, name, None, ta, tb, note))


def _usd_attribute(xa: Any, xb: Any, path: str, name: str, out: _Collector) -> None:
    from pxr import Usd

    type_a, type_b = str(xa.GetTypeName()), str(xb.GetTypeName())
    if type_a != type_b:
        out.add(Difference(path, name, None, type_a, type_b, "value type"))
        return
    if xa.GetVariability() != xb.GetVariability():
        out.add(Difference(path, name, None, str(xa.GetVariability()),
                           str(xb.GetVariability()), "variability"))
    ca = [str(t) for t in xa.GetConnections()]
    cb = [str(t) for t in xb.GetConnections()]
    if ca != cb:
        out.add(Difference(path, name, None, ca, cb, "connections"))
    for key in ("interpolation", "elementSize"):
        ka, kb = xa.GetMetadata(key), xb.GetMetadata(key)
        if ka != kb:
            out.add(Difference(path, name, None, ka, kb, key))
    qa, qb = Usd.AttributeQuery(xa), Usd.AttributeQuery(xb)  # faster repeated Get
    _usd_compare(qa.Get(Usd.TimeCode.Default()), qb.Get(Usd.TimeCode.Default()), path, name,
                 None, out)
    # the value at every time code either file samples: one difference per attribute, at
    # the first time code that differs, with how many do
    times = sorted(set(qa.GetTimeSamples()) | set(qb.GetTimeSamples()))
    found = _Collector(out.atol, out.rtol, None)
    first: Difference | None = None
    count = 0
    for t in times:
        _usd_compare(qa.Get(t), qb.Get(t), path, name, t, found)
        if found.items:
            first = first or found.items[0]
            count += 1
            found.items.clear()
    if first is not None:
        note = f"{count} of {len(times)} time codes differ"
        out.add(replace(first, note=f"{first.note}; {note}" if first.note else note))


def _usd_compare(va: Any, vb: Any, path: str, name: str, frame: float | None,
                 out: _Collector) -> None:
    try:  # fast path: Vt arrays and Gf values compare in C++
        same = va == vb
        if isinstance(same, bool) and same:
            return
    except Exception:
        pass
    pa, pb = _usd_value(va), _usd_value(vb)
    if isinstance(pa, np.ndarray) and isinstance(pb, np.ndarray):
        out.arrays(pa, pb, path, name, frame)
    else:
        out.values(pa, pb, path, name, frame)


# ----------------------------------------------------------------------------- glTF

_COMPONENT = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTH = {"SCALAR": (1, 1), "VEC2": (1, 2), "VEC3": (1, 3), "VEC4": (1, 4),
          "MAT2": (2, 2), "MAT3": (3, 3), "MAT4": (4, 4)}  # (columns, rows)
_NORMALIZE = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0, 5125: 4294967295.0}
_GLB_MAGIC, _GLB_JSON, _GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


def _load_gltf(path: Path) -> tuple[dict[str, Any], list[bytes]]:
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
    if not isinstance(doc, dict):
        raise DiffError(f"{path}: not a glTF document (the JSON is not an object)")
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
        else:
            file = path.parent / unquote(uri)
            try:
                buffers.append(file.read_bytes())
            except OSError as exc:
                raise DiffError(f"{path}: buffers[{i}] file {file} cannot be read "
                                f"({exc.strerror or exc})") from None
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


def _diff_gltf(a: Path, b: Path, out: _Collector) -> None:
    doc_a, buf_a = _load_gltf(a)
    doc_b, buf_b = _load_gltf(b)
    # decode first, so an unreadable file is an error (exit 2), not a difference
    acc_a = [_accessor(a, doc_a, buf_a, i) for i in range(len(_list(doc_a, "accessors")))]
    acc_b = [_accessor(b, doc_b, buf_b, i) for i in range(len(_list(doc_b, "accessors")))]
    out.values(doc_a, doc_b, "", skip=_gltf_skip)
    uses = _accessor_uses(doc_a)
    for i in range(min(len(acc_a), len(acc_b))):
        where, target, per_key = uses.get(i, (f"accessors[{i}]", None, None))
        attribute = f"accessors[{i}]" if where != f"accessors[{i}]" else None
        if attribute and target:
            attribute += f" ({target})"
        out.arrays(acc_a[i], acc_b[i], where, attribute, frame_axis=per_key is not None,
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

