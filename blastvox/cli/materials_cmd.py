"""``blastvox materials``: show the material library."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import typer


def materials(
    materials_file: Path = typer.Option(None, "--materials", help="TOML file extending or "
                                        "overriding the built-in materials."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
) -> None:
    """List materials with density (kg/m^3), yields (Pa), restitution and combustibility."""
    from blastvox.materials import MaterialLibrary

    library = MaterialLibrary.load(materials_file)
    if as_json:
        def finite(value):  # JSON has no Infinity: unbounded limits are the string "inf"
            return "inf" if value == float("inf") else value

        table = {n: {k: finite(v) for k, v in asdict(library[n]).items()}
                 for n in library.names()}
        typer.echo(json.dumps(table, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table("name", "density kg/m³", "link yield Pa", "voxel yield Pa",
                  "foundation Pa", "restitution", "ignites at Pa")
    for name in library.names():
        m = library[name]
        table.add_row(name, f"{m.density:g}", f"{m.link_yield_mean:g} ± {m.link_yield_var:g}",
                      f"{m.voxel_yield_mean:g} ± {m.voxel_yield_var:g}", f"{m.foundation_yield:g}",
                      f"{m.restitution:g}", f"{m.combustibility:g}")
    Console().print(table)
