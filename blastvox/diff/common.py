"""Common types of ``blastvox diff``: file kinds, tolerances, :class:`DiffError`,
:class:`Difference` and the collector that compares values within tolerances."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from blastvox.errors import BlastvoxError

NPZ_SUFFIXES = (".npz",)
USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
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
               key_size: int = 1, frames: np.ndarray | None = None) -> None:
        """Compare two arrays (shape, then values) and add at most one difference.

        ``frame_axis``: the first axis is the frame (reported as ``frame``);
        ``key_size``: with ``frame_axis``, rows per key (glTF CUBICSPLINE: 3);
        ``frames``: the frame number of each key (default: its index).
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
            if frames is not None and frame < len(frames):
                frame = int(frames[frame])
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
