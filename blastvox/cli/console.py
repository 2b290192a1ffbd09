"""Shared terminal output: a stderr console, warnings and a rich progress sink."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


def err_console() -> Any:
    """A rich Console on stderr (imported lazily)."""
    import sys

    from rich.console import Console

    # piped (a shot build's log): one message per line, never wrapped at 80 columns
    width = None if sys.stderr.isatty() else 10_000
    return Console(stderr=True, highlight=False, width=width, soft_wrap=width is not None)


@contextmanager
def cli_warnings(console: Any) -> Iterator[None]:
    """Print each :class:`~blastvox.errors.BlastvoxWarning` (a simulation limit, an
    export a client handles badly) raised inside as one ``blastvox: warning:
    <message>`` line on ``console`` (stderr), each message once; other warnings go
    to Python's usual handler."""
    import warnings

    from blastvox.errors import BlastvoxWarning

    seen: set[str] = set()
    show = warnings.showwarning

    def showwarning(message, category, filename, lineno, file=None, line=None) -> None:
        if not issubclass(category, BlastvoxWarning):
            show(message, category, filename, lineno, file, line)
        elif str(message) not in seen:
            seen.add(str(message))
            console.print(f"blastvox: warning: {message}", markup=False, highlight=False)

    with warnings.catch_warnings():
        warnings.simplefilter("always", BlastvoxWarning)
        warnings.showwarning = showwarning
        yield


class RichProgress:
    """Adapter from the pipeline's Progress protocol to a rich progress bar."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self._progress = None
        self._task = None

    def __enter__(self) -> RichProgress:
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
            )

            self._progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                      MofNCompleteColumn(), TimeElapsedColumn(),
                                      console=err_console(), transient=True)
            self._progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()

    def start(self, description: str, total: int) -> None:
        if self._progress is None:
            return
        if self._task is not None:
            self._progress.update(self._task, completed=self._progress.tasks[-1].total)
        self._task = self._progress.add_task(description, total=max(total, 1))

    def advance(self, amount: int = 1) -> None:
        if self._progress is not None and self._task is not None:
            self._progress.advance(self._task, amount)

    def stop(self) -> None:
        pass
