"""The damage textures an export writes: one PNG per material whose fracture faces show.

Both writers take them from here: USD as ``<stem>_textures/<name>.png`` beside the
file, bound through a UsdUVTexture in ``Materials/<material>_damage``; glTF
embedded, as the ``baseColorTexture`` of material ``<material>_damage``. The
image is :func:`blastvox.damage_look.damage_png` of the material's pattern
(``material_damage_pattern`` in the model, else by name) and damage colour; it
is read at the box UVs of :mod:`blastvox.export.uv` (1 tile per metre).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from blastvox.cache import SimCache
from blastvox.damage_look import damage_png, pattern_for
from blastvox.export.names import unique


@dataclass(frozen=True)
class DamageTexture:
    """material: model material index; name: file and identifier safe, unique among the
    export's textures (``damage_<material>``); pattern; png: the encoded image."""

    material: int
    name: str
    pattern: str
    png: bytes


def damage_textures(cache: SimCache, materials: list[int],
                    taken: list[str] = ()) -> list[DamageTexture]:
    """The damage texture of each of ``materials`` (model material indices, in that
    order); names avoid ``taken`` (the source look's texture names)."""
    names = list(cache.model.meta.get("materials", []))
    a = cache.model.arrays
    chosen = a.get("material_damage_pattern")
    colors = np.asarray(a["material_damage_color"], dtype=np.float64)
    used = set(taken)
    out = []
    for m in materials:
        material = names[m] if m < len(names) else f"material_{m}"
        pattern = pattern_for(material, str(chosen[m]) if chosen is not None else "")
        name = unique("damage_" + (re.sub(r"[^A-Za-z0-9_]", "_", material) or str(m)), used)
        color = tuple(float(c) for c in np.clip(colors[m], 0.0, 1.0))
        out.append(DamageTexture(m, name, pattern, damage_png(pattern, color)))
    return out
