"""Import a blastvox export into Blender, render frames with Cycles and report them, as JSON.

Run by the Blender venv's python (``.venv-blender``: ``make blender-venv``), not by
the project's::

    .venv-blender/bin/python tools/blender/render_check.py FILE OUT_DIR FRAME [FRAME ...]
        [--size WxH] [--samples N] [--motion-blur]
        [--camera EX,EY,EZ:TX,TY,TZ] [--fire [--glow G]] [--opaque] [--denoise]
        [--ground Z]

What an artist does with a cache, in a script: FILE (.usd/.usda/.usdc or
.gltf/.glb) is imported into an empty scene with the importer's defaults (as
``import_check.py`` does); the scene's camera is the file's when it has one
(made the active camera, as the importers leave it inactive).
A file without a camera gets one, as the artist would add it: a 35 mm lens
looking at the centre of the imported meshes' box at frame 0 from the front
right, above, far enough away to frame the box. A sun and a grey sky light
the scene (the exports carry no lights). ``--camera`` puts a 35 mm camera at E
looking at T instead (Blender's world: Z up, m), for a close look at the debris.
Particle volumes (a USD export's ``<stem>_volumes/``, read where the file is) import
as Volume objects with Blender's default volume material (its USD importer reads no
material of a Volume prim: grey smoke whose density is the ``density`` grid); a
plain import shows fire and the fireball by their own glow (``<system>_glow``:
emissive balls, which the importer does read). ``--fire`` gives the volumes that
hold a ``temperature`` grid (fire, fireball) the one material an artist adds for
flames: a Principled Volume with Blackbody Intensity ``--glow`` (default 0.5: 1 is
physical) reading ``temperature``, and dust a warm grey colour, and hides the
``_glow`` objects. ``--opaque`` renders the sky behind (for pictures) instead of a
transparent film; ``--denoise`` runs Cycles' denoiser (OpenImageDenoise) on each
frame (for pictures: few samples, smooth volumes).
``--ground Z`` adds what the exports leave out and an artist adds first: a ground, a
400 m square at height Z (Blender's world, m; the shot's ground height, 0 for the
examples) in a matte grey-brown, so that the rubble lies on something and casts shadows.
Each FRAME is rendered with Cycles on the CPU (few samples, a tiny image, film
transparent so that the alpha channel says what is covered) to ``OUT_DIR/frame_NNNN.png``.

Prints one JSON object, alone, on stdout (Blender's log goes to stderr)::

    {"blender": "5.0.1", "camera": {"from_file": bool, "lens_mm": 35.0,
                                   "sensor_width_mm": 36.0},
     "volumes": {"NAME": {"grids": [names], "materials": [names]}},
     "frames": {"FRAME": {"png": path,
                          "coverage": c,      # fraction of pixels with alpha > 0.5
                          "luminance": l,     # mean Rec. 709 luminance of covered pixels
                          "rgb": [r, g, b]}}} # mean colour of covered pixels

A crash in Blender (as an empty point cloud crashed Cycles at frame 0) ends
the process without the JSON: the caller sees a non-zero exit code.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import bpy
import numpy as np
from mathutils import Vector

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
LUMA = np.array([0.2126, 0.7152, 0.0722])
LENS_MM = 35.0
SENSOR_MM = 36.0


def _import(path: Path) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if path.suffix.lower() in USD_SUFFIXES:
        result = bpy.ops.wm.usd_import(filepath=str(path), set_frame_range=True)
    else:
        result = bpy.ops.import_scene.gltf(filepath=str(path))
    if "FINISHED" not in result:
        raise SystemExit(f"{path}: Blender's importer returned {result}")


def _mesh_box(scene: bpy.types.Scene) -> tuple[Vector, Vector]:
    """World box of the evaluated vertices of every shown mesh at the current frame."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for obj in scene.objects:
        if obj.type != "MESH" or obj.hide_render:
            continue
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        if len(mesh.vertices):
            co = np.empty(len(mesh.vertices) * 3)
            mesh.vertices.foreach_get("co", co)
            m = np.array(evaluated.matrix_world)
            world = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
            lo, hi = np.minimum(lo, world.min(axis=0)), np.maximum(hi, world.max(axis=0))
        evaluated.to_mesh_clear()
    if not np.isfinite(lo).all():
        lo = hi = np.zeros(3)
    return Vector(lo.tolist()), Vector(hi.tolist())


def _add_camera(scene: bpy.types.Scene) -> None:
    """A 35 mm camera that frames the meshes' box at the current frame."""
    lo, hi = _mesh_box(scene)
    centre, radius = (lo + hi) / 2, max((hi - lo).length / 2, 0.5)
    fov = 2 * math.atan(SENSOR_MM / 2 / LENS_MM)
    distance = radius / math.sin(fov / 2) * 1.1
    direction = Vector((0.55, -0.75, 0.38)).normalized()
    data = bpy.data.cameras.new("render_check")
    data.lens, data.sensor_width = LENS_MM, SENSOR_MM
    data.clip_end = max(1000.0, 4 * distance)
    camera = bpy.data.objects.new("render_check", data)
    scene.collection.objects.link(camera)
    camera.location = centre + direction * distance
    camera.rotation_euler = (centre - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera


def _place_camera(scene: bpy.types.Scene, eye: Vector, target: Vector) -> None:
    """A 35 mm camera at ``eye`` looking at ``target`` (Blender's world, Z up, m)."""
    data = bpy.data.cameras.new("render_check")
    data.lens, data.sensor_width = LENS_MM, SENSOR_MM
    camera = bpy.data.objects.new("render_check", data)
    scene.collection.objects.link(camera)
    camera.location = eye
    camera.rotation_euler = (target - eye).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera


def _ground(scene: bpy.types.Scene, height: float) -> None:
    """A 400 m matte square at ``height`` (Blender's Z)."""
    bpy.ops.mesh.primitive_plane_add(size=400.0, location=(0.0, 0.0, height))
    plane = bpy.context.active_object
    plane.name = "render_check_ground"
    material = bpy.data.materials.new("render_check_ground")
    material.use_nodes = True
    shader = material.node_tree.nodes["Principled BSDF"]
    shader.inputs["Base Color"].default_value = (0.32, 0.30, 0.27, 1.0)
    shader.inputs["Roughness"].default_value = 0.95
    plane.data.materials.append(material)


def _light(scene: bpy.types.Scene) -> None:
    sun = bpy.data.objects.new("render_check_sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(50), 0.0, math.radians(30))
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("render_check")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.4, 0.4, 0.45, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    scene.world = world


#: --fire's Blackbody Intensity (--glow): 1 is physical; half of it keeps the debris
#: beside a 2,200 K fireball in view in the sun (3 W/m^2) of this script
GLOW = 0.5
#: the colour an artist gives each particle system's volume with --fire
VOLUME_COLORS = {"dust": (0.55, 0.50, 0.45), "smoke": (0.25, 0.25, 0.25),
                 "fire": (0.6, 0.45, 0.3), "fireball": (0.6, 0.45, 0.3)}


def _volumes(scene: bpy.types.Scene, fire: bool, glow: float = 1.0) -> dict:
    """The imported Volume objects: their grids and materials; with ``fire`` a
    Principled Volume each (Blackbody from ``temperature`` where the volume has it)
    and the exports' own glow of fire and the fireball (``<system>_glow``, emissive
    shells) hidden, as an artist who shades the flame in the volume hides it."""
    out = {}
    for obj in scene.objects:
        if fire and obj.name.split(".")[0].endswith("_glow"):
            obj.hide_render = True
        if obj.type != "VOLUME":
            continue
        volume = obj.data
        volume.grids.load()
        grids = [g.name for g in volume.grids]
        if fire:
            material = bpy.data.materials.new(f"render_check_{obj.name}")
            material.use_nodes = True
            nodes = material.node_tree.nodes
            nodes.clear()
            shader = nodes.new("ShaderNodeVolumePrincipled")
            output = nodes.new("ShaderNodeOutputMaterial")
            material.node_tree.links.new(shader.outputs["Volume"], output.inputs["Volume"])
            system = obj.name.split(".")[0]
            color = VOLUME_COLORS.get(system, (0.5, 0.5, 0.5))
            shader.inputs["Color"].default_value = (*color, 1.0)
            if "temperature" in grids:
                shader.inputs["Blackbody Intensity"].default_value = glow
                shader.inputs["Temperature Attribute"].default_value = "temperature"
                # Cycles multiplies the Temperature input by the attribute: the grid is K
                shader.inputs["Temperature"].default_value = 1.0
            obj.data.materials.clear()
            obj.data.materials.append(material)
        out[obj.name] = {"grids": grids, "materials": [m.name for m in obj.data.materials if m]}
    return out


def _render(scene: bpy.types.Scene, frame: int, out: Path) -> dict:
    scene.frame_set(frame)
    scene.render.filepath = str(out)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(out))
    pixels = np.array(image.pixels[:], dtype=np.float64).reshape(-1, 4)
    bpy.data.images.remove(image)
    covered = pixels[:, 3] > 0.5
    rgb = pixels[covered, :3].mean(axis=0) if covered.any() else np.zeros(3)
    return {"png": str(out), "coverage": float(covered.mean()),
            "luminance": float(rgb @ LUMA), "rgb": rgb.tolist()}


def main(argv: list[str]) -> None:
    args, size, samples, blur, view = [], (96, 54), 4, False, None
    fire, opaque, glow, denoise, ground = False, False, GLOW, False, None
    it = iter(argv)
    for arg in it:
        if arg == "--size":
            size = tuple(int(v) for v in next(it).lower().split("x"))
        elif arg == "--samples":
            samples = int(next(it))
        elif arg == "--motion-blur":
            blur = True
        elif arg == "--fire":
            fire = True
        elif arg == "--glow":
            glow = float(next(it))
        elif arg == "--opaque":
            opaque = True
        elif arg == "--denoise":
            denoise = True
        elif arg == "--ground":
            ground = float(next(it))
        elif arg == "--camera":
            view = [Vector(float(c) for c in point.split(",")) for point in next(it).split(":")]
        else:
            args.append(arg)
    if "-h" in args or "--help" in args or len(args) < 3:
        sys.exit(__doc__)  # usage, not an IndexError
    path, out_dir, frames = Path(args[0]), Path(args[1]), [int(f) for f in args[2:]]
    out_dir.mkdir(parents=True, exist_ok=True)
    real_stdout = os.dup(1)
    os.dup2(2, 1)  # Blender's own log lines go to stderr: stdout carries only the JSON
    _import(path)
    scene = bpy.context.scene
    if scene.camera is None:  # the importers add the file's camera but leave it inactive
        scene.camera = next((o for o in scene.objects if o.type == "CAMERA"), None)
    from_file = scene.camera is not None and view is None
    if view is not None:
        _place_camera(scene, view[0], view[1])
    elif not from_file:
        scene.frame_set(frames[0] if frames else 0)
        _add_camera(scene)
    _light(scene)
    if ground is not None:
        _ground(scene, ground)
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = denoise
    scene.render.film_transparent = not opaque
    # Cycles' motion blur, shutter open a whole frame: it blurs what moves between the
    # frame's sub-steps as the importers evaluate them (USD transform caches at
    # sub-frames, glTF keyframes interpolated)
    scene.render.use_motion_blur = blur
    scene.render.motion_blur_shutter = 1.0
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.frame_set(frames[0] if frames else 0)
    volumes = _volumes(scene, fire, glow)
    report = {"blender": bpy.app.version_string, "volumes": volumes,
              "camera": {"from_file": from_file, "lens_mm": scene.camera.data.lens,
                         "sensor_width_mm": scene.camera.data.sensor_width},
              "frames": {str(f): _render(scene, f, out_dir / f"frame_{f:04d}.png")
                         for f in frames}}
    sys.stdout.flush()
    os.dup2(real_stdout, 1)
    print(json.dumps(report))


if __name__ == "__main__":
    main(sys.argv[1:])
