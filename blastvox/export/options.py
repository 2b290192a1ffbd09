"""``ExportOptions``: what an export may ask for besides the cache and the path.

Its own module so that the writers (usd, gltf) and the entry point
(:mod:`blastvox.export.api`) share it without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ExportOptions:
    """up_axis: "Y" (default, glTF's and Blender-USD's convention) or "Z".
    layout: "xforms" (one Xform + Mesh per piece; a glTF node per piece),
    "instancer" (USD PointInstancer for shots with many thousands of pieces; USD
    only) or "skinned" (glTF only: one mesh of all pieces, a joint per piece).
    shock: also write each charge's shock front as a growing sphere, a viewport aid
    (USD: a guide-purpose prim, which renderers and Blender's importer skip; glTF: a
    translucent sphere, which a renderer does draw: it grows past the camera).
    damage_textures: draw each material's damage pattern on its fracture faces
    (:mod:`blastvox.export.damage_textures`; USD: PNGs in ``<stem>_textures/``);
    False keeps the flat ``damage_color`` and writes no texture files for them.
    fracture_faces: "rough" (default) draws fracture faces as rubble surfaces
    (:mod:`blastvox.export.rubble`), "voxel" as the voxels' cell faces.
    particles: how USD writes dust, fire, smoke and the fireball: "volumes" (OpenVDB
    density and temperature grids per frame in ``<stem>_volumes/``, a UsdVolVolume per
    system), "spheres" (a PointInstancer of spheres per system) or "auto" (volumes
    for .usd/.usda/.usdc, spheres for .usdz, which cannot carry .vdb files); glTF
    writes a sphere node per particle with "spheres" only
    (:mod:`blastvox.export.gltf_particles`).
    volume_voxel_m: the volumes' cell size (m)."""

    up_axis: str = "Y"
    layout: str = "xforms"
    shock: bool = False
    damage_textures: bool = True
    fracture_faces: str = "rough"
    particles: str = "auto"
    volume_voxel_m: float = 0.1
