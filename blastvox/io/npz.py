"""Deterministic, self-describing ``.npz`` contract files.

NumPy's own ``np.savez`` stamps every member with the current time, so two runs
with the same inputs give different bytes. :func:`write_npz` writes the same
format (a zip of ``.npy`` members, readable by ``np.load``) with fixed member
timestamps and a fixed member order, atomically.

Every contract file carries a ``meta`` member: UTF-8 JSON (stored as a uint8
array, so no pickles are ever needed) with at least ``schema``,
``schema_version``, ``tool_version`` and ``units``.

:func:`read_npz` reads only the members its caller names (others are never
decompressed), refuses a file whose members would decompress to more than
:data:`MAX_NPZ_BYTES` (or ``$BLASTVOX_MAX_NPZ_BYTES``) or, above
:data:`RATIO_FLOOR_BYTES`, to more than :data:`MAX_NPZ_RATIO` times its size,
and checks each member's ``.npy`` header against the member's size before
reading its data. What the arrays hold is checked by the contracts themselves
(:mod:`blastvox.model`, :mod:`blastvox.cache`, with :mod:`blastvox.io.validate`).
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from collections.abc import Callable, Collection, Mapping
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


#: Default cap on the bytes a contract file's members may decompress to (all members
#: read, summed, as the zip directory declares them): 8 GiB. Override with the
#: environment variable :data:`MAX_BYTES_ENV`.
MAX_NPZ_BYTES = 8 * 2**30
#: Environment variable that replaces :data:`MAX_NPZ_BYTES` (a byte count: ``17179869184``,
#: or with a binary suffix: ``16G``, ``512M``); setting it also lifts the ratio check.
MAX_BYTES_ENV = "BLASTVOX_MAX_NPZ_BYTES"
#: Files whose members decompress to more than :data:`RATIO_FLOOR_BYTES` may do so at
#: most this many times the file's size. blastvox's own files hold float data that
#: deflate shrinks a few times at most; a zip bomb of zeros reaches ~1000.
MAX_NPZ_RATIO = 200
RATIO_FLOOR_BYTES = 256 * 2**20

MemberFilter = Callable[[str], bool] | Collection[str]

_SUFFIXES = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}
_ALLOWED_KINDS = "biufU"  # bool, int, uint, float, fixed-width unicode
_CHUNK = 16 * 2**20


def max_npz_bytes() -> tuple[int, bool]:
    """(cap in bytes, whether it was set by :data:`MAX_BYTES_ENV`).

    Raises :class:`ContractError` for a value that is not a byte count.
    """
    text = os.environ.get(MAX_BYTES_ENV, "").strip()
    if not text:
        return MAX_NPZ_BYTES, False
    body = text.upper().removesuffix("IB").removesuffix("B")
    suffix = body[-1:] if body[-1:] in _SUFFIXES else ""
    number = body[: len(body) - len(suffix)].strip()
    if not number.isdigit():
        raise ContractError(f"{MAX_BYTES_ENV}={text!r}: expected a byte count such as "
                            f"17179869184 or 16G")
    return int(number) * _SUFFIXES[suffix], True


def _size(n: int) -> str:
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n} bytes"


def _wants(members: MemberFilter | None) -> Callable[[str], bool]:
    if members is None:
        return lambda _name: True
    if callable(members):
        return members
    known = frozenset(members)
    return known.__contains__


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def read_npz(path: str | os.PathLike, schema: str, max_version: int,
             what: str = "file", members: MemberFilter | None = None
             ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Load a contract file of ``schema`` (at most ``max_version``): :func:`read_contract`
    of one schema."""
    return read_contract(path, {schema: max_version}, what, members)


def read_contract(path: str | os.PathLike, versions: Mapping[str, int], what: str = "file",
                  members: MemberFilter | None = None
                  ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Load a contract file written by :func:`write_npz` whose meta names one of the
    schemas of ``versions`` (schema -> newest version read); ``meta["schema"]`` says which.

    Returns ``(meta, arrays)``: the JSON ``meta`` and every member that
    ``members`` selects (a collection of member names, without ``.npy``, or a
    predicate on them; ``None`` selects all), loaded eagerly as writeable arrays.
    **Members not selected are ignored without being decompressed**, so an
    unknown member, however large, costs nothing; so are zip entries that are not
    ``.npy`` files.

    Before decompressing anything it checks the zip directory: only stored or
    deflated members; the selected members' declared sizes summed at most
    :func:`max_npz_bytes` (8 GiB, or ``$BLASTVOX_MAX_NPZ_BYTES``) and, above
    :data:`RATIO_FLOOR_BYTES`, at most :data:`MAX_NPZ_RATIO` times the file's
    size. Each member's ``.npy`` header is read first and its shape times item size
    must equal the member's size before any data is read; object (pickled),
    structured and other non-numeric dtypes are refused (pickles are never
    loaded). Raises :class:`ContractError` (one line, naming ``path``) for all of
    these and for a missing, truncated, corrupt, foreign or newer-version file.
    """
    p = Path(path)
    if not p.is_file():
        from blastvox.io.outputs import not_a_file

        raise ContractError(not_a_file(p, what))
    if not zipfile.is_zipfile(p):
        raise ContractError(f"{p}: not a blastvox {what} (not an .npz archive)")
    wanted = _wants(members)
    try:
        with zipfile.ZipFile(p) as zf:
            infos = _select(p, zf, wanted, what)
            meta = _read_meta(p, zf, infos.pop(META_KEY), versions)
            arrays = {key: _read_member(p, zf, info, key) for key, info in infos.items()}
    except ContractError:
        raise
    except (OSError, zipfile.BadZipFile, EOFError, ValueError, RuntimeError,
            NotImplementedError, zlib.error) as exc:
        raise ContractError(
            f"{p}: not a readable .npz {what} (truncated or foreign: {_one_line(exc)})") from None
    return meta, arrays


def _select(p: Path, zf: zipfile.ZipFile, wanted: Callable[[str], bool],
            what: str) -> dict[str, zipfile.ZipInfo]:
    """The zip entries to read (meta first), after the directory-level checks."""
    infos: dict[str, zipfile.ZipInfo] = {}
    for info in zf.infolist():
        if info.is_dir() or not info.filename.endswith(".npy"):
            continue
        key = info.filename[: -len(".npy")]
        if key != META_KEY and not wanted(key):
            continue
        if key in infos:
            raise ContractError(f"{p}: member '{key}' appears twice")
        if info.flag_bits & 0x1:
            raise ContractError(f"{p}: member '{key}' is encrypted")
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise ContractError(f"{p}: member '{key}' uses zip compression method "
                                f"{info.compress_type}; blastvox files use deflate or none")
        infos[key] = info
    if META_KEY not in infos:
        raise ContractError(f"{p}: not a blastvox {what} (no '{META_KEY}' member)")
    total = sum(info.file_size for info in infos.values())
    cap, explicit = max_npz_bytes()
    if total > cap:
        raise ContractError(
            f"{p}: its arrays would decompress to {_size(total)}, more than the "
            f"{_size(cap)} allowed; set {MAX_BYTES_ENV} to a larger byte count to load it")
    file_size = p.stat().st_size
    if not explicit and total > RATIO_FLOOR_BYTES and total > MAX_NPZ_RATIO * file_size:
        raise ContractError(
            f"{p}: its arrays would decompress to {_size(total)}, {total / file_size:.0f} "
            f"times the file's {_size(file_size)} (a decompression bomb?); set "
            f"{MAX_BYTES_ENV} to a byte count to load it anyway")
    return {META_KEY: infos.pop(META_KEY), **infos}


def _read_meta(p: Path, zf: zipfile.ZipFile, info: zipfile.ZipInfo,
               versions: Mapping[str, int]) -> dict[str, Any]:
    raw = _read_member(p, zf, info, META_KEY)
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise ContractError(f"{p}: corrupt metadata ('{META_KEY}' has shape {raw.shape} and "
                            f"dtype {raw.dtype}; expected 1-D uint8 JSON)")
    try:
        meta = json.loads(raw.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ContractError(f"{p}: corrupt metadata ({_one_line(exc)})") from None
    schema = meta.get("schema") if isinstance(meta, dict) else None
    if not isinstance(schema, str) or schema not in versions:
        raise ContractError(f"{p}: expected a {' or '.join(versions)} file, found "
                            f"{'a meta naming no schema' if schema is None else repr(schema)}")
    check_schema_version(p, "", meta, schema, versions[schema])
    return meta


def check_schema_version(path: str | os.PathLike, where: str, meta: Mapping[str, Any],
                         schema: str, max_version: int) -> None:
    """``meta["schema_version"]`` is an int in 1..``max_version``; else :class:`ContractError`.

    ``where`` prefixes the message (``"meta 'model': "`` for an embedded meta).
    """
    version = meta.get("schema_version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ContractError(f"{path}: {where}invalid schema_version {version!r}")
    if version > max_version:
        raise ContractError(
            f"{path}: {where}{schema} version {version} is newer than this blastvox "
            f"understands (up to {max_version}); upgrade blastvox")


def _read_member(p: Path, zf: zipfile.ZipFile, info: zipfile.ZipInfo, key: str) -> np.ndarray:
    """One ``.npy`` member: header first (dtype, and shape against the member's size),
    then exactly the data it declares."""
    with zf.open(info) as fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
            else:
                raise ContractError(f"{p}: member '{key}' is a .npy file of version "
                                    f"{version[0]}.{version[1]}, which blastvox does not read")
        except (ValueError, SyntaxError, EOFError) as exc:
            raise ContractError(f"{p}: member '{key}' has no valid .npy header "
                                f"({_one_line(exc)})") from None
        if dtype.hasobject:
            raise ContractError(f"{p}: member '{key}' holds pickled objects, which "
                                "blastvox never loads")
        if (dtype.kind not in _ALLOWED_KINDS or dtype.names is not None or dtype.subdtype
                or dtype.itemsize == 0):
            raise ContractError(f"{p}: member '{key}' has dtype {dtype}, which no blastvox "
                                "file holds")
        if any(n < 0 for n in shape):
            raise ContractError(f"{p}: member '{key}' declares the shape {shape}")
        count = math.prod(shape)
        nbytes = count * dtype.itemsize
        header = fh.tell()
        if nbytes != info.file_size - header:
            raise ContractError(
                f"{p}: member '{key}' declares shape {shape} of {dtype} ({nbytes} bytes) but "
                f"holds {info.file_size - header} bytes of data")
        flat = np.empty(count, dtype=dtype)
        if nbytes:
            view = memoryview(flat.view(np.uint8))
            done = 0
            while done < nbytes:
                got = fh.readinto(view[done: done + _CHUNK])
                if not got:
                    raise ContractError(f"{p}: member '{key}' is truncated")
                done += got
    if fortran:
        return flat.reshape(shape[::-1]).transpose()
    return flat.reshape(shape)
