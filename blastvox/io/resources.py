"""The files a mesh refers to: what a shot's voxelize stage reads besides the mesh.

Used by ``blastvox run`` (a stage is stale when any of them is newer than its
output) and by wedge shot keys (:mod:`blastvox.wedge.digest`). Standard library
(and the reader policy), so an up-to-date shot costs a few reads and stats.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from blastvox.errors import InputError
from blastvox.io.references import ReferencePolicy, uri_paths

_POLICY = ReferencePolicy()

#: An MTL texture statement: ``map_Kd [-options value] file``.
_MTL_MAP = r"^\s*(?:map_\w+|bump|disp|decal|norm)\s+(?:-\S+\s+\S+\s+)*(.+?)\s*$"


def mesh_resources(mesh: Path, policy: ReferencePolicy | None = None) -> list[Path]:
    """``mesh`` and the files it refers to that change what voxelize or export reads:
    an OBJ's ``mtllib`` files and their ``map_*`` textures, a .gltf's buffer and image
    URIs (not ``data:`` URIs). References the reader policy refuses (outside the
    mesh's folder, a FIFO, a device, a URL: :mod:`blastvox.io.references`) are neither
    read nor listed, and unreadable ones are left to the mesh reader, which says why.
    ``policy``: the reader policy (default: inside the mesh's folder)."""
    policy = policy or _POLICY
    found = [mesh]
    suffix = mesh.suffix.lower()
    if suffix == ".obj":
        for mtl in _referenced(mesh, r"^\s*mtllib\s+(.+?)\s*$", policy):
            found.append(mtl)
            found += _referenced(mtl, _MTL_MAP, policy)
    elif suffix == ".gltf":
        found += _gltf_uris(mesh, policy)
    return found


def _referenced(path: Path, pattern: str, policy: ReferencePolicy) -> list[Path]:
    """The files that ``path`` names (by ``pattern``) and the policy would read."""
    try:
        text = policy.read(path, path.name).decode("utf-8", errors="replace")
    except (OSError, ValueError, InputError):
        return []
    return [ref for name in re.findall(pattern, text, flags=re.M)
            if (ref := _allowed(path, name, policy)) is not None]


def _allowed(referrer: Path, name: str, policy: ReferencePolicy) -> Path | None:
    """referrer's reference ``name`` if the reader policy reads it, else None."""
    try:
        policy.resolve(referrer, name)
    except (OSError, InputError):
        return None
    return referrer.parent / name


def _gltf_uris(path: Path, policy: ReferencePolicy) -> list[Path]:
    try:
        doc = json.loads(policy.read(path, path.name).decode("utf-8"))
    except (OSError, ValueError, RecursionError, InputError):  # nested past the stack
        return []
    if not isinstance(doc, dict):
        return []
    uris = []
    for kind in ("buffers", "images"):
        for item in doc.get(kind) or []:
            uri = item.get("uri") if isinstance(item, dict) else None
            if not isinstance(uri, str) or uri.startswith("data:"):
                continue
            for name in uri_paths(uri):  # the file the loader reads (missing: None)
                if (ref := _allowed(path, name, policy)) is not None:
                    uris.append(ref)
                    break
    return uris
