"""Deterministic, self-describing ``.npz`` contract files.

NumPy's own ``np.savez`` stamps every member with the current time, so two runs
with the same inputs give different bytes. :func:`write_npz` writes the same
format (a zip of ``.npy`` members, readable by ``np.load``) with fixed member
timestamps and a fixed member order, atomically.

Every contract file carries a ``meta`` member: UTF-8 JSON (stored as a uint8
array, so no pickles are ever needed) with at least ``schema``,
``schema_version``, ``tool_version`` and ``units``.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from blastvox.errors import ContractError
from blastvox.io.atomic import atomic_path

_FIXED_DATE = (1980, 1, 1, 0, 0, 0)
META_KEY = "meta"


def encode_meta(meta: Mapping[str, Any]) -> np.ndarray:
    """JSON-encode ``meta`` deterministically (sorted keys) into a uint8 array."""
    text = json.dumps(meta, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return np.frombuffer(text.encode("utf-8"), dtype=np.uint8)


def write_npz(path: str | os.PathLike, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any],
              compress: bool = True) -> None:
    """Write ``arrays`` plus ``meta`` to ``path`` atomically and byte-reproducibly.

    Members are written in sorted key order with a fixed timestamp. Object
    arrays are refused: contract files must load with ``allow_pickle=False``.
    """
    members = dict(arrays)
    members[META_KEY] = encode_meta(meta)
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with atomic_path(path) as tmp, zipfile.ZipFile(tmp, "w", allowZip64=True) as zf:
        for key in sorted(members):
            array = np.ascontiguousarray(members[key])
            if array.dtype.hasobject:
                raise TypeError(f"member {key!r} is an object array; contracts never store pickles")
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_FIXED_DATE)
            info.compress_type = method
            info.external_attr = 0o644 << 16
            with zf.open(info, "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, array, allow_pickle=False)


def read_npz(path: str | os.PathLike, schema: str, max_version: int,
             what: str = "file") -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Load a contract file written by :func:`write_npz` and check its schema.

    Returns ``(meta, arrays)`` with every member loaded eagerly. Raises
    :class:`ContractError` (one line, naming ``path``) for a missing, truncated,
    foreign, pickled or newer-version file.
    """
    p = Path(path)
    if not p.is_file():
        raise ContractError(f"{p}: no such {what}")
    if not zipfile.is_zipfile(p):
        raise ContractError(f"{p}: not a blastvox {what} (not an .npz archive)")
    try:
        with np.load(p, allow_pickle=False) as data:
            if META_KEY not in data.files:
                raise ContractError(f"{p}: not a blastvox {what} (no '{META_KEY}' member)")
            arrays = {k: data[k] for k in data.files}
    except ContractError:
        raise
    except ValueError:  # pickled members refuse to load with allow_pickle=False
        raise ContractError(f"{p}: not a blastvox {what} (it holds pickled objects, which "
                            f"blastvox never loads)") from None
    except (OSError, zipfile.BadZipFile, EOFError) as exc:
        raise ContractError(
            f"{p}: not a readable .npz {what} (truncated or foreign: {exc})") from None
    try:
        meta = json.loads(arrays.pop(META_KEY).tobytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ContractError(f"{p}: corrupt metadata ({exc})") from None
    if not isinstance(meta, dict) or meta.get("schema") != schema:
        found = meta.get("schema") if isinstance(meta, dict) else None
        raise ContractError(f"{p}: expected a {schema} file, found {found!r}")
    version = meta.get("schema_version")
    if not isinstance(version, int) or version < 1:
        raise ContractError(f"{p}: invalid schema_version {version!r}")
    if version > max_version:
        raise ContractError(
            f"{p}: {schema} version {version} is newer than this blastvox understands "
            f"(up to {max_version}); upgrade blastvox")
    return meta, arrays
