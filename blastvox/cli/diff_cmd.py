"""``blastvox diff``: compare two caches within tolerances (the golden-file check in CI)."""

from __future__ import annotations

from pathlib import Path

import typer


def diff(
    a: Path = typer.Argument(..., metavar="A", help="A blastvox .npz, USD (.usd/.usda/.usdc/.usdz) "
                             "or glTF (.glb/.gltf) file, e.g. the fresh bake."),
    b: Path = typer.Argument(..., metavar="B", help="The file to compare with, of the same "
                             "kind, e.g. the committed golden file."),
    atol: float = typer.Option(1e-6, "--atol", help="Absolute tolerance for floats."),
    rtol: float = typer.Option(1e-6, "--rtol", help="Relative tolerance for floats "
                               "(|A-B| <= atol + rtol*|B|)."),
    limit: int = typer.Option(20, "-n", "--limit", min=1,
                              help="Print at most this many differences."),
    verbose: bool = typer.Option(False, "-v", "--verbose",
                                 help='Print "same" when the files agree.'),
    references_anywhere: bool = typer.Option(
        False, "--references-anywhere", help="Let the files a USD layer or a .gltf refers "
        "to (sublayers, references, payloads, clips, textures, buffers) lie outside the "
        "folder of A or B; they must still be regular files (no device, FIFO or URL)."),
) -> None:
    """Compare A with B: exit 0 if they agree within the tolerances, 1 if they differ
    (the first differences are printed, one per line: path, attribute, frame, both
    values), 2 if they cannot be compared (missing, unreadable, different kinds).

    npz: meta (except tool_version) and every array. USD: stage metadata, prims,
    types, authored attributes (default and every time sample), connections and
    relationship targets. glTF: the JSON (except buffer layout and generator) and
    every accessor decoded.

    What the files refer to (USD sublayers, references, payloads, clips and textures,
    a .gltf's buffers) is read only if it is a regular file inside the folder of the
    file that names it (--references-anywhere: any folder), never a URL; anything else
    is refused (exit 2) before it is opened.
    """
    from blastvox.diff import DiffError, diff_files
    from blastvox.errors import BlastvoxError
    from blastvox.io.references import ReferencePolicy

    policy = ReferencePolicy(anywhere=references_anywhere)
    try:
        differences = diff_files(a, b, atol=atol, rtol=rtol, limit=limit + 1,
                                 references=policy)
    except BlastvoxError:
        raise
    except Exception as exc:  # a crash must not look like "different" (exit 1) in CI
        message = " ".join(str(exc).split()) or type(exc).__name__
        raise DiffError(f"cannot compare {a} with {b}: {message}") from exc
    if not differences:
        if verbose:
            typer.echo("same")
        return
    for d in differences[:limit]:
        typer.echo(d.format())
    if len(differences) > limit:
        typer.echo(f"blastvox diff: more than {limit} differences; only the first {limit} "
                   f"shown (--limit)", err=True)
    raise typer.Exit(1)
