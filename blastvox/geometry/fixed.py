"""Elementary functions and sums that round the same whatever numpy dispatched to.

numpy picks its float64 loops for cbrt, exp, log, log2, power, arccos, arctan and
arctan2 at import, by the CPU's features: with AVX-512 on (a process that imported numpy
before blastvox, which otherwise turns it off, or another CPU) they are Intel's SVML
loops, which round differently from the AVX2 and baseline ones (those call libm). An
export's decisions (a key kept or dropped, a fracture face's rubble, a quantised
velocity) turned one ulp into other bytes: the house's .glb had two vertices fewer,
its .usdc other angular velocities (issue 37). Here every function calls libm in a
compiled loop (numba, :func:`blastvox.jit.kernel`), one element at a time, which gives
the CLI's bytes (numpy's AVX2 loops of these functions are libm's) in any process and
whatever ``NPY_DISABLE_CPU_FEATURES`` says. Scalars (a camera's angle, a tolerance)
go through :mod:`math`, which is libm too.

Sums and products (norms, dot products, a frame change) are in
:mod:`blastvox.geometry.exact`, in a fixed order with numpy's elementwise operations.

Shapes: any; the elementwise functions return float64 arrays of their broadcast
arguments' shape.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.jit import kernel

__all__ = ["arccos", "arctan2", "cbrt", "cos", "exp", "expm1", "hypot", "log2", "power",
           "sin"]

_CBRT, _SIN, _COS, _EXP, _EXPM1, _LOG2, _ACOS = range(7)
_ATAN2, _POW, _HYPOT = range(3)


@kernel
def _unary(code, x, out) -> None:  # pragma: no cover - numba
    """out[i] = f(x[i]) from libm, f chosen by ``code`` (one loop per function)."""
    n = x.shape[0]
    if code == _CBRT:
        for i in range(n):
            out[i] = np.cbrt(x[i])
    elif code == _SIN:
        for i in range(n):
            out[i] = math.sin(x[i])
    elif code == _COS:
        for i in range(n):
            out[i] = math.cos(x[i])
    elif code == _EXP:
        for i in range(n):
            out[i] = math.exp(x[i])
    elif code == _EXPM1:
        for i in range(n):
            out[i] = math.expm1(x[i])
    elif code == _LOG2:
        for i in range(n):
            out[i] = math.log2(x[i]) if x[i] > 0.0 else (
                -math.inf if x[i] == 0.0 else math.nan)
    else:
        for i in range(n):
            out[i] = math.acos(x[i]) if -1.0 <= x[i] <= 1.0 else math.nan


@kernel
def _binary(code, a, b, out) -> None:  # pragma: no cover - numba
    """out[i] = f(a[i], b[i]) from libm: atan2, hypot or pow, by ``code``."""
    if code == _ATAN2:
        for i in range(a.shape[0]):
            out[i] = math.atan2(a[i], b[i])
    elif code == _HYPOT:
        for i in range(a.shape[0]):
            out[i] = math.hypot(a[i], b[i])
    else:
        for i in range(a.shape[0]):
            out[i] = a[i] ** b[i]


def _apply(code: int, x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    flat = np.ascontiguousarray(x).reshape(-1)
    out = np.empty(flat.shape[0])
    _unary(code, flat, out)
    return out.reshape(x.shape)


def cbrt(x: np.ndarray) -> np.ndarray:
    """Cube roots of ``x`` (any shape), float64, libm's."""
    return _apply(_CBRT, x)


def sin(x: np.ndarray) -> np.ndarray:
    """Sines of ``x`` (any shape, rad), float64, libm's."""
    return _apply(_SIN, x)


def cos(x: np.ndarray) -> np.ndarray:
    """Cosines of ``x`` (any shape, rad), float64, libm's."""
    return _apply(_COS, x)


def exp(x: np.ndarray) -> np.ndarray:
    """e ** ``x`` (any shape), float64, libm's."""
    return _apply(_EXP, x)


def log2(x: np.ndarray) -> np.ndarray:
    """Base-2 logarithms of ``x`` (any shape; -inf at 0, nan below), float64, libm's."""
    return _apply(_LOG2, x)


def arccos(x: np.ndarray) -> np.ndarray:
    """Arc cosines of ``x`` (any shape; nan outside [-1, 1]), rad, float64, libm's."""
    return _apply(_ACOS, x)


def expm1(x: np.ndarray) -> np.ndarray:
    """e ** ``x`` - 1 (any shape), float64, libm's (exact near 0)."""
    return _apply(_EXPM1, x)


def _apply2(code: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a, b = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    out = np.empty(a.size)
    _binary(code, np.ascontiguousarray(a).reshape(-1), np.ascontiguousarray(b).reshape(-1), out)
    return out.reshape(a.shape)


def arctan2(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """atan2(y, x) (the broadcast shape of y and x), rad in [-pi, pi], float64, libm's."""
    return _apply2(_ATAN2, y, x)


def hypot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """sqrt(x^2 + y^2) (the broadcast shape of x and y), float64, libm's hypot."""
    return _apply2(_HYPOT, x, y)


def power(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """x ** y (the broadcast shape of x and y), float64, libm's pow."""
    return _apply2(_POW, x, y)
