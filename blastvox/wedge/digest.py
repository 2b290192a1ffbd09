"""Content keys of wedge shots: a hash of everything that makes a shot's files.

A shot's key covers the blastvox code (every file of the package), the scene as
the shot runs it (its parsed file with the varied values set, without the output
paths a wedge chooses and without the ``[wedge]`` table; the export file names
and options stay in), the scene file's name (the model records it), and the bytes
of every input file: each mesh and what it refers to (an OBJ's MTL files and their
texture maps, a glTF's buffers and images) and the materials file. Two shots with
the same key make byte-identical files, so a finished shot is never run again
and a changed input, scene value or code version runs it afresh.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from functools import cache
from pathlib import Path
from typing import Any

import blastvox

#: Bumped when what a key covers changes.
KEY_FORMAT = 1
#: Hex digits of a shot key (64 bits: no collision in any wedge a farm can run).
KEY_DIGITS = 16


@cache
def code_digest() -> str:
    """SHA-256 (hex) of every file of the installed blastvox package, in path order."""
    root = Path(blastvox.__file__).parent
    digest = hashlib.sha256()
    for path in sorted(p for p in root.rglob("*") if p.is_file()
                       and "__pycache__" not in p.parts and p.suffix != ".pyc"):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def file_digest(path: Path, memo: dict[Path, str] | None = None) -> str:
    """SHA-256 (hex) of the bytes of ``path``; "missing" if it cannot be read (the shot
    then fails with the reader's own message)."""
    if memo is not None and path in memo:
        return memo[path]
    try:
        digest = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        text = digest.hexdigest()
    except OSError:
        text = "missing"
    if memo is not None:
        memo[path] = text
    return text


def shot_key(scene_data: Mapping[str, Any], scene_name: str, inputs: Iterable[Path],
             memo: dict[Path, str] | None = None) -> str:
    """The key (:data:`KEY_DIGITS` hex digits) of a shot that runs the parsed scene
    ``scene_data`` (outputs as :func:`keyed_scene` leaves them) from a file named
    ``scene_name`` with the input files ``inputs``."""
    record = {
        "format": KEY_FORMAT,
        "code": code_digest(),
        "scene_name": scene_name,
        "scene": scene_data,
        "inputs": [[str(p), file_digest(p, memo)] for p in inputs],
    }
    text = json.dumps(record, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:KEY_DIGITS]


def keyed_scene(data: Mapping[str, Any]) -> dict[str, Any]:
    """``data`` as its key sees it: no ``[wedge]``, no model or cache path, export
    paths reduced to their file names (their format and name make the files)."""
    out = {k: v for k, v in data.items() if k != "wedge"}
    output = dict(out.get("output") or {})
    output.pop("model", None)
    output.pop("cache", None)
    export = output.get("export")
    if isinstance(export, list):
        output["export"] = [Path(str(e)).name for e in export]
    elif export is not None:
        output["export"] = Path(str(export)).name
    out["output"] = output
    return out
