"""Read OpenVDB files with the real library (bpy's ``openvdb`` module, OpenVDB 12) and
print what they hold, as JSON.

Run by the Blender venv's python (``.venv-blender``: ``make blender-venv``)::

    .venv-blender/bin/python tools/blender/vdb_check.py FILE.vdb [FILE.vdb ...]

Prints one JSON object on stdout: per file, per grid (in file order) its ``name``,
``class``, ``type``, ``voxel_size`` (3), ``origin`` (the world position of index
(0, 0, 0)), ``active`` (active voxel count), ``bbox`` (min, max index), ``metadata``,
and ``ijk`` / ``values``: every active voxel's index and value, sorted by index.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import bpy  # noqa: F401  (puts Blender's libraries in place)

for parent in Path(bpy.__file__).resolve().parents:  # bpy/5.0/python/lib/python3.x/...
    for site in parent.glob("*/python/lib/python3*/site-packages"):
        sys.path.insert(0, str(site))
import openvdb  # noqa: E402


def _grid(grid) -> dict:
    ijk, values = [], []
    for item in grid.citerOnValues():
        if item.count != 1:  # a tile: blastvox writes none
            raise SystemExit(f"{grid.name}: an active tile of {item.count} voxels")
        ijk.append(list(item.min))
        values.append(item.value)
    order = sorted(range(len(ijk)), key=lambda n: ijk[n])
    meta = {k: (list(v) if isinstance(v, tuple) else v) for k, v in dict(grid.metadata).items()}
    return {"name": grid.name, "class": str(grid.gridClass).rsplit(".", 1)[-1],
            "type": grid.valueTypeName, "voxel_size": list(grid.transform.voxelSize()),
            "origin": list(grid.transform.indexToWorld((0, 0, 0))),
            "active": int(grid.activeVoxelCount()),
            "bbox": [list(c) for c in grid.evalActiveVoxelBoundingBox()],
            "metadata": meta, "ijk": [ijk[n] for n in order],
            "values": [values[n] for n in order]}


def main(paths: list[str]) -> None:
    out = {}
    for path in paths:
        grids, _ = openvdb.readAll(path)
        out[path] = [_grid(g) for g in grids]
    sys.stdout.write(json.dumps(out) + "\n")
    sys.stdout.flush()


if __name__ == "__main__":
    main(sys.argv[1:])
