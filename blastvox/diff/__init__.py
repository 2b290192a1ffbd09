"""Compare two blastvox outputs within tolerances: the golden-file check for CI.

:func:`diff_files` compares two files of the same kind and returns their
differences (empty when they agree):

* blastvox ``.npz`` (VoxelModel or SimCache): meta (JSON, ``tool_version``
  ignored) and every array: names, shapes, dtypes and values;
* OpenUSD (``.usd``/``.usda``/``.usdc``/``.usdz``; a .usda may be compared with a .usdc):
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

Modules: :mod:`~blastvox.diff.common` (kinds, tolerances, :class:`Difference`,
:class:`DiffError`, value comparison), :mod:`~blastvox.diff.npz`,
:mod:`~blastvox.diff.usd` and :mod:`~blastvox.diff.gltf` (one per kind of file).
"""

from __future__ import annotations

import math
from pathlib import Path

from blastvox.diff.common import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    FRAME_MAJOR,
    GLTF_SUFFIXES,
    KIND_NAMES,
    KINDS,
    NPZ_SUFFIXES,
    USD_SUFFIXES,
    Difference,
    DiffError,
    _Collector,
    _Full,
)
from blastvox.diff.gltf import _diff_gltf
from blastvox.diff.npz import _diff_npz
from blastvox.diff.usd import _diff_usd
from blastvox.errors import BlastvoxError
from blastvox.io.references import ReferencePolicy

__all__ = [
    "DEFAULT_ATOL",
    "DEFAULT_RTOL",
    "FRAME_MAJOR",
    "GLTF_SUFFIXES",
    "KIND_NAMES",
    "KINDS",
    "NPZ_SUFFIXES",
    "USD_SUFFIXES",
    "DiffError",
    "Difference",
    "diff_files",
    "kind_of",
]


def kind_of(path: str | Path) -> str | None:
    """"npz", "usd" or "gltf" by suffix; None for anything else."""
    return KINDS.get(Path(path).suffix.lower())


def diff_files(a: str | Path, b: str | Path, atol: float = DEFAULT_ATOL,
               rtol: float = DEFAULT_RTOL, limit: int | None = 20,
               references: ReferencePolicy | None = None) -> list[Difference]:
    """The differences between files ``a`` and ``b`` (at most ``limit``; None: all).

    Raises :class:`DiffError` (one line) if either file is missing or unreadable,
    if they are of different kinds, if a tolerance is negative, or if either refers to
    a file (a USD layer's sublayers, references, payloads, clips and assets, a .gltf's
    buffers) that the reader policy ``references`` refuses (default: regular files in
    the file's folder, :mod:`blastvox.io.references`), checked before anything opens it.
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
            from blastvox.io.outputs import not_a_file

            raise DiffError(not_a_file(p))
    out = _Collector(atol, rtol, limit)
    compare = {"npz": _diff_npz, "usd": _diff_usd, "gltf": _diff_gltf}[kinds[0]]
    try:
        if kinds[0] == "npz":
            compare(a, b, out)
        else:
            compare(a, b, out, references or ReferencePolicy())
    except _Full:
        pass
    except BlastvoxError as exc:
        if isinstance(exc, DiffError):
            raise
        raise DiffError(str(exc)) from None
    return out.items
