"""``blastvox info``: summarise a blastvox file (VoxelModel or SimCache)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import typer


def info(
    file: Path = typer.Argument(..., metavar="FILE", help="A VoxelModel .npz (from `blastvox "
                                "voxelize`) or a SimCache .npz (from `blastvox simulate`)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object for scripts."),
) -> None:
    """Print a summary of a VoxelModel or a SimCache; the file's own schema says which.

    VoxelModel: counts, bounds, mass, materials and foundations; with --json the
    object has "kind": "VoxelModel" and at least voxel_count, link_count,
    object_count, foundation_voxel_count, total_volume_m3, total_mass_kg, bounds_m.

    SimCache: frames, step, pieces, broken links, voxels turned to dust and
    charges; with --json the object has "kind": "SimCache" and at least
    frame_count, fps, dt_s, duration_s, piece_count, moving_piece_count,
    voxel_count, broken_link_count, destroyed_voxel_count, charge_count, the rooms
    (closed_room_count: confined charges' rooms; leaky_room_count and
    leaky_room_volume_m3: rooms the waves enter through openings), and the
    momentum ledger (momentum_<term>_n_s, [x, y, z] N s: the pieces' momentum at the
    end and where it came from: blast, released, gravity_drag, ground, foundations,
    damping, sleep, initial; docs/file-formats.md).
    """
    summary = load_summary(file)
    if as_json:
        typer.echo(json.dumps(summary, indent=2, sort_keys=True))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=str(file), show_header=False, title_justify="left")
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


def load_summary(path: Path) -> dict[str, Any]:
    """Load ``path`` as whichever contract its meta names and return its summary.

    Raises :class:`~blastvox.errors.ContractError` (one line, naming ``path``) for a
    missing, truncated, foreign, pickled or newer-version file.
    """
    from blastvox import cache, model
    from blastvox.errors import ContractError

    if not path.is_file():
        from blastvox.io.outputs import not_a_file

        raise ContractError(not_a_file(path))
    from blastvox.io.npz import read_contract

    versions = {model.SCHEMA: model.SCHEMA_VERSION, cache.SCHEMA: cache.SCHEMA_VERSION}
    meta, _ = read_contract(path, versions, "VoxelModel or SimCache", members=())
    loader = cache.SimCache if meta["schema"] == cache.SCHEMA else model.VoxelModel
    return loader.load(path).summary()
