"""Run the Khronos glTF Validator (npm ``gltf-validator``) on an exported file.

The validator is a node package pinned in ``tools/gltf-validator`` (package.json
and package-lock.json); install it once with ``npm ci --prefix tools/gltf-validator``.
:func:`validate_gltf` runs ``node tools/gltf-validator/validate.mjs FILE`` and
returns the validator's JSON report (``report["issues"]["numErrors"]``,
``["numWarnings"]``, ``["messages"]``...).
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

from blastvox.errors import BlastvoxError

TOOL_DIR = Path(__file__).resolve().parents[2] / "tools" / "gltf-validator"
SCRIPT = TOOL_DIR / "validate.mjs"
INSTALL_HINT = "npm ci --prefix tools/gltf-validator"


class ValidatorUnavailable(BlastvoxError):
    """node, the validator script or its npm install is missing."""


def validator_available() -> str | None:
    """None if the validator can run, else the reason it cannot."""
    if shutil.which("node") is None:
        return "node is not installed (the Khronos glTF Validator runs on node.js)"
    if not SCRIPT.is_file():
        return f"{SCRIPT} is missing (the validator lives in a source checkout of blastvox)"
    if not (TOOL_DIR / "node_modules" / "gltf-validator" / "package.json").is_file():
        return (f"the gltf-validator npm package is not installed in {TOOL_DIR}; "
                f"run `{INSTALL_HINT}` from the repository root")
    return None


def validate_gltf(path: str | Path, timeout: float = 600.0) -> dict[str, Any]:
    """The Khronos validator's report for the .glb/.gltf at ``path`` (a JSON dict).

    Raises :class:`ValidatorUnavailable` if node or the npm install is missing,
    :class:`BlastvoxError` if the validator could not run on the file.
    """
    reason = validator_available()
    if reason is not None:
        raise ValidatorUnavailable(reason)
    node = shutil.which("node")
    assert node is not None
    proc = subprocess.run([node, str(SCRIPT), str(Path(path).resolve())], capture_output=True,
                          text=True, timeout=timeout, check=False)
    if proc.returncode != 0:
        raise BlastvoxError(f"glTF validator failed on {path} (exit {proc.returncode}): "
                            f"{proc.stderr.strip() or proc.stdout.strip()}")
    try:
        return json.loads(proc.stdout)
    except json.JSONDecodeError as exc:
        raise BlastvoxError(f"glTF validator printed no JSON report for {path}: {exc}") from None
