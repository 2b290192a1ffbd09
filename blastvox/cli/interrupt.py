"""The CLI's interrupt state: SIGINT, SIGTERM and SIGHUP turned into
:class:`Interrupted`, raised where it is safe (:func:`interrupt_handlers`), and
:func:`check_interrupt` for long loops whose library code may swallow one.

Its own module so that the entry point (:mod:`blastvox.cli.entry`) and the commands
(:mod:`blastvox.cli.simulate_cmd`) share it without importing each other.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager


class Interrupted(BaseException):  # noqa: N818 - like KeyboardInterrupt, not an error
    """Raised in the main thread by SIGINT, SIGTERM or SIGHUP; ``exit_code`` is 128 + signal.

    A BaseException and not a KeyboardInterrupt, so that neither library code that
    catches ``Exception`` nor the CLI framework (which turns KeyboardInterrupt into a
    silent exit) can swallow it, while ``try/finally`` and ``atomic_path`` still clean up.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum
        self.exit_code = 128 + signum
        self.reason = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated"}.get(
            signum, f"stopped by {signal.Signals(signum).name}")


_HANDLED = tuple(s for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None))
                 if s is not None)


#: Seconds the watchdog waits between looks for a swallowed interrupt.
WATCH_S = 0.05
#: Re-deliveries after which an interrupt that never surfaces exits the process hard.
MAX_REDELIVERIES = 100


class _Interrupt:
    """Delivery of one interrupt to the main thread, whatever it is doing.

    An exception raised in a signal handler surfaces at the main thread's next
    bytecode, unless that bytecode runs inside a ctypes callback: there Python
    reports it to ``sys.unraisablehook`` ("Exception ignored") and carries on.
    numba compiles through such callbacks (llvmlite's object cache), so a Ctrl-C
    during the first run's compilation used to be swallowed and the command
    finished with exit 0, or left numba half-way through a compilation ("no
    compiled object yet"). So the handler does not raise while llvmlite or an
    import is on the stack (C code calls Python back there; a C extension
    importing a module printed the exception as a traceback): it marks the
    interrupt pending, and a watchdog thread re-delivers the signal
    (``signal.pthread_kill``) every :data:`WATCH_S` until the main thread is
    out of them and the exception can surface. ``sys.unraisablehook``
    catches any other callback that swallows it, quietly, for the same retry.
    """

    def __init__(self) -> None:
        self.signum = 0  # the first signal received, 0 for none yet
        self.redelivering = False
        self.swallowed = False
        self.done = False
        self._watchdog = None  # threading.Thread, started on the first deferral

    def handle(self, signum: int, frame: object) -> None:
        import os

        if self.signum and not self.redelivering:  # a second Ctrl-C: stop now
            os._exit(128 + self.signum)
        self.redelivering = False
        self.signum = self.signum or signum
        if _in_callback_prone_code(frame):
            self.swallowed = True  # not yet: the watchdog delivers it again shortly
            self._start_watchdog()
            return
        raise Interrupted(self.signum)

    def unraisable(self, hook: object, unraisable: object) -> None:
        """``sys.unraisablehook``: note our swallowed interrupt, pass anything else on."""
        if isinstance(getattr(unraisable, "exc_value", None), Interrupted):
            self.swallowed = True
            self._start_watchdog()
        else:
            hook(unraisable)

    def _start_watchdog(self) -> None:
        import threading

        # this interrupt's own: an earlier one's may still be winding down (in-process use)
        if self._watchdog is None or not self._watchdog.is_alive():
            self._watchdog = threading.Thread(target=self._watch, name="blastvox-interrupt",
                                              daemon=True)
            self._watchdog.start()

    def _watch(self) -> None:
        import os
        import threading
        import time

        main = threading.main_thread().ident

        for _ in range(MAX_REDELIVERIES):
            time.sleep(WATCH_S)
            if self.done:
                return
            if self.swallowed:
                self.swallowed, self.redelivering = False, True
                # a real signal to the main thread, which also wakes a blocking call
                signal.pthread_kill(main, self.signum)
        _echo(f"blastvox: {Interrupted(self.signum).reason}; exiting")
        os._exit(128 + self.signum)


#: The interrupt state of the CLI run in progress (innermost last), for check_interrupt.
_ACTIVE: list[_Interrupt] = []


def check_interrupt() -> None:
    """Raise :class:`Interrupted` if a signal arrived and never surfaced: C code that
    calls Python back and then clears any error it raised swallows it without a trace
    (a Ctrl-C 1 s into a cold first run once finished with exit 0 in CI; the frame that
    swallowed it was not found). Long-running commands
    call this between units of work (a simulated frame), so such an interrupt stops
    the command there instead of letting it run to the end."""
    if _ACTIVE and _ACTIVE[-1].signum and not _ACTIVE[-1].done:
        raise Interrupted(_ACTIVE[-1].signum)


def _in_callback_prone_code(frame: object, depth: int = 64) -> bool:
    """Is a frame on the stack from ``frame`` one that C code called, which may print or
    drop an exception raised there: llvmlite's (numba's compiler calls back into it)
    or the import machinery's (a C extension importing a module printed the
    Interrupted of a Ctrl-C 0.3 s into a run as a traceback, then carried on)?"""
    while frame is not None and depth > 0:
        name = frame.f_code.co_filename  # type: ignore[attr-defined]
        if "llvmlite" in name or name.startswith("<frozen importlib"):
            return True
        frame, depth = frame.f_back, depth - 1  # type: ignore[attr-defined]
    return False


@contextmanager
def interrupt_handlers() -> Iterator[_Interrupt]:
    """Turn SIGINT/SIGTERM/SIGHUP into :class:`Interrupted` for the duration.

    The first signal raises (see :class:`_Interrupt` for why it may be
    re-delivered); a second one while the first unwinds exits at once
    (``os._exit``), as a user pressing Ctrl-C twice expects. Signals the parent
    set to be ignored (``nohup``, background jobs) stay ignored. The previous
    handlers are restored on exit, so the CLI can run in-process (tests).
    """
    import functools

    interrupt = _Interrupt()
    hook = sys.unraisablehook
    sys.unraisablehook = functools.partial(interrupt.unraisable, hook)
    previous = {}
    for signum in _HANDLED:
        old = signal.getsignal(signum)
        if old is signal.SIG_IGN:
            continue
        previous[signum] = old
        signal.signal(signum, interrupt.handle)
    _ACTIVE.append(interrupt)
    try:
        yield interrupt
    finally:
        interrupt.done = True
        _ACTIVE.remove(interrupt)
        sys.unraisablehook = hook
        for signum, old in previous.items():
            signal.signal(signum, old)


def _echo(line: str) -> None:
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # stderr closed or a broken pipe: the exit code still says it
        pass
