"""How the simulator's numba functions are compiled: kernels and helpers.

A *kernel* is called from Python (``@nb.njit(cache=True)``). A *helper* is
called only from other compiled functions (:func:`helper`): numba then builds no
CPython wrapper for it, the code that unboxes each argument from a Python
object. That wrapper is never used for a helper, yet costs about 60 ms plus
15 ms per array argument to compile, on every first run: without it the
kernels of a first run compile about 7 % faster.

numba itself would crash if such a function were called from Python, so a
helper raises a TypeError instead; its ``py_func`` is the plain Python function.
"""

from __future__ import annotations

from collections.abc import Callable

import numba as nb
from numba.core.registry import CPUDispatcher


class HelperDispatcher(CPUDispatcher):
    """A numba dispatcher without a Python entry point (see the module docstring)."""

    def __call__(self, *args, **kwargs):
        raise TypeError(f"{self.py_func.__module__}.{self.py_func.__qualname__} is compiled "
                        "for other numba functions only; call its .py_func from Python")


def helper(func: Callable) -> Callable:
    """``@nb.njit(cache=True)`` for a function called only from compiled code."""
    if nb.config.DISABLE_JIT:
        return func
    dispatcher = HelperDispatcher(py_func=func, locals={}, targetoptions={
        "nopython": True, "boundscheck": None, "no_cpython_wrapper": True,
        "no_cfunc_wrapper": True})
    dispatcher.enable_caching()
    return dispatcher
