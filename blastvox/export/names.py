"""Names the exporters make from user text: file-name and identifier safe, and unique."""

from __future__ import annotations

import re


def identifier(text: str, fallback: str) -> str:
    """``text`` with every character outside [A-Za-z0-9_] made "_", "_" before a leading
    digit; ``fallback`` for empty text."""
    base = re.sub(r"[^A-Za-z0-9_]", "_", text) or fallback
    return f"_{base}" if base[0].isdigit() else base


def unique(base: str, taken: set[str]) -> str:
    """``base``, or ``base_1``, ``base_2``... the first not in ``taken``; added to it."""
    name, n = base, 1
    while name in taken:
        name, n = f"{base}_{n}", n + 1
    taken.add(name)
    return name
