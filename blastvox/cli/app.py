"""The ``blastvox`` typer application and its error handling."""

from __future__ import annotations

import typer

from blastvox.cli import (
    blast_cmd,
    diff_cmd,
    export_cmd,
    info_cmd,
    materials_cmd,
    preview_cmd,
    run_cmd,
    simulate_cmd,
    voxelize_cmd,
    wedge_cmd,
)

app = typer.Typer(
    name="blastvox",
    help="Connected-voxel blast-wave destruction for shot pipelines: "
         "voxelize meshes, simulate blasts, bake USD/glTF caches.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)
app.command("voxelize", help="Turn meshes into connected voxels with per-voxel materials "
            "(writes a VoxelModel .npz).")(voxelize_cmd.voxelize)
app.command("simulate", help="Blow up a VoxelModel: blast wave, fracture, fragments and "
            "motion at a fixed step (writes a SimCache .npz).")(simulate_cmd.simulate)
app.command("export", help="Bake a SimCache into a USD or glTF cache (pieces, damage faces, "
            "dust, shock).")(export_cmd.export)
app.command("run", help="Build a whole shot from a scene: voxelize, simulate, export, "
            "skipping up-to-date stages (like make).")(run_cmd.run)
app.command("wedge", help="Run a scene over a grid of parameter values (charge, seed, "
            "strength, voxel size, dt...) on Dask; resumable.")(wedge_cmd.wedge)
app.command("info", help="Summarise a blastvox file (VoxelModel or SimCache); --json for "
            "scripts.")(
    info_cmd.info)
app.command("materials", help="List the material library (built-in plus a TOML file).")(
    materials_cmd.materials)
app.command("blast", help="Blast-wave calculator: overpressure, arrival, duration and impulse "
            "at distances.")(blast_cmd.blast)
app.command("preview", help="Render a SimCache headless: a contact sheet (.png) or an "
            "animation (.gif, .mp4).")(preview_cmd.preview)
app.command("diff", help="Compare two caches within tolerances (exit 0 same, 1 different, "
            "2 error).")(diff_cmd.diff)


def _print_version(value: bool) -> None:
    if value:
        from blastvox import __version__

        typer.echo(f"blastvox {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", help="Print the version and exit.",
                                       is_eager=True, callback=_print_version)) -> None:
    """Connected-voxel blast-wave destruction for shot pipelines."""
