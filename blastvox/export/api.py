"""``export(cache, path, options)``: the export stage's one entry point.

The format follows the output suffix: .usda/.usdc/.usd (OpenUSD), .usdz (a
package of the .usdc and its textures) or .gltf/.glb (glTF 2.0). Writers
produce byte-identical files for the same cache and options (stable names and
order, no timestamps) and write atomically.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

from blastvox.cache import SimCache
from blastvox.errors import BlastvoxError, OutputError
from blastvox.export.options import ExportOptions
from blastvox.geometry.frames import UP_AXES

__all__ = ["ExportOptions", "GLTF_SUFFIXES", "USD_SUFFIXES", "export", "side_folders",
           "side_outputs"]

USD_SUFFIXES = (".usda", ".usdc", ".usd", ".usdz")
GLTF_SUFFIXES = (".gltf", ".glb")
#: pieces above which a node-per-piece glTF warns: Blender's importer slows down with
#: the square of the node count (docs/benchmarks.md, "Export at scale")
GLTF_NODE_WARNING = 2000


def side_outputs(path: str | Path) -> tuple[Path | None, Path | None]:
    """What an export to ``path`` writes beside it: (file, directory): a .gltf's buffer
    ``<stem>.bin``, and a .usd/.usda/.usdc's ``<stem>_textures/`` (the look's and the
    damage faces' PNGs); None where there is none."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".gltf":
        return path.with_name(path.stem + ".bin"), None
    if suffix in USD_SUFFIXES and suffix != ".usdz":  # a .usdz packs its textures inside
        return None, path.with_name(path.stem + "_textures")
    return None, None


def side_folders(path: str | Path) -> list[Path]:
    """Every folder an export to ``path`` may write files into: a .usd/.usda/.usdc's
    ``<stem>_textures/`` and ``<stem>_volumes/`` (its particle volumes)."""
    _, textures = side_outputs(path)
    if textures is None:
        return []
    path = Path(path)
    return [textures, path.with_name(path.stem + "_volumes")]


PARTICLE_MODES = ("auto", "volumes", "spheres")


def _resolved(options: ExportOptions, path: Path) -> ExportOptions:
    """``options`` with ``particles`` "auto" made "volumes" or "spheres" for ``path``'s
    format; a bad particles mode or cell size is a BlastvoxError."""
    import dataclasses
    import math

    if options.particles not in PARTICLE_MODES:
        raise BlastvoxError(f"{path}: --particles must be one of {', '.join(PARTICLE_MODES)} "
                            f"(got {options.particles!r})")
    voxel = options.volume_voxel_m
    if not (isinstance(voxel, int | float) and math.isfinite(voxel) and 0.001 <= voxel <= 100):
        raise BlastvoxError(f"{path}: --volume-voxel must be a cell size from 0.001 to 100 m "
                            f"(got {voxel!r})")
    suffix = path.suffix.lower()
    if suffix == ".usdz" and options.particles == "volumes":
        raise BlastvoxError(f"{path}: a .usdz cannot carry the .vdb files of particle volumes; "
                            f"use --particles spheres (or auto), or a .usdc")
    mode = options.particles
    if mode == "auto":
        mode = "spheres" if suffix == ".usdz" else "volumes"
    return dataclasses.replace(options, particles=mode)


def export(cache: SimCache, path: str | Path, options: ExportOptions | None = None) -> None:
    """Write ``cache`` to ``path`` in the format its suffix names."""
    options = options or ExportOptions()
    path = Path(path)
    suffix = path.suffix.lower()
    if options.up_axis not in UP_AXES:
        raise BlastvoxError(f"{path}: --up-axis must be Y or Z (got {options.up_axis!r})")
    options = _resolved(options, path)
    if suffix in USD_SUFFIXES:
        if options.layout == "skinned":
            raise BlastvoxError(f"{path}: --layout skinned is glTF only; USD takes xforms "
                                f"or instancer")
        if suffix == ".usdz":
            from blastvox.export.usdz import write_usdz

            with _usd_errors(path):
                write_usdz(cache, path, options)
        else:
            _write_usd_staged(cache, path, options)
    elif suffix in GLTF_SUFFIXES:
        if options.layout == "instancer":
            raise BlastvoxError(f"{path}: --layout instancer is USD only; glTF takes xforms "
                                f"(a node per piece) or skinned (one mesh, a joint per piece)")
        if options.layout == "xforms" and cache.piece_count > GLTF_NODE_WARNING:
            import warnings

            from blastvox.errors import ExportWarning

            warnings.warn(f"{path}: {cache.piece_count:,} pieces, a glTF node each: Blender's "
                          f"importer slows down with the square of the node count; --layout "
                          f"skinned or a .usdc imports several times faster "
                          f"(docs/benchmarks.md, Export at scale)", ExportWarning, stacklevel=2)
        from blastvox.export.gltf import write_gltf

        write_gltf(cache, path, options)
    else:
        raise BlastvoxError(f"{path}: unknown export format {suffix or '(no suffix)'!r}; use "
                            f"{', '.join(USD_SUFFIXES + GLTF_SUFFIXES)}")


def _write_usd_staged(cache: SimCache, path: Path, options: ExportOptions) -> None:
    """write_usd into a private folder beside ``path``, then its textures and volumes
    folders and the file moved into place, the folders first (issue 36): a failed export
    (a full disk, Ctrl-C, an error) leaves the previous export and its folders as they
    were, and no
    temporary behind (a killed one's is removed by the next export); USD's errors are
    one line."""
    import os

    from blastvox.export.usd import write_usd
    from blastvox.io.atomic import staged_directory, swapped_in
    from blastvox.io.outputs import refuse_special

    with staged_directory(path) as staging, _usd_errors(path):
        staged = staging / path.name
        try:
            write_usd(cache, staged, options)
        except OutputError as exc:  # name the file where it was to go, not the staging
            where = "" if path.parent == Path(".") else f"{path.parent}{os.sep}"
            raise OutputError(str(exc).replace(f"{staging}{os.sep}", where)) from None
        try:
            with contextlib.ExitStack() as swaps:
                for folder in side_folders(path):  # textures, then volumes
                    new = staging / folder.name
                    if new.is_dir():
                        swaps.enter_context(swapped_in(new, folder))
                refuse_special(path, "output")  # it may have become a device meanwhile
                os.replace(staged, path)
        except OSError as exc:
            raise OutputError(f"{path}: cannot write ({exc.strerror or exc})") from None


@contextlib.contextmanager
def _usd_errors(path: Path) -> Iterator[None]:
    """USD's error (a Tf.ErrorException holding every C++ error: 9,963 lines for a full
    disk) as one OutputError line: the first error's own words."""
    from pxr import Tf

    try:
        yield
    except Tf.ErrorException as exc:
        first = str(exc.args[0]) if exc.args else str(exc)
        first = next((line for line in first.splitlines() if line.strip()), first)
        said = first.split(" : ", 1)[-1].strip().strip("'\" ")
        raise OutputError(f"{path}: cannot write ({' '.join(said.split())})") from None
