"""Shared checks for the bad-input suites: how blastvox must fail.

``run_blastvox`` runs the real entry point (:func:`blastvox.cli.entry.run`)
in-process, which is what the console script calls, so hundreds of cases cost
no interpreter start-ups; ``run_subprocess`` is for signals and crashes.
``assert_clean_failure`` states the contract every refused input must meet
(issue 18): the exit code, exactly one line on stderr that names the file and
the problem, no traceback, the inputs unchanged and no output or temporary
file left behind, within a time bound.
"""

from __future__ import annotations

import contextlib
import faulthandler
import hashlib
import io
import os
import subprocess
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path


@dataclass
class Outcome:
    """What a command did: exit ``code``, its ``stdout`` and ``stderr`` text, ``seconds``."""

    code: int
    stdout: str
    stderr: str
    seconds: float


def run_blastvox(*args: str | os.PathLike, cwd: Path | None = None) -> Outcome:
    """Run ``blastvox ARGS`` in this process (in ``cwd``) and capture what it printed."""
    from blastvox.cli.entry import run

    out, err = io.StringIO(), io.StringIO()
    old = Path.cwd()
    started = time.perf_counter()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = run([str(a) for a in args])
    finally:
        os.chdir(old)
    return Outcome(code, out.getvalue(), err.getvalue(), time.perf_counter() - started)


def run_subprocess(*args: str | os.PathLike, cwd: Path, timeout: float = 120.0) -> Outcome:
    """Run ``python -m blastvox ARGS`` in a child process."""
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "blastvox", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout)
    return Outcome(done.returncode, done.stdout, done.stderr, time.perf_counter() - started)


def snapshot(paths: Iterable[Path]) -> dict[Path, str]:
    """SHA-256 of each existing regular file in ``paths`` (to prove inputs unchanged)."""
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in paths if p.is_file()}


def listing(directory: Path) -> set[str]:
    """Every file under ``directory``, relative, hidden ones (temporary files) included."""
    return {str(p.relative_to(directory)) for p in directory.rglob("*")}


def assert_clean_failure(outcome: Outcome, names: Sequence[str], code: int = 1,
                         words: Sequence[str] = (), seconds: float = 60.0) -> str:
    """The refusal contract; returns the error line.

    ``names``: strings the line must contain (the file, the key or flag);
    ``words``: further words of the problem it must say (case-insensitive).
    """
    assert outcome.code == code, (outcome.code, outcome.stderr[-2000:])
    lines = outcome.stderr.strip().splitlines()
    assert len(lines) == 1, outcome.stderr[-2000:]
    line = lines[0]
    assert "Traceback" not in outcome.stderr
    if code == 1:
        assert line.startswith("blastvox: error: "), line
    for name in names:
        assert str(name) in line, (name, line)
    for word in words:
        assert word.lower() in line.lower(), (word, line)
    assert outcome.seconds < seconds, (outcome.seconds, line)
    return line


@contextlib.contextmanager
def unchanged(directory: Path, inputs: Iterable[Path] = (), allow: Iterable[str] = ()):
    """Assert that the block leaves ``inputs`` byte-identical and adds no file to
    ``directory`` (temporary ``.partial`` files included) except those in ``allow``."""
    inputs = list(inputs)
    before_files, before_hash = listing(directory), snapshot(inputs)
    yield
    added = listing(directory) - before_files - set(allow)
    assert not added, f"left behind: {sorted(added)}"
    assert snapshot(inputs) == before_hash, "an input was modified"


@contextlib.contextmanager
def deadline(seconds: float = 10.0):
    """End the test process (with every thread's stack on stderr) if the block runs past
    ``seconds``: a regression that blocks in C (USD opening a FIFO) then costs seconds,
    not a hung suite (under xdist the worker is replaced and the test reported)."""
    faulthandler.dump_traceback_later(seconds, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
