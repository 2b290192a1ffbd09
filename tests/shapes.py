"""Test meshes shared by the suites."""

from __future__ import annotations

from pathlib import Path

import trimesh


def standing_box(path: Path, extents: tuple[float, float, float]) -> Path:
    """Write a box of ``extents`` (m), centred on x = y = 0 and standing on z = 0, to
    ``path`` (any format trimesh writes); returns ``path``."""
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation((0.0, 0.0, extents[2] / 2.0))
    mesh.export(path)
    return path
