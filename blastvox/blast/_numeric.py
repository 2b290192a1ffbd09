"""Plumbing shared by the blast modules: Horner's rule for compiled code, and the
NumPy faces' broadcasting around compiled loop kernels.

Every formula of the blast model is written once, as a scalar numba function. A
NumPy face (array in, array out) broadcasts its arguments, flattens them into
fresh float64 C arrays and hands them to a ``@nb.njit(cache=True)`` loop
kernel that calls the scalar function per element. The kernel therefore always
sees one argument type and is compiled, and cached, once.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from blastvox.jit import helper, kernel


@helper
def horner_nb(coeffs, u):
    """sum_i coeffs[i] u^i (coeffs a float64 array, highest power last)."""
    out = coeffs[coeffs.shape[0] - 1]
    for i in range(coeffs.shape[0] - 2, -1, -1):
        out = out * u + coeffs[i]
    return out


def flat_arrays(*values: Any) -> tuple[tuple[int, ...], list[np.ndarray]]:
    """The broadcast shape of ``values`` and each as a fresh, writeable 1-D float64 C array."""
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in values))
    return arrays[0].shape, [np.array(a, dtype=np.float64, order="C").reshape(-1)
                             for a in arrays]


def run_kernel(kernel: Callable[..., None], outputs: int,
               *values: Any) -> tuple[np.ndarray, ...]:
    """``kernel(*flat inputs, out)`` with out (outputs, N); each row in the broadcast shape."""
    shape, flat = flat_arrays(*values)
    out = np.empty((outputs, flat[0].size))
    kernel(*flat, out)
    return tuple(row.reshape(shape) for row in out)


@kernel
def _cbrt_kernel(x, out) -> None:
    for i in range(x.shape[0]):
        out[0, i] = np.cbrt(x[i])


@kernel
def _exp10_kernel(x, out) -> None:
    for i in range(x.shape[0]):
        out[0, i] = 10.0 ** x[i]


def cbrt(values: Any) -> np.ndarray:
    """The cube roots of ``values`` (any shape, float64), from libm in a compiled loop.

    numpy's own cbrt, exp, log, power and trigonometric loops are chosen at numpy's
    import for the CPU's features (AVX-512 or AVX2 loops round differently), so a shot
    run after numpy was imported with AVX-512 on differed from the CLI's, whose import
    of blastvox turns it off (issue 37). The simulator's inputs go through these."""
    return run_kernel(_cbrt_kernel, 1, values)[0]


def exp10(values: Any) -> np.ndarray:
    """10 ** ``values`` (any shape, float64) from libm in a compiled loop (see
    :func:`cbrt`)."""
    return run_kernel(_exp10_kernel, 1, values)[0]


def libm(function: Callable[[float], float], values: Any) -> np.ndarray:
    """``function`` (a scalar :mod:`math` function) of each of ``values`` (any shape),
    float64: for small arrays whose numpy loop would round as the CPU numpy dispatched
    to does (see :func:`cbrt`)."""
    x = np.asarray(values, dtype=np.float64)
    return np.fromiter((function(v) for v in x.ravel().tolist()), dtype=np.float64,
                       count=x.size).reshape(x.shape)
