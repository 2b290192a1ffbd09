"""The ``blastvox`` console entry point: signals, exit codes and one-line errors.

This module imports nothing heavy at the top, so that the signal handlers are in
place before the command-line framework and the stage modules load: Ctrl-C at
any moment (imports included) exits 130 and SIGTERM exits 143, both with one
line on stderr and no partial output (outputs are written through
:func:`blastvox.io.atomic.atomic_path`, which removes its temporary file when
the interrupt unwinds through it).

Exit codes: 0 success; 1 bad input or a failed write (one line naming the file
and the problem); 2 usage error (the CLI framework's message); 130 interrupted
(SIGINT); 143 terminated (SIGTERM); 129 hang-up (SIGHUP).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import NoReturn

from blastvox.cli.interrupt import (  # noqa: F401 - the entry point's names
    Interrupted,
    _echo,
    check_interrupt,
    interrupt_handlers,
)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def main(argv: Sequence[str] | None = None) -> NoReturn:
    """Run the CLI with ``argv`` (default ``sys.argv[1:]``) and exit with its code.

    User errors (:class:`~blastvox.errors.BlastvoxError`) and out-of-memory become
    one ``blastvox: error: ...`` line on stderr and exit 1.
    """
    sys.exit(run(argv))


def run(argv: Sequence[str] | None = None) -> int:
    """Like :func:`main` but returns the exit code instead of exiting (in-process use)."""
    interrupt = None
    try:
        with interrupt_handlers() as interrupt:
            return _run_app(argv)
    except Interrupted as exc:
        _echo(f"blastvox: {exc.reason}; no partial output left")
        return exc.exit_code
    except KeyboardInterrupt:  # raised by Python itself before a handler was set
        _echo("blastvox: interrupted; no partial output left")
        return 130
    except Exception:
        if interrupt is not None and interrupt.signum:  # a library failed as it was stopped
            stopped = Interrupted(interrupt.signum)
            _echo(f"blastvox: {stopped.reason}; no partial output left")
            return stopped.exit_code
        raise


def _run_app(argv: Sequence[str] | None) -> int:
    from blastvox.errors import BlastvoxError

    try:
        from blastvox.cli.app import app

        app(args=list(argv) if argv is not None else None, prog_name="blastvox")
    except SystemExit as exc:
        return _exit_code(exc.code)
    except BlastvoxError as exc:
        _echo(f"blastvox: error: {_one_line(exc)}")
        return exc.exit_code
    except OSError as exc:  # a file the OS refused (permissions, a device, a full disk)
        where = f"{exc.filename}: " if exc.filename else ""
        _echo(f"blastvox: error: {where}{_one_line(exc.strerror or exc)}")
        return 1
    except MemoryError:
        _echo("blastvox: error: out of memory; lower the resolution, the duration or the "
              "frame rate (see docs/user-guide.md, Limits)")
        return 1
    return 0


def _exit_code(code: object) -> int:
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    _echo(str(code))
    return 1
