"""What every benchmark shares: the machine line above its tables, pass/FAIL, --repeat.

Importing it imports blastvox, which pins numpy's loops and OpenBLAS's kernels for
what loads after it (blastvox/__init__.py): a benchmark that imports this module
before trimesh or scipy.linalg times the CLI's shot, byte for byte.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

import blastvox  # noqa: F401  (see the docstring)

ROOT = Path(__file__).resolve().parent.parent


def revision() -> str:
    """The git commit of the checkout, "+ local changes" if blastvox/ differs from it."""
    try:
        sha = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, check=True,
                             capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "blastvox"], cwd=ROOT,
                               check=True, capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "not a git checkout"
    return f"git {sha}" + (" + local changes in blastvox/" if dirty else "")


def machine(packages: tuple[str, ...] = ("blastvox", "numpy", "numba")) -> str:
    """Platform, CPU model and count, load average, Python and package versions."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh
                       if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    versions = ", ".join(f"{p} {_version(p)}" for p in packages)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (f"Machine: {platform.platform()}; {cpu}; {os.cpu_count()} CPUs; load average "
            f"{load}; Python {platform.python_version()}; {versions}")


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "?"


def verdict(ok: bool) -> str:
    """A target's result cell."""
    return "pass" if ok else "FAIL"


def repeat_count(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """--repeat as given, else 3 (1 with --quick); at least 1."""
    repeat = args.repeat if args.repeat is not None else (1 if args.quick else 3)
    if repeat < 1:
        parser.error("--repeat must be at least 1")
    return repeat
