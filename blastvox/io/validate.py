"""Small, vectorised checks of contract-file arrays and meta values.

The contracts (:mod:`blastvox.model`, :mod:`blastvox.cache`) describe their
arrays and call these checks on load. Each check costs one or two passes over
its array (``min``/``max`` where possible, with no temporaries); only when it
fails does it search for the first offending element to name it. Every failure
raises :class:`~blastvox.errors.ContractError` with one line::

    <path>: array '<name>' <what is wrong> (<value> at [<index>])

so the CLI prints it as ``blastvox: error: ...`` and exits 1. ``name`` is the
name as stored in the file (``model.voxel_mass`` for a SimCache's embedded
model).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any, NoReturn

import numpy as np

from blastvox.errors import ContractError

#: A shape spec: each dimension a fixed size or a symbol looked up in ``dims``.
Shape = tuple[int | str, ...]
#: An array spec: (dtype, shape spec).
Spec = tuple[np.dtype | type, Shape]


def fail(path: str | os.PathLike, message: str) -> NoReturn:
    """Raise :class:`ContractError` ``"<path>: <message>"``."""
    raise ContractError(f"{path}: {message}")


def _at(arr: np.ndarray, bad: np.ndarray) -> tuple[Any, str]:
    """(value, "[i, j]") of the first True element of ``bad`` (same shape as ``arr``)."""
    flat = int(np.flatnonzero(bad.ravel())[0])
    index = np.unravel_index(flat, arr.shape)
    value = arr.reshape(-1)[flat]
    return value.item(), "[" + ", ".join(str(int(i)) for i in index) + "]"


def _show(value: Any) -> str:
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def _expected(spec: Spec, dims: Mapping[str, int] | None = None) -> str:
    dtype, shape = spec
    kind = "unicode" if np.dtype(dtype).kind == "U" else str(np.dtype(dtype))
    parts = [str(d) if isinstance(d, int) else (f"{d}={dims[d]}" if dims else d)
             for d in shape]
    inner = ", ".join(parts) + ("," if len(parts) == 1 else "")
    return f"({inner}) {kind}"


# ----------------------------------------------------------------------------- layout


def check_layout(path: str | os.PathLike, arrays: Mapping[str, np.ndarray],
                 specs: Mapping[str, Spec], prefix: str = "", kind: str = "file",
                 optional: Sequence[str] = ()) -> None:
    """Every array of ``specs`` is present (unless ``optional``), with its exact dtype
    and number of dimensions. Names in ``arrays`` and ``specs`` lack ``prefix``;
    messages add it."""
    for name, spec in specs.items():
        if name not in arrays:
            if name in optional:
                continue
            fail(path, f"{kind} is missing array '{prefix}{name}'")
        arr = arrays[name]
        dtype, shape = spec
        want = np.dtype(dtype)
        same = arr.dtype.kind == "U" if want.kind == "U" else arr.dtype == want
        if not same or arr.ndim != len(shape):
            fail(path, f"array '{prefix}{name}' has shape {arr.shape} and dtype {arr.dtype}; "
                       f"expected {_expected(spec)}")


def check_shapes(path: str | os.PathLike, arrays: Mapping[str, np.ndarray],
                 specs: Mapping[str, Spec], dims: Mapping[str, int], prefix: str = "",
                 meaning: Mapping[str, str] | None = None) -> None:
    """Every present array of ``specs`` has its full shape, symbols resolved by ``dims``
    (after :func:`check_layout`). ``meaning`` explains a symbol in the message
    (``{"N": "one per voxel"}``)."""
    for name, spec in specs.items():
        arr = arrays.get(name)
        if arr is None:
            continue
        want = tuple(d if isinstance(d, int) else dims[d] for d in spec[1])
        if arr.shape != want:
            why = next((f" ({meaning[d]})" for d in spec[1]
                        if isinstance(d, str) and meaning and d in meaning), "")
            fail(path, f"array '{prefix}{name}' has shape {arr.shape}; expected "
                       f"{_expected(spec, dims).rsplit(' ', 1)[0]}{why}")


# ----------------------------------------------------------------------------- values


def check_range(path: str | os.PathLike, name: str, arr: np.ndarray,
                lo: float | None = None, hi: float | None = None, *,
                lo_open: bool = False, hi_open: bool = False, finite: bool = True,
                rule: str | None = None) -> None:
    """Every element of ``arr`` is a number within [lo, hi] (bounds open if asked);
    NaN always fails; +-inf fails when ``finite`` (default) or outside the bounds.

    ``rule`` words the expectation in the message (default: built from the bounds).
    """
    if arr.size == 0:
        return
    if rule is None:
        words = ["a finite number" if finite else "a number"]
        if lo is not None:
            words.append(f"{'>' if lo_open else '>='} {lo:g}")
        if hi is not None:
            words.append(f"{'<' if hi_open else '<='} {hi:g}")
        rule = " ".join(words[:1]) + (" " + " and ".join(words[1:]) if len(words) > 1 else "")
        if not finite:
            rule += " (inf allowed)"
    mn, mx = arr.min(), arr.max()  # NaN propagates into both
    ok = not (np.isnan(mn) or np.isnan(mx)) if arr.dtype.kind == "f" else True
    if ok and finite and arr.dtype.kind == "f":
        ok = bool(np.isfinite(mn) and np.isfinite(mx))
    if ok and lo is not None:
        ok = bool(mn > lo if lo_open else mn >= lo)
    if ok and hi is not None:
        ok = bool(mx < hi if hi_open else mx <= hi)
    if ok:
        return
    good = ~np.isnan(arr) if arr.dtype.kind == "f" else np.ones(arr.shape, dtype=bool)
    if finite and arr.dtype.kind == "f":
        good &= np.isfinite(arr)
    if lo is not None:
        good &= (arr > lo) if lo_open else (arr >= lo)
    if hi is not None:
        good &= (arr < hi) if hi_open else (arr <= hi)
    value, index = _at(arr, ~good)
    fail(path, f"array '{name}' holds a value that is not {rule} ({_show(value)} at {index})")


def check_finite(path: str | os.PathLike, name: str, arr: np.ndarray) -> None:
    """No NaN or +-inf in ``arr``."""
    check_range(path, name, arr)


def check_bound(path: str | os.PathLike, name: str, arr: np.ndarray, limit: float) -> None:
    """Finite, with every |element| <= ``limit`` (coordinates, m)."""
    check_range(path, name, arr, -limit, limit,
                rule=f"a finite coordinate within +-{limit:g} m")


def check_index(path: str | os.PathLike, name: str, arr: np.ndarray, upper: int,
                thing: str, none: int | None = None) -> None:
    """Every element of integer ``arr`` is an index in [0, upper), or equals ``none``
    (e.g. -1: "never"). Message: ``array 'voxel_piece' refers to piece 7 of 5``."""
    if arr.size == 0:
        return
    lower = 0 if none is None else min(0, none)
    mn, mx = int(arr.min()), int(arr.max())
    if mn >= lower and mx < upper:
        return
    bad = (arr < 0) | (arr >= upper)
    if none is not None:
        bad &= arr != none
    value, index = _at(arr, bad)
    if value < 0:
        allowed = f" other than {none}" if none is not None else ""
        fail(path, f"array '{name}' holds a negative {thing} index{allowed} "
                   f"({value} at {index})")
    fail(path, f"array '{name}' refers to {thing} {value} of {upper} (at {index})")


def check_values(path: str | os.PathLike, name: str, arr: np.ndarray,
                 allowed: Sequence[int]) -> None:
    """Every element of integer ``arr`` is one of ``allowed``."""
    if arr.size == 0:
        return
    if arr.dtype == np.uint8:  # a histogram is one fast pass
        counts = np.bincount(arr.reshape(-1), minlength=256)
        counts[list(allowed)] = 0
        if not counts.any():
            return
    bad = ~np.isin(arr, np.asarray(allowed, dtype=arr.dtype))
    if bad.any():
        value, index = _at(arr, bad)
        fail(path, f"array '{name}' holds {value} at {index}; expected one of "
                   f"{', '.join(str(a) for a in allowed)}")


def check_non_decreasing(path: str | os.PathLike, name: str, arr: np.ndarray) -> None:
    """1-D ``arr`` never decreases."""
    if len(arr) > 1:
        drop = arr[1:] < arr[:-1]
        if drop.any():
            i = int(np.flatnonzero(drop)[0]) + 1
            fail(path, f"array '{name}' decreases at [{i}] ({_show(arr[i - 1].item())} then "
                       f"{_show(arr[i].item())})")


def check_offsets(path: str | os.PathLike, name: str, arr: np.ndarray, total: int,
                  what: str) -> None:
    """CSR offsets (C+1,): start at 0, never decrease, end at ``total`` (the number of
    ``what``). The length is checked by :func:`check_shapes`."""
    if len(arr) == 0:
        fail(path, f"array '{name}' is empty; expected at least [0]")
    if arr[0] != 0:
        fail(path, f"array '{name}' starts at {arr[0]}; expected 0")
    check_non_decreasing(path, name, arr)
    if arr[-1] != total:
        fail(path, f"array '{name}' ends at {arr[-1]}; expected {total} (the number of {what})")


def check_unique(path: str | os.PathLike, name: str, arr: np.ndarray, upper: int,
                 thing: str) -> None:
    """Every element of ``arr`` is an index in [0, upper), none twice (O(upper) memory)."""
    check_index(path, name, arr, upper, thing)
    if arr.size:
        seen = np.zeros(upper, dtype=bool)
        seen[arr] = True
        if int(np.count_nonzero(seen)) != arr.size:
            _, first = np.unique(arr, return_index=True)
            dup = np.setdiff1d(np.arange(arr.size), first)[0]
            fail(path, f"array '{name}' lists {thing} {arr[dup]} twice (again at [{dup}])")


def check_unit(path: str | os.PathLike, name: str, arr: np.ndarray, tolerance: float,
               what: str = "unit vector") -> None:
    """Finite rows along the last axis of length 1 within ``tolerance``."""
    check_finite(path, name, arr)
    if arr.size == 0:
        return
    rows = arr.reshape(-1, arr.shape[-1]).astype(np.float64, copy=False)
    square = np.einsum("ij,ij->i", rows, rows)
    if (1.0 - tolerance) ** 2 <= square.min() and square.max() <= (1.0 + tolerance) ** 2:
        return
    length = np.sqrt(square)
    row = int(np.flatnonzero(np.abs(length - 1.0) > tolerance)[0])
    index = np.unravel_index(row, arr.shape[:-1])
    fail(path, f"array '{name}' holds a value that is not a {what} (length "
               f"{length[row]:.6g} at [{', '.join(str(int(i)) for i in index)}])")


# ----------------------------------------------------------------------------- meta


def is_number(value: Any) -> bool:
    """An int or float from JSON (not a bool)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def check_meta_number(path: str | os.PathLike, key: str, value: Any,
                      lo: float | None = None, lo_open: bool = False,
                      limit: float | None = None, integer: bool = False) -> None:
    """``meta <key>`` is a finite number (an int if ``integer``), >= / > ``lo``, and
    |value| <= ``limit``."""
    ok = (isinstance(value, int) and not isinstance(value, bool)) if integer else (
        is_number(value) and math.isfinite(value))
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and limit is not None:
        ok = abs(value) <= limit
    if not ok:
        rule = "an integer" if integer else "a finite number"
        if lo is not None:
            rule += f" {'>' if lo_open else '>='} {lo:g}"
        if limit is not None:
            rule += f" within +-{limit:g}"
        fail(path, f"meta {key} is {value!r}; expected {rule}")


def check_meta_vector(path: str | os.PathLike, key: str, value: Any, size: int = 3,
                      limit: float | None = None) -> None:
    """``meta <key>`` is a list of ``size`` finite numbers (each within +-``limit``)."""
    ok = (isinstance(value, list) and len(value) == size
          and all(is_number(v) and math.isfinite(v) for v in value))
    if ok and limit is not None:
        ok = all(abs(v) <= limit for v in value)
    if not ok:
        within = f" within +-{limit:g}" if limit is not None else ""
        fail(path, f"meta {key} is {value!r}; expected a list of {size} finite numbers{within}")
