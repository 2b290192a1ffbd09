"""``blastvox diff`` of OpenUSD stages (.usd/.usda/.usdc)."""

from __future__ import annotations

import contextlib
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from blastvox.diff.common import (
    _ABSENT,
    Difference,
    DiffError,
    _Collector,
)
from blastvox.errors import BlastvoxError
from blastvox.io.references import ReferencePolicy


def _open_stage(path: Path) -> Any:
    try:
        from pxr import Tf, Usd
    except ImportError:
        raise DiffError("comparing USD files needs the USD Python bindings "
                        "(pip install usd-core)") from None
    # USD's warnings while composing (a layer it could not open, a sublayer cycle) are
    # C++ lines on stderr after which the stage is composed without what failed: they
    # are kept here, and the stage's composition errors refuse the comparison
    trap = getattr(Tf, "DiagnosticTrap", contextlib.nullcontext)
    try:
        with trap() as kept:
            stage = Usd.Stage.Open(str(path), Usd.Stage.LoadAll)
            errors = list(stage.GetCompositionErrors()) if stage is not None else []
            if errors and kept is not None:
                kept.Clear()  # said in one line below instead
    except Tf.ErrorException as exc:
        raise DiffError(f"{path}: not a readable USD file ({_first_line(exc)})") from None
    if stage is None:
        raise DiffError(f"{path}: not a readable USD file")
    if errors:
        more = f" (and {len(errors) - 1:,} more)" if len(errors) > 1 else ""
        message = " ".join(str(errors[0]).split())
        raise DiffError(f"{path}: USD could not compose it: {message}{more}; diff compares "
                        "only stages that compose without errors")
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


def _diff_usd(a: Path, b: Path, out: _Collector, policy: ReferencePolicy) -> None:
    from blastvox.diff.usd_refs import check_usd_references

    for path in (a, b):  # before USD opens anything they name
        check_usd_references(path, policy)
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
    va, vb = qa.Get(Usd.TimeCode.Default()), qb.Get(Usd.TimeCode.Default())
    _usd_compare(va, vb, path, name, None, out)
    if type_a == "asset":  # a texture: what the file holds, not only its name
        _usd_asset_content(va, vb, path, name, out)
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


def _usd_asset_content(va: Any, vb: Any, path: str, name: str, out: _Collector) -> None:
    """A difference if the files two asset paths resolve to (beside the layer, or inside
    a .usdz) hold different bytes, or only one of them resolves."""
    ha, hb = _asset_digest(va), _asset_digest(vb)
    if ha != hb:
        out.add(Difference(path, name, None, ha, hb, "asset content"))


def _asset_digest(value: Any) -> str | None:
    """'<bytes> bytes, sha256 <first 12 hex>' of the file an Sdf.AssetPath resolves to;
    'missing' if it does not resolve; None for no asset."""
    import hashlib

    from pxr import Ar

    if value is None or not getattr(value, "path", ""):
        return None
    resolved = value.resolvedPath
    if not resolved:
        return "missing"
    if not resolved.endswith("]"):  # a file (not in a package): judged again as read
        try:
            data = ReferencePolicy(anywhere=True).read(Path(resolved), resolved)
        except (OSError, BlastvoxError) as exc:
            return f"unread ({exc})"
        return f"{len(data)} bytes, sha256 {hashlib.sha256(data).hexdigest()[:12]}"
    asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    if asset is None:
        return "missing"
    data = bytes(asset.GetBuffer())
    return f"{len(data)} bytes, sha256 {hashlib.sha256(data).hexdigest()[:12]}"


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

