"""``blastvox info``: summarise a blastvox file."""

from __future__ import annotations

import json
from pathlib import Path

import typer


def info(
    path: Path = typer.Argument(..., help="A VoxelModel .npz file."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object for scripts."),
) -> None:
    """Print counts, bounds, mass, materials and foundations of a VoxelModel.

    With --json the object has at least: voxel_count, link_count, object_count,
    foundation_voxel_count, total_volume_m3, total_mass_kg, bounds_m.
    """
    from blastvox.model import VoxelModel

    summary = VoxelModel.load(path).summary()
    if as_json:
        typer.echo(json.dumps(summary, indent=2, sort_keys=True))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=str(path), show_header=False, title_justify="left")
    for key, value in summary.items():
        if isinstance(value, float):
            value = f"{value:.6g}"
        elif isinstance(value, list) and key == "bounds_m":
            value = " .. ".join("(" + ", ".join(f"{x:.4g}" for x in corner) + ")"
                                for corner in value)
        elif isinstance(value, list):
            value = ", ".join(str(v) for v in value[:12]) + (" ..." if len(value) > 12 else "")
        table.add_row(key, str(value))
    Console().print(table)
