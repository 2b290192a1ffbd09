"""The ``blastvox`` typer application and its error handling."""

from __future__ import annotations

import sys

import typer

from blastvox.cli import info_cmd, materials_cmd, voxelize_cmd

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
app.command("info", help="Summarise a blastvox file (VoxelModel); --json for scripts.")(
    info_cmd.info)
app.command("materials", help="List the material library (built-in plus a TOML file).")(
    materials_cmd.materials)


@app.callback()
def _root(version: bool = typer.Option(False, "--version", help="Print the version and exit.",
                                       is_eager=True)) -> None:
    if version:
        from blastvox import __version__

        typer.echo(f"blastvox {__version__}")
        raise typer.Exit()


def main() -> None:
    """Console entry point: run the app; user errors become one line and exit code 1."""
    from blastvox.errors import BlastvoxError

    try:
        app(standalone_mode=False)
    except BlastvoxError as exc:
        typer.echo(f"blastvox: error: {exc}", err=True)
        sys.exit(exc.exit_code)
    except KeyboardInterrupt:
        typer.echo("blastvox: interrupted; no output written", err=True)
        sys.exit(130)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except typer.Abort:
        sys.exit(130)
    except Exception as exc:  # click usage errors carry their own formatting
        import click

        if isinstance(exc, click.ClickException):
            exc.show()
            sys.exit(exc.exit_code)
        raise
