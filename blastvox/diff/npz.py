"""``blastvox diff`` of blastvox .npz files (VoxelModel or SimCache)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from blastvox.diff.common import (
    _ABSENT,
    FRAME_MAJOR,
    Difference,
    DiffError,
    _Collector,
)


def _load_npz(path: Path) -> tuple[str, dict[str, Any], dict[str, np.ndarray]]:
    """(schema, meta, arrays) of a VoxelModel or SimCache, loaded without pickles."""
    from blastvox import cache, model
    from blastvox.io.npz import read_contract

    versions = {model.SCHEMA: model.SCHEMA_VERSION, cache.SCHEMA: cache.SCHEMA_VERSION}
    meta, arrays = read_contract(path, versions, what="file")  # diff_files names the error
    if meta["schema"] == cache.SCHEMA and "piece_position" in arrays:
        # positions as a SimCache reads them (float64 world), whatever the version
        cache.upgrade(meta, arrays)
        origin = arrays.pop("position_origin", None)
        position = arrays["piece_position"]
        if origin is not None and origin.shape == (3,) and position.ndim == 3 \
                and position.shape[-1] == 3:
            arrays["piece_position"] = cache.world_positions(origin, arrays["piece_position"])
    return meta["schema"], meta, arrays


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
