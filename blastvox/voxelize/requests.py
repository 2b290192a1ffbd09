"""Building voxelize requests from a scene file or from command-line flags."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from blastvox.voxelize.pipeline import ObjectRequest
from blastvox.voxelize.regions import RegionRule


def transform_matrix(translate, rotate_deg, scale) -> np.ndarray:
    """4x4 matrix: scale, then rotate (XYZ Euler angles in degrees), then translate (m)."""
    from trimesh.transformations import euler_matrix

    m = euler_matrix(*np.radians(np.asarray(rotate_deg, dtype=np.float64)), axes="sxyz")
    m[:3, :3] = m[:3, :3] @ np.diag(np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,)))
    m[:3, 3] = translate
    return m


def rule_from_scene(rule: Any) -> RegionRule:
    """Convert a scene ``Rule`` into a :class:`RegionRule`."""
    scale = 1.0 if rule.strength_scale is None else float(rule.strength_scale)
    chunk = None if rule.chunk_size is None else float(rule.chunk_size)
    if rule.box is not None:
        return RegionRule("box", tuple(rule.box.min), tuple(rule.box.max), rule.material, scale,
                          chunk)
    if rule.sphere is not None:
        return RegionRule("sphere", tuple(rule.sphere.center), float(rule.sphere.radius),
                          rule.material, scale, chunk)
    return RegionRule("halfspace", tuple(rule.halfspace.point), tuple(rule.halfspace.normal),
                      rule.material, scale, chunk)


def requests_from_scene(scene: Any) -> list[ObjectRequest]:
    """One :class:`ObjectRequest` per ``[[objects]]`` entry of a validated scene."""
    out = []
    source = getattr(scene, "source", None)
    for i, obj in enumerate(scene.objects):
        t = obj.transform
        matrix = transform_matrix(t.translate, t.rotate_deg, t.scale)
        out.append(ObjectRequest(
            mesh=Path(obj.mesh), name=obj.name,
            source=getattr(obj, "mesh_as_written", None),
            origin=f"{source}: objects[{i}]" if source else None,
            voxel_size=tuple(obj.voxel_size) if obj.voxel_size is not None else None,
            resolution=obj.resolution, shape=obj.shape, jitter=obj.jitter,
            chunk_size=obj.chunk_size, part_bond=obj.part_bond, anchored=obj.anchored,
            sheet_thickness=obj.sheet_thickness,
            material=obj.material, material_map=dict(obj.material_map),
            transform=None if np.allclose(matrix, np.eye(4)) else matrix,
            rules=[rule_from_scene(r) for r in obj.rules]))
    return out


def settings_from_scene(scene: Any, max_voxels: int | None = None) -> Any:
    """:class:`VoxelizeSettings` from a validated scene (its library, frame and seed).

    Without ``max_voxels`` (``blastvox run``, which has no --max-voxels) the default
    budget applies, and a refusal says to voxelize the scene with a larger one first.
    """
    from blastvox.bounds import DEFAULT_MAX_VOXELS
    from blastvox.voxelize.budget import HINT
    from blastvox.voxelize.pipeline import VoxelizeSettings

    hint = HINT
    if max_voxels is None:
        name = getattr(scene, "source", None) or "SCENE.toml"
        hint = (f"voxelize it first with `blastvox voxelize --scene {name} --max-voxels N`, "
                f"which `blastvox run` then finds up to date, or use a larger voxel size")
    return VoxelizeSettings(up_axis=scene.up_axis,
                            ground=None if scene.ground == "none" else scene.ground,
                            seed=scene.seed, max_voxels=max_voxels or DEFAULT_MAX_VOXELS,
                            library=scene.material_library(), budget_hint=hint,
                            budget_scene=(getattr(scene, "source", None) or "SCENE.toml")
                            if max_voxels is None else None)
