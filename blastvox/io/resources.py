"""The files a mesh refers to: what a shot's voxelize stage reads besides the mesh.

Used by ``blastvox run`` (a stage is stale when any of them is newer than its
output) and by wedge shot keys (:mod:`blastvox.wedge.digest`). Standard library
only, so an up-to-date shot costs a few reads and stats.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

#: An MTL texture statement: ``map_Kd [-options value] file``.
_MTL_MAP = r"^\s*(?:map_\w+|bump|disp|decal|norm)\s+(?:-\S+\s+\S+\s+)*(.+?)\s*$"


def mesh_resources(mesh: Path) -> list[Path]:
    """``mesh`` and the files it refers to that change what voxelize or export reads:
    an OBJ's ``mtllib`` files and their ``map_*`` textures, a .gltf's buffer and image
    URIs (not ``data:`` URIs). Unreadable references are left to the mesh reader."""
    found = [mesh]
    suffix = mesh.suffix.lower()
    if suffix == ".obj":
        for mtl in _referenced(mesh, r"^\s*mtllib\s+(.+?)\s*$"):
            found.append(mtl)
            found += _referenced(mtl, _MTL_MAP)
    elif suffix == ".gltf":
        found += _gltf_uris(mesh)
    return found


def _referenced(path: Path, pattern: str) -> list[Path]:
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return []
    names = re.findall(pattern, text, flags=re.M)
    return [path.parent / name for name in names]


def _gltf_uris(path: Path) -> list[Path]:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    if not isinstance(doc, dict):
        return []
    uris = []
    for kind in ("buffers", "images"):
        for item in doc.get(kind) or []:
            uri = item.get("uri") if isinstance(item, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                uris.append(path.parent / uri)
    return uris
