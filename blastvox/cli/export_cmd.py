"""``blastvox export``: SimCache -> USD or glTF cache."""

from __future__ import annotations

import time
from enum import StrEnum
from pathlib import Path

import typer

from blastvox.cli.options import UpAxis


class FractureFaces(StrEnum):
    rough = "rough"
    voxel = "voxel"


class Particles(StrEnum):
    auto = "auto"
    volumes = "volumes"
    spheres = "spheres"


class Layout(StrEnum):
    xforms = "xforms"
    instancer = "instancer"
    skinned = "skinned"


def export(
    cache_path: Path = typer.Argument(..., metavar="SIM", help="SimCache .npz from "
                                      "`blastvox simulate`."),
    output: Path = typer.Option(..., "-o", "--output", help="Output: .usda, .usdc, .usd, "
                                ".usdz (one package with its textures), .gltf or .glb (the "
                                "suffix picks the format)."),
    up_axis: UpAxis = typer.Option(UpAxis.Y, "--up-axis", case_sensitive=False,
                                   help="Up axis of the written file."),
    layout: Layout = typer.Option(Layout.xforms, "--layout", case_sensitive=False,
                                  help="xforms: an Xform and Mesh "
                                  "per piece (USD) or a node per piece (glTF); instancer: a USD "
                                  "PointInstancer (many pieces); skinned: a glTF of one mesh "
                                  "with a joint per piece (imports fast in Blender)."),
    shock: bool = typer.Option(False, "--shock/--no-shock", help="Also write each charge's "
                               "shock front as a growing sphere (viewport aid; USD: a guide "
                               "prim that renders skip)."),
    damage_textures: bool = typer.Option(True, "--damage-textures/--flat-damage",
                                         help="Fracture faces show their material's damage "
                                         "texture (cracked concrete, splintered wood...; "
                                         "USD: PNGs in <stem>_textures/), or its flat "
                                         "damage_color."),
    fracture_faces: FractureFaces = typer.Option(
        FractureFaces.rough, "--fracture-faces", case_sensitive=False,
        help="rough: fracture faces drawn as broken rubble (steps smoothed, corners "
        "roughened; the pieces still fit together at rest; collision stays voxel-based); "
        "voxel: the voxels' cell faces."),
    particles: Particles = typer.Option(
        Particles.auto, "--particles", case_sensitive=False,
        help="USD: dust, fire, smoke and the fireball as volumes (OpenVDB grids per frame "
        "in <stem>_volumes/: soft clouds, fire with a temperature grid) or spheres (a "
        "PointInstancer); auto: volumes, spheres in a .usdz (it cannot carry .vdb files). "
        "glTF: spheres writes a node per particle (at most 256 per system), else none."),
    volume_voxel: float = typer.Option(0.1, "--volume-voxel", metavar="M",
                                       help="Cell size of the particle volumes, m."),
    key_tolerance: float = typer.Option(
        1e-4, "--key-tolerance", metavar="M", min=0.0, max=1.0,
        help="Keyframe reduction: key a piece's translation only where interpolating the "
        "kept keys (linearly) would miss it by more than this, m (0.1 mm). 0 with "
        "--key-angle-tolerance 0 keys every frame."),
    key_angle_tolerance: float = typer.Option(
        0.1, "--key-angle-tolerance", metavar="DEG", min=0.0, max=90.0,
        help="Keyframe reduction: key a piece's rotation only where interpolating the kept "
        "keys would miss it by more than this angle, degrees."),
    damage_samples: bool = typer.Option(
        False, "--damage-samples/--final-damage",
        help="USD: time-sample the per-face damage primvar at every change (Blender then "
        "re-reads every mesh at each frame change), or write its final value and the "
        "frame each face is first damaged."),
    velocity_primvars: bool = typer.Option(
        True, "--velocity-primvars/--no-velocity-primvars",
        help="USD: each piece's time-sampled velocity (m/s) and angularVelocity (deg/s) "
        "primvars, or none (a smaller file, faster frame changes in Blender)."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="No summary."),
) -> None:
    """Bake per-piece meshes and transforms, damage faces, dust and cues into USD or glTF."""
    from blastvox.cache import SimCache
    from blastvox.cli.console import cli_warnings, err_console
    from blastvox.export.api import ExportOptions, side_folders, side_outputs
    from blastvox.export.api import export as run
    from blastvox.io.outputs import check_distinct, check_output, check_side_directory

    check_output(output, [cache_path])
    buffer, _ = side_outputs(output)
    if buffer is not None:  # a .gltf's buffer is written beside it
        check_output(buffer, [cache_path], label="-o (the .gltf's .bin)")
        check_distinct([("-o", output), ("its .bin", buffer)])
    for folder in side_folders(output):  # textures, volumes
        check_side_directory(folder, [cache_path],
                             label=f"-o (its {folder.name.rsplit('_', 1)[-1]})")
    started = time.perf_counter()
    cache = SimCache.load(cache_path)
    with cli_warnings(err_console()):
        run(cache, output, ExportOptions(up_axis=up_axis.value, layout=layout.value,
                                           shock=shock, damage_textures=damage_textures,
                                           fracture_faces=fracture_faces.value,
                                           particles=particles.value,
                                           volume_voxel_m=volume_voxel,
                                           key_tolerance_m=key_tolerance,
                                           key_tolerance_deg=key_angle_tolerance,
                                           damage_samples=damage_samples,
                                           velocity_primvars=velocity_primvars))
    if not quiet:
        err_console().print(f"{output}: {cache.piece_count:,} pieces, {cache.frame_count} "
                            f"frames, {output.stat().st_size / 1e6:.2f} MB "
                            f"({time.perf_counter() - started:.2f} s)", markup=False)
