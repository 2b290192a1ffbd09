"""``blastvox preview``: SimCache -> contact sheet (.png) or animation (.gif, .mp4)."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from blastvox.bounds import MAX_OUTPUT_PIXELS, MAX_PIXELS


def preview(
    cache_path: Path = typer.Argument(..., metavar="SIM", help="SimCache .npz from "
                                      "`blastvox simulate` or `blastvox run`."),
    output: Path = typer.Option(..., "-o", "--output", help="Output: .png (contact sheet of "
                                "the frames), .gif or .mp4 (animation)."),
    frames: str = typer.Option(None, "--frames", metavar="A:B:STEP",
                               help="Frames A to B inclusive, every STEP (A alone: one frame; "
                                    "'::10': every tenth). [default: 6 frames spread over the "
                                    "shot for .png, every frame for .gif/.mp4]"),
    camera: str = typer.Option(None, "--camera", metavar="scene|auto|PX,PY,PZ:LX,LY,LZ[:MM]",
                               help="scene: the scene's camera with its shake; auto: framed "
                                    "on the action; or a position and look-at point in m "
                                    "(model frame) and a focal length in mm (default 35). "
                                    "[default: scene if the shot has one, else auto]"),
    size: str = typer.Option("960x540", "--size", metavar="WxH",
                             help="Pixels of each frame."),
    hide: str = typer.Option(None, "--hide", metavar="LAYER[,LAYER]",
                             help="Leave out layers: pieces, ground, particles, shock."),
    supersample: int = typer.Option(2, "--supersample", metavar="N",
                                    help="Anti-aliasing: N x N samples per pixel (1-4)."),
    fps: float = typer.Option(None, "--fps", help="Animation frame rate, 0.01 to 1000 "
                              "[default: the shot's fps / STEP]."),
    max_pixels: int = typer.Option(MAX_PIXELS, "--max-pixels", metavar="N",
                                   help="Refuse to render more pixels a frame (W x H x "
                                        "supersample^2; about 32 bytes each)."),
    max_output_pixels: int = typer.Option(MAX_OUTPUT_PIXELS, "--max-output-pixels",
                                          metavar="N", help="Refuse a .png sheet or .gif of "
                                          "more pixels in all (frames x W x H, all kept in "
                                          "memory; an .mp4 streams)."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="No progress bar or summary."),
) -> None:
    """Render a SimCache headless on the CPU: pieces with their materials and damage faces,
    dust, fire and smoke, the ground and the shock fronts, from the scene camera or an
    automatic one. Sizes over the pixel budgets (--max-pixels, --max-output-pixels) are
    refused before anything is rendered (docs/user-guide.md, "Limits and exit codes")."""
    from blastvox.preview.options import (
        PreviewOptions,
        check_fps,
        check_supersample,
        output_format,
        parse_camera,
        parse_frame_spec,
        parse_hide,
        parse_size,
    )

    started = time.perf_counter()
    output_format(output)  # argument errors first, before loading anything
    from blastvox.io.outputs import check_output

    check_output(output, [cache_path])
    options = PreviewOptions(frames=parse_frame_spec(frames), camera=parse_camera(camera),
                             size=parse_size(size), supersample=check_supersample(supersample),
                             hide=parse_hide(hide), fps=check_fps(fps),
                             max_pixels=max_pixels, max_output_pixels=max_output_pixels)
    from blastvox.cache import SimCache
    from blastvox.cli.console import RichProgress, err_console
    from blastvox.preview.api import preview as run

    cache = SimCache.load(cache_path)
    with RichProgress(enabled=not quiet) as progress:
        result = run(cache, output, options, progress=progress, source=str(cache_path))
    if not quiet:
        n = len(result.frames)
        what = (f"contact sheet of {n} frame{'s' * (n != 1)}" if result.kind == "sheet"
                else f"{n} frames at {result.fps:.4g} fps")
        err_console().print(f"{output}: {what}, {result.size[0]}x{result.size[1]} px, "
                            f"{result.render_seconds / max(n, 1):.3f} s/frame rendering, "
                            f"{time.perf_counter() - started:.2f} s total", markup=False)
