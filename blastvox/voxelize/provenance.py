"""What a VoxelModel records of the settings that made it (its ``meta["settings"]``).

One record for every way a scene is voxelized (``blastvox voxelize``, ``blastvox run``,
a wedge's shots), so the same scene gives the same model file whichever command made
it. Budgets (``--max-voxels``) are not recorded: they only refuse a model, they never
change one.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any


def recorded_settings(requests: Sequence[Any], settings: Any,
                      scene: Path | None) -> dict[str, Any]:
    """The settings that made the model, JSON-safe, without absolute paths: the scene's
    file name (None without a scene), up axis, ground, seed and each object's request
    (:class:`~blastvox.voxelize.pipeline.ObjectRequest`) by its mesh's file name."""
    from blastvox.bounds import printable

    return {
        "scene": printable(Path(scene).name) if scene else None,
        "up_axis": settings.up_axis, "ground": settings.ground, "seed": settings.seed,
        "objects": [{
            "mesh": printable(Path(r.mesh).name), "name": r.name,
            "voxel_size": list(r.voxel_size) if r.voxel_size else None,
            "resolution": r.resolution, "shape": r.shape, "jitter": r.jitter,
            "chunk_size": r.chunk_size, "part_bond": r.part_bond, "anchored": r.anchored,
            "sheet_thickness": r.sheet_thickness,
            "material": r.material, "material_map": dict(r.material_map),
            "transform": r.transform.tolist() if r.transform is not None else None,
            "rules": [{"kind": x.kind, "a": list(x.a), "b": x.b if isinstance(x.b, float)
                       else list(x.b), "material": x.material,
                       "strength_scale": x.strength_scale, "chunk_size": x.chunk_size}
                      for x in r.rules],
        } for r in requests],
    }
