"""``blastvox wedge``: a scene over a grid of parameter values, each variant a shot, on Dask."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import typer

from blastvox.bounds import DEFAULT_MAX_VOXELS, MAX_MEMORY_GIB


def wedge(
    scene: Path = typer.Argument(..., metavar="SCENE", help="Scene TOML (its [wedge] table, "
                                 "if any, gives keys to vary and defaults)."),
    vary: list[str] = typer.Option([], "--vary", metavar="KEY=VALUES",
                                   help="A key of the scene file and its values, repeatable: "
                                        "KEY is a dotted path as written (charges.0.mass_kg, "
                                        "seed, simulation.dt, objects.0.voxel_size, "
                                        "materials.brick.link_yield_mean); VALUES a list "
                                        "(10,50,100) or a range START:STOP:COUNT[:log]."),
    sample: int = typer.Option(None, "--sample", metavar="N", min=1,
                               help="Run a seeded random sample of N shots of the grid."),
    sample_seed: int = typer.Option(None, "--sample-seed", metavar="S", min=0,
                                    help="Seed of --sample [default: the scene's "
                                         "wedge.sample_seed, else 0]."),
    out: Path = typer.Option(None, "-o", "--out", metavar="DIR",
                             help="Directory of the shots, summary.csv/.json and sheet.png "
                                  "[default: wedge.out, else wedge/ beside output.cache]."),
    scheduler: str = typer.Option(None, "--scheduler", metavar="ADDRESS",
                                  help="Run on an existing Dask scheduler (tcp://host:8786) "
                                       "instead of a local cluster."),
    connect_timeout: float = typer.Option(10.0, "--connect-timeout", metavar="S", min=0.1,
                                          max=3600.0, help="Seconds to wait for --scheduler "
                                          "before giving up."),
    workers: int = typer.Option(None, "--workers", metavar="N", min=1, max=1024,
                                help="Worker processes of the local cluster [default: one "
                                     "per CPU, at most one per shot]."),
    preview: bool = typer.Option(None, "--preview/--no-preview",
                                 help="Render each shot's preview strip and the contact "
                                      "sheet [default: wedge.preview, else on]."),
    dry_run: bool = typer.Option(False, "--dry-run", help="List the shots and their keys; "
                                 "run nothing."),
    max_voxels: int = typer.Option(DEFAULT_MAX_VOXELS, "--max-voxels", help="Refuse a shot that "
                                   "would make more voxels than this (`blastvox voxelize "
                                   "--help`)."),
    max_memory: float = typer.Option(MAX_MEMORY_GIB, "--max-memory", metavar="GIB",
                                     help="Refuse a shot whose simulation would need more "
                                     "memory, GiB (`blastvox simulate --help`); a worker "
                                     "needs this much for each shot it runs at once."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="Print nothing but errors."),
) -> None:
    """Run the scene once per combination of --vary values (a wedge), each variant through
    voxelize, simulate, export and a preview, as tasks on Dask.

    Each shot goes to DIR/shots/<key>/, keyed by a hash of everything that makes it
    (the scene with its values, the input files, the blastvox version): a re-run skips
    finished shots, so an interrupted wedge resumes. A failed shot does not stop the
    others; the exit code is 1 if any failed. Writes DIR/summary.csv, summary.json and
    sheet.png (the shots side by side)."""
    from blastvox.bounds import MAX_VOXELS, printable
    from blastvox.cli.console import RichProgress, err_console
    from blastvox.io.outputs import check_output
    from blastvox.wedge.cluster import connect, dashboard_link, local_workers, run_shots
    from blastvox.wedge.plan import plan_wedge
    from blastvox.wedge.report import write_sheet, write_summary

    console = err_console()
    say = (lambda m: None) if quiet else (
        lambda m: console.print(m, markup=False, highlight=False))
    started = time.perf_counter()
    MAX_VOXELS.at(max_voxels, f"{printable(scene)}: --max-voxels")
    plan = plan_wedge(scene, vary, sample=sample, sample_seed=sample_seed, out=out,
                      preview=preview, max_voxels=max_voxels, max_memory_gib=max_memory)
    shots = plan.shots
    if dry_run:
        for spec in shots:
            typer.echo(f"{spec.label()}  -> {spec.directory}")
        return
    sampled = f" (a sample of {plan.grid_size:,})" if len(shots) < plan.grid_size else ""
    with RichProgress(not quiet and sys.stderr.isatty()) as progress, \
            connect(scheduler, local_workers(workers, len(shots)),
                    connect_timeout) as client:
        for name in ("summary.csv", "summary.json", "sheet.png"):
            check_output(plan.out / name, [scene], label=f"--out ({name})", make_dirs=True)
        say(f"wedge: {len(shots)} shots{sampled} of {scene} -> {plan.out}")
        link = dashboard_link(client, remote=bool(scheduler))
        if link:
            say(f"Dask dashboard: {link}")
        progress.start("shots", len(shots))
        labels = {spec.index: spec.label() for spec in shots}

        def done(result: dict) -> None:
            say(_line(result, labels[result["shot"]]))
            progress.advance()

        results = run_shots(client, shots, done)
    csv_path, _ = write_summary(plan.out, plan.axes, plan.grid_size, results)
    sheet = write_sheet(plan.out / "sheet.png", results,
                        [labels[r["shot"]] for r in results]) if plan.preview else None
    failed = [r for r in results if r["status"] == "failed"]
    ran = sum(r["status"] == "ran" for r in results)
    say(f"wedge: {ran} ran, {len(results) - ran - len(failed)} up to date, {len(failed)} "
        f"failed in {time.perf_counter() - started:.1f} s; {csv_path}"
        + (f", {sheet}" if sheet else ""))
    if failed:
        raise typer.Exit(1)


def _line(result: dict, label: str) -> str:
    """One shot's line: its values, status, time and what it made."""
    if result["status"] == "failed":
        return f"{label}: failed: {result['error']}"
    stats = result.get("stats") or {}
    return (f"{label}: {result['status']} ({result.get('total_s', 0):.1f} s): "
            f"{stats.get('pieces', '?')} pieces, {stats.get('broken_links', '?')} broken "
            f"links, {100 * stats.get('moved_fraction', 0):.1f} % of the mass moved")
