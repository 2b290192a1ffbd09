"""The binary side of the glTF writer: a buffer of views and accessors, and float
helpers that keep JSON numbers and buffer values bit-identical.

Shared by :mod:`blastvox.export.gltf` (the document) and
:mod:`blastvox.export.gltf_meshes` (the pieces' meshes).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: glTF componentType and bufferView target constants (OpenGL enums)
FLOAT, UINT8, UINT16, UINT32 = 5126, 5121, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


class _Builder:
    """Accumulates buffer views and accessors over one binary buffer."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.size = 0
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []

    def view(self, data: bytes, target: int | None = None, stride: int | None = None) -> int:
        pad = -self.size % 4
        if pad:
            self.parts.append(b"\0" * pad)
            self.size += pad
        view: dict[str, Any] = {"buffer": 0, "byteOffset": self.size, "byteLength": len(data)}
        if stride is not None:
            view["byteStride"] = stride
        if target is not None:
            view["target"] = target
        self.parts.append(data)
        self.size += len(data)
        self.views.append(view)
        return len(self.views) - 1

    def accessor(self, view: int, offset: int, component: int, count: int, kind: str,
                 lo: list[float] | None = None, hi: list[float] | None = None,
                 normalized: bool = False) -> int:
        """lo/hi: min/max (lists of float32 values as floats, see :func:`_floats`);
        ``normalized``: integers read as fractions of their type's maximum."""
        acc: dict[str, Any] = {"bufferView": view, "componentType": component, "count": count,
                               "type": kind}
        if offset:
            acc["byteOffset"] = offset
        if normalized:
            acc["normalized"] = True
        if lo is not None:
            acc["min"], acc["max"] = lo, hi
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def blob(self) -> bytes:
        return b"".join(self.parts)


def _floats(a: Any) -> Any:
    """Nested lists of floats that JSON writes and reads back as exactly the same float32
    values (float32 -> float64 is exact, and ``repr`` of a float round-trips; no -0.0)."""
    return (np.asarray(a, dtype=np.float32).astype(np.float64) + 0.0).tolist()


def _f32(a: np.ndarray) -> bytes:
    return np.ascontiguousarray(a, dtype="<f4").tobytes()
