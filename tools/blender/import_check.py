"""Import a blastvox export into Blender and report what Blender sees, as JSON.

Run by the Blender venv's python (``.venv-blender``: ``make blender-venv``, see
tools/blender/requirements.txt), not by the project's::

    .venv-blender/bin/python tools/blender/import_check.py FILE FRAME [FRAME ...]
        [--set OPTION=JSON ...]

FILE is a .usd/.usda/.usdc (``bpy.ops.wm.usd_import``) or a .gltf/.glb
(``bpy.ops.import_scene.gltf``). It is imported into an empty scene
(``bpy.ops.wm.read_factory_settings(use_empty=True)``) with the importer's
defaults, except that the USD importer is always asked to set the scene's frame
range from the stage (``set_frame_range=True``, also its default in 5.0).
``--set OPTION=JSON`` passes one more importer option, its value parsed as JSON
(e.g. ``--set merge_parent_xform=false``). FRAME is an integer Blender frame.

Prints one JSON object, alone, on stdout (Blender's own log lines, which it
writes to stdout, are sent to stderr)::

    {"blender": "5.0.1", "format": "usd" | "gltf", "options": {...},
     "piece_count": N,          # objects whose name starts with "piece_"
     "parents": {"piece_00000": "wall" | null, ...},  # each piece object's parent
     "objects": {"MESH": n, "EMPTY": n, ...},   # all scene objects by type
     "frame_start": s, "frame_end": e,          # scene frame range after the import
     "fps": 24.0,               # scene.render.fps / fps_base after the import
     "actions": A,              # bpy.data.actions (glTF animation arrives as actions)
     "action_frame_range": [a, b] | null,       # union of the actions' frame ranges
     "transform_caches": C,     # Transform Cache constraints (USD transform animation)
     "scene_bounds": {"FRAME": [[x0, y0, z0], [x1, y1, z1]] | null},  # all shown meshes
     "properties": {"piece_00000": {"piece": 0, "mass_kg": m, "object": "wall"}, ...},
     "cameras": [{"name", "lens_mm", "sensor_fit", "sensor_mm": [w, h],
                  "render": [x, y], "fov": [horizontal, vertical] (radians)}],
     "frames": {"FRAME": {"piece_00000": {
         "location": [x, y, z],     # evaluated matrix_world.translation (Blender Z-up world)
         "rotation": [w, x, y, z],  # evaluated matrix_world's rotation, unit quaternion
         "bounds": [[x0, y0, z0], [x1, y1, z1]] | null}, ...}, ...}}

A piece's ``bounds`` is the world-space box of the evaluated vertices of the
shown mesh objects among the piece object and its descendants (with the USD
importer's ``merge_parent_xform=False`` a piece is an empty whose child is the
mesh), or null when none is shown (hidden in the viewport or for rendering).
A piece scaled to 0 has a box of size 0. Each value is read after
``scene.frame_set(FRAME)`` from ``bpy.context.evaluated_depsgraph_get()``.
"""

from __future__ import annotations

import json
import os
import sys
from collections import Counter
from pathlib import Path

import bpy
import numpy as np

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
GLTF_SUFFIXES = (".gltf", ".glb")
PREFIX = "piece_"
#: the piece data both exports give each piece object as custom properties
PIECE_PROPERTIES = ("piece", "mass_kg", "object")


def _import(path: Path, options: dict) -> str:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    suffix = path.suffix.lower()
    if suffix in USD_SUFFIXES:
        result = bpy.ops.wm.usd_import(filepath=str(path),
                                       **{"set_frame_range": True, **options})
        kind = "usd"
    elif suffix in GLTF_SUFFIXES:
        result = bpy.ops.import_scene.gltf(filepath=str(path), **options)
        kind = "gltf"
    else:
        raise SystemExit(f"{path}: not a USD or glTF file")
    if "FINISHED" not in result:
        raise SystemExit(f"{path}: import failed ({result})")
    return kind


def _bounds(obj, depsgraph) -> list | None:
    """World-space box of the shown, evaluated mesh vertices of obj and its descendants."""
    boxes = []
    for o in (obj, *obj.children_recursive):
        if o.type != "MESH":
            continue
        ev = o.evaluated_get(depsgraph)
        if not o.visible_get() or ev.hide_viewport or ev.hide_render:
            continue
        mesh = ev.to_mesh()
        try:
            co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
            mesh.vertices.foreach_get("co", co)
        finally:
            ev.to_mesh_clear()
        if not len(co):
            continue
        m = np.array(ev.matrix_world)
        world = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
        boxes.append((world.min(axis=0), world.max(axis=0)))
    if not boxes:
        return None
    return [np.min([b[0] for b in boxes], axis=0).tolist(),
            np.max([b[1] for b in boxes], axis=0).tolist()]


def _camera(obj, scene) -> dict:
    """A camera's lens, sensor and fit, and the horizontal and vertical fields of view
    (radians) it frames at the scene's render size."""
    cam = obj.data
    r = scene.render
    aspect = (r.resolution_x * r.pixel_aspect_x) / (r.resolution_y * r.pixel_aspect_y)
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if aspect >= 1 else "VERTICAL"
    half = cam.sensor_width / 2 / cam.lens if fit == "HORIZONTAL" else (
        (cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width) / 2 / cam.lens)
    tan_x, tan_y = (half, half / aspect) if fit == "HORIZONTAL" else (half * aspect, half)
    return {"name": obj.name, "lens_mm": cam.lens, "sensor_fit": cam.sensor_fit,
            "sensor_mm": [cam.sensor_width, cam.sensor_height],
            "render": [r.resolution_x, r.resolution_y],
            "fov": [2 * float(np.arctan(tan_x)), 2 * float(np.arctan(tan_y))]}


def _parse(argv: list[str]) -> tuple[list[str], dict]:
    options: dict = {}
    positional: list[str] = []
    args = iter(argv)
    for arg in args:
        if arg == "--set":
            key, sep, value = next(args, "").partition("=")
            if not sep:
                raise SystemExit("--set needs OPTION=JSON")
            options[key] = json.loads(value)
        else:
            positional.append(arg)
    return positional, options


def main(argv: list[str]) -> int:
    positional, options = _parse(argv)
    if len(positional) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    path = Path(positional[0]).resolve()
    frames = [int(f) for f in positional[1:]]
    # Blender and its importers log to stdout (C and Python alike): point fd 1 at
    # stderr while they run, and keep the real stdout for the one JSON line.
    sys.stdout.flush()
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)

    kind = _import(path, options)
    scene = bpy.context.scene
    pieces = sorted((o for o in scene.objects if o.name.startswith(PREFIX)),
                    key=lambda o: o.name)
    ranges = [tuple(a.frame_range) for a in bpy.data.actions]
    report = {
        "blender": bpy.app.version_string,
        "format": kind,
        "options": options,
        "piece_count": len(pieces),
        "parents": {o.name: o.parent.name if o.parent else None for o in pieces},
        "objects": dict(sorted(Counter(o.type for o in scene.objects).items())),
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "fps": scene.render.fps / scene.render.fps_base,
        "actions": len(ranges),
        "action_frame_range": ([min(r[0] for r in ranges), max(r[1] for r in ranges)]
                               if ranges else None),
        "transform_caches": sum(1 for o in scene.objects for c in o.constraints
                                if c.type == "TRANSFORM_CACHE"),
        "frames": {},
        # each piece object's custom properties of the piece data (USD userProperties,
        # glTF node extras)
        "properties": {o.name: {k: o[k] for k in PIECE_PROPERTIES if k in o.keys()}
                       for o in pieces},
        "cameras": [_camera(o, scene) for o in scene.objects if o.type == "CAMERA"],
    }
    for frame in frames:
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        at = report["frames"][str(frame)] = {}
        boxes = [b for b in (_bounds(o, depsgraph) for o in scene.objects if o.parent is None)
                 if b is not None]
        report.setdefault("scene_bounds", {})[str(frame)] = (
            [np.min([b[0] for b in boxes], axis=0).tolist(),
             np.max([b[1] for b in boxes], axis=0).tolist()] if boxes else None)
        for o in pieces:
            world = o.evaluated_get(depsgraph).matrix_world
            at[o.name] = {"location": list(world.translation),
                          "rotation": list(world.to_quaternion()),
                          "bounds": _bounds(o, depsgraph)}
    sys.stdout.flush()
    out.write(json.dumps(report) + "\n")
    out.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
