"""How blastvox's numba functions are compiled: kernels and helpers, and where they are cached.

Every numba function of blastvox is decorated here, so importing this module
first points numba's on-disk cache at a directory keyed on the source
(:data:`KERNEL_CACHE`, see :mod:`blastvox._kernel_cache`): editing any numba
module, or a module one imports, recompiles everything once, and nothing is
ever stale. Modules that do not use numba never pay for computing the key.

A *kernel* is called from Python (:func:`kernel`, ``@nb.njit(cache=True)``). A *helper* is
called only from other compiled functions (:func:`helper`): numba then builds no
CPython wrapper for it, the code that unboxes each argument from a Python
object. That wrapper is never used for a helper, yet costs about 60 ms plus
15 ms per array argument to compile, on every first run: without it the
kernels of a first run compile about 7 % faster. Nor does a helper get machine code
or a cache file of its own (:func:`_link_only_helpers`): its code reaches the
machine only inside the kernels that call it, and their cache files hold it.

numba itself would crash if such a function were called from Python, so a
helper raises a TypeError instead; its ``py_func`` is the plain Python function.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numba as nb
from numba.core import types
from numba.core.registry import CPUDispatcher

from blastvox import _kernel_cache

#: numba's compiled kernels of this source tree; set before any blastvox function
#: is decorated (numba picks a function's cache directory when it is decorated)
KERNEL_CACHE = _kernel_cache.configure(Path(__file__).resolve().parent)


def _quick_flag_compare() -> None:
    """Make numba's comparison of compiler flags (``TargetConfig``) cheap, with the same
    results. Typing any overloaded call (``np.empty``, ``min``, ...) looks its
    implementation up in a dict keyed on the compile's flags, whose hash is the same
    for every flags object (the sorted option names), so each lookup compares flags
    with ``==``, which built two dicts of every option's value through properties:
    about 100,000 comparisons to compile the contact solver, 5-8 % of its compile.
    Here the hash is the same number, computed once per class, and ``==`` compares
    only the options either side set (the others are both the default)."""
    from numba.core.targetconfig import TargetConfig
    if getattr(TargetConfig, "_blastvox_quick", False) or not hasattr(TargetConfig, "values"):
        return
    full_eq, hashes = TargetConfig.__eq__, {}

    def __hash__(self):
        cls = type(self)
        if cls not in hashes:
            hashes[cls] = hash(tuple(sorted(self.values())))
        return hashes[cls]

    def __eq__(self, other):
        if type(self) is not type(other):
            return full_eq(self, other)
        mine, theirs, options = self._values, other._values, self.options
        for name in mine.keys() | theirs.keys():
            default = options[name].default
            a, b = mine.get(name, default), theirs.get(name, default)
            if a is not b and not a == b:  # as dict equality compares values
                return False
        return True

    TargetConfig.__hash__, TargetConfig.__eq__ = __hash__, __eq__
    TargetConfig._blastvox_quick = True


_quick_flag_compare()


class KernelDispatcher(CPUDispatcher):
    """numba's dispatcher, compiling one version per argument *type* for calls from
    compiled code: a constant argument (``pick_four(points, 0, out)``) is typed as an
    ``int64``, not as the literal ``0``, which numba would otherwise compile a
    separate copy of the whole function (and of everything it inlines) for. A first
    run compiled 32 such copies, 8.5 s of its compile time."""

    def get_call_template(self, args, kws):
        args = tuple(types.unliteral(a) for a in args)
        kws = {k: types.unliteral(v) for k, v in kws.items()}
        return super().get_call_template(args, kws)


class HelperDispatcher(KernelDispatcher):
    """A numba dispatcher without a Python entry point (see the module docstring)."""

    def __call__(self, *args, **kwargs):
        raise TypeError(f"{self.py_func.__module__}.{self.py_func.__qualname__} is compiled "
                        "for other numba functions only; call its .py_func from Python")


def kernel(func: Callable) -> Callable:
    """``@nb.njit(cache=True)``: a numba function called from Python (and compiled code),
    compiled once per argument type (:class:`KernelDispatcher`), without the C-ABI
    (``cfunc``) wrapper numba builds by default for first-class function use, which
    blastvox never makes: about 4 % of a first run's compile CPU (the house, one
    process: 37.7 s of user CPU against 36.0 s without)."""
    if nb.config.DISABLE_JIT:
        return func
    dispatcher = KernelDispatcher(py_func=func, locals={}, targetoptions={
        "nopython": True, "boundscheck": None, "no_cfunc_wrapper": True})
    dispatcher.enable_caching()
    return dispatcher


def parallel_kernel(func: Callable) -> Callable:
    """A :func:`kernel` whose ``numba.prange`` loops run on every core (numba's threading
    layer; ``NUMBA_NUM_THREADS`` caps it). Only for loops whose iterations write their
    own outputs and reduce nothing: the bytes are then the same for any thread count."""
    if nb.config.DISABLE_JIT:
        return func
    dispatcher = KernelDispatcher(py_func=func, locals={}, targetoptions={
        "nopython": True, "boundscheck": None, "no_cfunc_wrapper": True, "parallel": True})
    dispatcher.enable_caching()
    return dispatcher


def helper(func: Callable) -> Callable:
    """``@nb.njit`` for a function called only from compiled code: not cached on disk, and
    compiled to LLVM IR only (see :func:`_link_only_helpers`)."""
    if nb.config.DISABLE_JIT:
        return func
    return HelperDispatcher(py_func=func, locals={}, targetoptions={
        "nopython": True, "boundscheck": None, "no_cpython_wrapper": True,
        "no_cfunc_wrapper": True})


#: the name numba gives the library of a parallel loop's body (numba.parfors.parfor_lowering)
_LOOP_BODY = "__numba_parfor_gufunc_"


def _link_only_helpers() -> None:
    """No machine code for a helper: numba links a callee's LLVM IR into each caller's
    module and compiles the caller whole, so the helper's own machine code (and its
    cache file, which held it) was never run, yet cost 8 % of the contact solver's
    first compile. A kernel's cache file holds all of its helpers' code, so a warm run
    never loads a helper. While the innermost compile is a helper's, numba's JIT
    library skips its codegen step (``_finalize_specific``): the helper's library is
    still optimised and linked into its callers; its (never called) entry point is null.
    The same for the body of a parallel kernel's ``prange`` loop, which numba compiles as
    a function of its own (``__numba_parfor_gufunc_*``) only to link it into the kernel."""
    from numba.core import codegen, event

    if getattr(codegen.JITCodeLibrary, "_blastvox_link_only", False):
        return
    compiling: list[bool] = []

    class _Track(event.Listener):
        def on_start(self, ev):
            compiling.append(isinstance(ev.data.get("dispatcher"), HelperDispatcher))

        def on_end(self, ev):
            compiling.pop()

    machine_code = codegen.JITCodeLibrary._finalize_specific

    def _finalize_specific(self):
        if not (compiling and compiling[-1]) and not self.name.startswith(_LOOP_BODY):
            machine_code(self)

    event.register("numba:compile", _Track())
    codegen.JITCodeLibrary._finalize_specific = _finalize_specific
    codegen.JITCodeLibrary._blastvox_link_only = True


_link_only_helpers()
