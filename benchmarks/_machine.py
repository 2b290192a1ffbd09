"""The machine line every benchmark prints above its tables."""

from __future__ import annotations

import os
import platform
from importlib import metadata


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
