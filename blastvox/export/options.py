"""``ExportOptions``: what an export may ask for besides the cache and the path.

Its own module so that the writers (usd, gltf) and the entry point
(:mod:`blastvox.export.api`) share it without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass

#: keyframe tolerances' defaults: 0.1 mm and 0.1 degree (blastvox.export.keys)
KEY_TOLERANCE_M = 1e-4
KEY_TOLERANCE_DEG = 0.1


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
    volume_voxel_m: the volumes' cell size (m).
    key_tolerance_m, key_tolerance_deg: keyframe reduction (:mod:`blastvox.export.keys`):
    a piece's transform is keyed only where interpolating the kept keys would miss it by
    more than this translation (m) or rotation (degrees); 0 and 0 key every frame where
    the value changes (the exact export).
    damage_samples: USD: time-sample each piece's per-face ``primvars:damage`` at every
    change (Blender then gives every piece a MeshSequenceCache modifier, and a frame
    change re-reads every mesh); False (default) writes its final value and, per face,
    ``primvars:blastvox:damageFrame`` (the first frame it is damaged, -1 never).
    velocity_primvars: USD: each piece Xform's time-sampled ``primvars:blastvox:velocity``
    and ``angularVelocity`` (False: left out; 18,225 pieces: 16 MB less, and a Blender
    frame change about a third faster)."""

    up_axis: str = "Y"
    layout: str = "xforms"
    shock: bool = False
    damage_textures: bool = True
    fracture_faces: str = "rough"
    particles: str = "auto"
    volume_voxel_m: float = 0.1
    key_tolerance_m: float = KEY_TOLERANCE_M
    key_tolerance_deg: float = KEY_TOLERANCE_DEG
    damage_samples: bool = False
    velocity_primvars: bool = True
