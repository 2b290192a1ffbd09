"""``blastvox run``: a whole shot from a scene file, make-style."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from blastvox.bounds import MAX_MEMORY_GIB


def run(
    scene: Path = typer.Argument(..., metavar="SCENE", help="Scene TOML with [[objects]], "
                                 "[[charges]] and [output] model, cache and export paths."),
    force: bool = typer.Option(False, "-B", "--force", help="Run every stage even if its "
                               "output is up to date."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="Print nothing but errors."),
    references_anywhere: bool = typer.Option(
        False, "--references-anywhere", help="Let a mesh's side files (an OBJ's MTL and "
        "textures, a .gltf's buffers and images) lie outside its folder; they must still "
        "be regular files (no device, FIFO or URL)."),
    max_memory: float = typer.Option(MAX_MEMORY_GIB, "--max-memory", metavar="GIB",
                                     help="Refuse a simulation that would need more memory, "
                                     "GiB (see `blastvox simulate --help`)."),
) -> None:
    """Run voxelize -> simulate -> export as the scene says, skipping up-to-date stages.

    A stage is up to date when its output is newer than all its inputs (like
    make). Outputs are written atomically.
    """
    from blastvox.cli.console import cli_warnings, err_console
    from blastvox.shot import run_scene

    console = err_console()
    started = time.perf_counter()

    def log(message: str) -> None:
        if not quiet:
            console.print(message, markup=False, highlight=False)

    with cli_warnings(console):
        ran = run_scene(scene, force=force, log=log,
                        warn=lambda m: console.print(f"blastvox: warning: {m}", markup=False,
                                                  highlight=False),
                        references_anywhere=references_anywhere, max_memory_gib=max_memory)
    if ran and not quiet:
        console.print(f"{scene}: {', '.join(ran)} in {time.perf_counter() - started:.2f} s",
                      markup=False, highlight=False)
