"""``blastvox voxelize``: meshes -> VoxelModel."""

from __future__ import annotations

import os
import time
from enum import StrEnum
from pathlib import Path

import typer

from blastvox.bounds import DEFAULT_MAX_VOXELS, DEFAULT_SHEET_THICKNESS_M, printable
from blastvox.cli.options import UpAxis
from blastvox.errors import BlastvoxError, SceneError

DEFAULT_RESOLUTION = 32


class Shape(StrEnum):
    cube = "cube"
    conform = "conform"


def _parse_size(text: str, where: str) -> tuple[float, float, float]:
    from blastvox.bounds import VOXEL_SIZE

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise BlastvoxError(f"{where}: --voxel-size must be S or SX,SY,SZ in metres "
                            f"(got {text!r})") from None
    if len(values) == 1:
        values *= 3
    if len(values) != 3:
        raise BlastvoxError(f"{where}: --voxel-size needs 1 or 3 values (got {len(values)})")
    checked = [VOXEL_SIZE.at(v, f"{where}: --voxel-size") for v in values]
    return checked[0], checked[1], checked[2]


def _parse_ground(text: str, where: str = "") -> str | float | None:
    from blastvox.bounds import COORDINATE

    if text.lower() == "none":
        return None
    if text.lower() == "auto":
        return "auto"
    try:
        value = float(text)
    except ValueError:
        raise BlastvoxError(f"{where + ': ' if where else ''}--ground must be auto, none or a "
                            f"height in metres (got {text!r})") from None
    return COORDINATE.at(value, f"{where + ': ' if where else ''}--ground")


def voxelize(
    meshes: list[Path] = typer.Argument(None, help="Mesh files: OBJ, STL, PLY, OFF, glTF/GLB, "
                                        "or volume meshes meshio reads (.vtu, .msh, ...).",
                                        show_default=False),
    output: Path = typer.Option(None, "-o", "--output", help="VoxelModel file to write (.npz). "
                                "Default: the scene's output.model."),
    scene: Path = typer.Option(None, "--scene", help="Scene TOML with [[objects]] to voxelize "
                               "instead of MESH arguments."),
    voxel_size: str = typer.Option(None, "--voxel-size", help="Voxel edge in metres, S or "
                                   "SX,SY,SZ."),
    resolution: int = typer.Option(None, "--resolution", help="Voxels along the longest axis "
                                   f"(default {DEFAULT_RESOLUTION} if no --voxel-size)."),
    shape: Shape = typer.Option(Shape.cube, "--shape", help="cube: hexahedral voxels; "
                                "conform: boundary voxels are the exact cell-and-mesh shape."),
    jitter: float = typer.Option(0.0, "--jitter", help="Displace lattice vertices by a seeded "
                                 "random fraction of the voxel size, [0, 0.5)."),
    chunk_size: float = typer.Option(None, "--chunk-size", help="Mean chunk size in metres "
                                     "(a chunk's equivalent cube side), overriding the "
                                     "materials' chunk_size; 0: no chunks."),
    part_bond: float = typer.Option(None, "--part-bond", help="Factor on the strength of "
                                    "links between touching parts of a mesh (glTF nodes, OBJ "
                                    "objects): 1 (default) welds them; 0.2 lets a tyre or "
                                    "window break off first."),
    sheet_thickness: float = typer.Option(None, "--sheet-thickness", help="Thickness in "
                                          "metres of the parts that are open surfaces (a "
                                          "window pane), voxelized as sheets one voxel deep "
                                          f"(default {DEFAULT_SHEET_THICKNESS_M:g})."),
    anchored: bool = typer.Option(True, "--anchor/--no-anchor", help="Voxels touching the "
                                  "ground are foundations (default); --no-anchor: the "
                                  "object stands on the ground as a free body."),
    material: str = typer.Option("concrete", "--material", help="Default material "
                                 "(see `blastvox materials`)."),
    materials_file: Path = typer.Option(None, "--materials", help="TOML file of extra or "
                                        "overriding materials."),
    up_axis: UpAxis = typer.Option(None, "--up-axis", case_sensitive=False,
                                   help="Which input axis points up "
                                   "[default: Y, as glTF; Z for most CAD/STL files]."),
    ground: str = typer.Option(None, "--ground", help="Ground height: auto (lowest point), "
                               "none (free-floating, no foundation), or metres [default: auto]."),
    seed: int = typer.Option(None, "--seed", help="Seed for jitter and yield perturbation "
                             "[default: 0]."),
    max_voxels: int = typer.Option(DEFAULT_MAX_VOXELS, "--max-voxels",
                                   help="Refuse to make more voxels than this."),
    max_triangles: int = typer.Option(2_000_000, "--max-triangles", help="Refuse to read more "
                                      "triangles than this (all meshes together), before "
                                      "parsing a file that says it holds more."),
    max_objects: int = typer.Option(2_000, "--max-objects", help="Refuse a scene of more "
                                    "objects than this, before reading any."),
    references_anywhere: bool = typer.Option(
        False, "--references-anywhere", help="Let a mesh's side files (an OBJ's MTL and "
        "textures, a .gltf's buffers and images) lie outside its folder; they must still "
        "be regular files (no device, FIFO or URL)."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="No progress bar or summary."),
) -> None:
    """Voxelize meshes into a connected-voxel model.

    Inside is decided by a ray-averaged winding number, so small holes are
    tolerated; triangle soups and open sheets are refused. Each connected body
    becomes an object; face-adjacent voxels are linked.
    """
    from blastvox.cli.console import RichProgress, err_console
    from blastvox.materials import MaterialLibrary
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings
    from blastvox.voxelize.pipeline import voxelize as run

    meshes = list(meshes or [])
    if scene is not None and meshes:
        raise BlastvoxError(f"{scene}: give either --scene or MESH arguments, not both")
    if scene is None and not meshes:
        raise BlastvoxError("no input: give MESH files or --scene SCENE.toml")
    from blastvox.bounds import (
        CHUNK_SIZE,
        JITTER,
        MAX_OBJECTS,
        MAX_TRIANGLES,
        MAX_VOXELS,
        PART_BOND,
        RESOLUTION,
        SHEET_THICKNESS,
        check_seed,
        printable,
    )

    where = printable(scene or meshes[0])
    MAX_VOXELS.at(max_voxels, f"{where}: --max-voxels")
    MAX_TRIANGLES.at(max_triangles, f"{where}: --max-triangles")
    MAX_OBJECTS.at(max_objects, f"{where}: --max-objects")
    JITTER.at(jitter, f"{where}: --jitter")
    if chunk_size is not None:
        CHUNK_SIZE.at(chunk_size, f"{where}: --chunk-size")
    if part_bond is not None:
        PART_BOND.at(part_bond, f"{where}: --part-bond")
    if sheet_thickness is not None:
        SHEET_THICKNESS.at(sheet_thickness, f"{where}: --sheet-thickness")
    size = _parse_size(voxel_size, where) if voxel_size is not None else None
    if resolution is not None:
        RESOLUTION.at(resolution, f"{where}: --resolution")
    if seed is not None:
        check_seed(seed, f"{where}: --seed")
    ground_value = _parse_ground(ground, where) if ground is not None else "auto"
    if size is not None and resolution is not None:
        raise BlastvoxError(f"{where}: give --voxel-size or --resolution, not both")

    if scene is not None:
        mesh_flags = (("--voxel-size", voxel_size), ("--resolution", resolution),
                      ("--material", None if material == "concrete" else material),
                      ("--shape", None if shape == Shape.cube else shape),
                      ("--jitter", jitter or None), ("--chunk-size", chunk_size),
                      ("--part-bond", part_bond), ("--no-anchor", None if anchored else True),
                      ("--sheet-thickness", sheet_thickness))
        given = [flag for flag, value in mesh_flags if value is not None]
        if given:
            raise BlastvoxError(f"{where}: {given[0]} applies to MESH arguments; with --scene "
                                f"set it per object in the scene file")
        from blastvox.scene import load_scene
        from blastvox.voxelize.requests import requests_from_scene, settings_from_scene

        spec = load_scene(scene)
        requests = requests_from_scene(spec)
        settings = settings_from_scene(spec, max_voxels)
        if materials_file is not None:
            settings.library = settings.library.extended(_read_toml(materials_file),
                                                         str(materials_file))
        if up_axis is not None:
            settings.up_axis = up_axis.value
        if ground is not None:
            settings.ground = ground_value
        if seed is not None:
            settings.seed = seed
        if output is None:
            output = spec.output.model
        if output is None:
            raise SceneError(f"{where}: output.model: not set, and no -o given")
    else:
        library = MaterialLibrary.load(materials_file)
        if material not in library:  # fail before any work
            from blastvox.errors import MaterialError

            raise MaterialError(f"{where}: --material: unknown material {material!r} "
                                f"(known: {', '.join(library.names())})")
        if size is None and resolution is None:
            resolution = DEFAULT_RESOLUTION
        names = _object_names(meshes)
        requests = [ObjectRequest(mesh=m, name=names[i], voxel_size=size, resolution=resolution,
                                  shape=shape.value, jitter=jitter, material=material,
                                  chunk_size=chunk_size,
                                  part_bond=1.0 if part_bond is None else part_bond,
                                  anchored=anchored,
                                  sheet_thickness=DEFAULT_SHEET_THICKNESS_M
                                  if sheet_thickness is None else sheet_thickness)
                    for i, m in enumerate(meshes)]
        settings = VoxelizeSettings(up_axis=up_axis.value if up_axis else "Y",
                                    ground=ground_value,
                                    seed=0 if seed is None else seed, max_voxels=max_voxels,
                                    library=library)
        if output is None:
            raise BlastvoxError(f"{where}: no output file: give -o MODEL.npz")
    settings.references_anywhere = references_anywhere
    settings.max_triangles, settings.max_objects = max_triangles, max_objects
    settings.budget_scene = None  # the flags are here
    from blastvox.io.outputs import check_npz_output, check_output

    label = "-o" if scene is None or output != spec.output.model else "output.model"
    check_output(output, [scene, materials_file, *(r.mesh for r in requests)],
                 make_dirs=scene is not None and output == spec.output.model, label=label)
    check_npz_output(output, label, "VoxelModel")
    from blastvox.voxelize.provenance import recorded_settings

    settings.recorded = recorded_settings(requests, settings, scene)

    console = err_console()
    started = time.perf_counter()
    with RichProgress(enabled=not quiet and console.is_terminal) as progress:
        model = run(requests, settings, progress=progress,
                    warn=lambda m: console.print(f"blastvox: warning: {m}", markup=False,
                                                  highlight=False))
    model.save(output)
    if not quiet:
        _print_summary(console, model, output, time.perf_counter() - started)


def _read_toml(path: Path) -> dict:
    from blastvox.errors import MaterialError
    from blastvox.materials import read_toml

    return read_toml(path, MaterialError)


def _print_summary(console, model, output: Path, seconds: float) -> None:
    s = model.summary()
    console.print(
        f"[bold]{output}[/]: {s['voxel_count']:,} voxels, {s['link_count']:,} links, "
        f"{s['object_count']} object(s), {s['foundation_voxel_count']:,} foundation voxels, "
        f"{s['total_mass_kg']:.4g} kg, materials {', '.join(s['materials_used'])} "
        f"({seconds:.2f} s, {s['voxel_count'] / max(seconds, 1e-9):,.0f} voxels/s)")


def _object_names(meshes: list[Path]) -> list[str]:
    """An object name per MESH argument: its file's stem, with _2, _3, ... for later files
    of the same stem (the scene refuses duplicate names; on the command line they come
    from the files). The same file twice is an error: two copies of one solid overlap."""
    names: list[str] = []
    seen: set[Path] = set()
    for mesh in meshes:
        try:
            key = Path(mesh).resolve()
        except (OSError, RuntimeError, ValueError):  # a symlink loop: the reader says why
            key = Path(os.path.abspath(mesh))
        if key in seen:
            raise BlastvoxError(f"{mesh}: given twice as a MESH (the second copy would "
                                "overlap the first); give each mesh once")
        seen.add(key)
        stem, k = Path(printable(mesh)).stem, 2  # a non-UTF-8 name's bytes escaped
        name = stem
        while name in names:
            name, k = f"{stem}_{k}", k + 1
        names.append(name)
    return names
