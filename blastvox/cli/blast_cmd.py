"""``blastvox blast``: the artist's blast-wave calculator."""

from __future__ import annotations

import json
import math
from enum import StrEnum
from pathlib import Path

import typer


class Burst(StrEnum):
    """Where the charge is: in free air (spherical) or on the ground (hemispherical)."""

    air = "air"
    surface = "surface"




def _number(text: str, what: str) -> float:
    try:
        value = float(text.strip())
    except ValueError:
        from blastvox.errors import BlastvoxError

        shown = text.strip() if len(text.strip()) <= 40 else text.strip()[:40] + "..."
        raise BlastvoxError(f"{what}: {shown!r} is not a number") from None
    if not math.isfinite(value):
        from blastvox.errors import BlastvoxError

        raise BlastvoxError(f"{what}: {text.strip()!r} is not a finite number")
    return value


def parse_charge(text: str | None) -> float:
    """The --charge value in kg, within :data:`blastvox.bounds.CHARGE_KG` (1 µg to 1 Mt)."""
    from blastvox.bounds import CHARGE_KG

    if text is None:  # a usage error (exit 2), as any missing required option
        raise typer.BadParameter("is required (mass of explosive in kg)",
                                 param_hint="'--charge'")
    return CHARGE_KG.named(_number(text, "--charge"), "--charge")


def parse_distances(text: str | None) -> list[float]:
    """The --distance list in m: at most :data:`~blastvox.bounds.MAX_DISTANCES`
    comma-separated numbers within :data:`~blastvox.bounds.DISTANCE_M` (0 to 1000 km)."""
    from blastvox.bounds import DISTANCE_M, MAX_DISTANCES
    from blastvox.errors import BlastvoxError

    if text is None:
        raise typer.BadParameter("is required (distances in m)", param_hint="'--distance'")
    parts = text.split(",")
    if not any(p.strip() for p in parts):
        raise BlastvoxError("--distance: no distances given")
    if len(parts) > MAX_DISTANCES:
        raise BlastvoxError(f"--distance: {len(parts):,} distances, over the limit of "
                            f"{MAX_DISTANCES:,} a call (make several calls, or use "
                            f"blastvox.blast.blast_parameters from Python)")
    values = []
    for part in parts:
        if not part.strip():
            raise BlastvoxError(f"--distance: empty entry in {text[:80]!r}")
        values.append(DISTANCE_M.named(_number(part, "--distance"), "--distance"))
    return values


def blast(
    charge: str = typer.Option(None, "--charge", metavar="KG",
                               help="Mass of explosive in kg, 1e-9 to 1e9 (required)."),
    explosive: str = typer.Option("TNT", "--explosive", metavar="NAME",
                                  help="Explosive, converted to a TNT-equivalent mass "
                                       "(e.g. TNT, C4, PETN, RDX, ANFO, Semtex)."),
    distance: str = typer.Option(None, "--distance", metavar="R[,R,...]",
                                 help="Distance(s) from the charge centre in m, 0 to 1e6, "
                                      "comma-separated, at most 1,000 (required)."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON list, one object per "
                                 "distance, in SI units."),
    plot: Path = typer.Option(None, "--plot", metavar="OUT.png",
                              help="Also plot the pressure-time curves at the distances "
                                   "(at most 12, spread over them; negative phase "
                                   "included) and peak overpressure and "
                                   "impulse, incident and reflected, against distance "
                                   "(.png, .svg or .pdf)."),
    burst: Burst = typer.Option(Burst.air, "--burst", case_sensitive=False,
                                help="air: spherical charge in free air; surface: "
                                     "hemispherical charge on the ground."),
) -> None:
    """Blast wave of a charge in free air or on the ground at the given distances.

    Kingery-Bulmash fits (ConWep, UFC 3-340-02), Hopkinson-Cranz scaled.
    JSON keys: distance_m, scaled_distance (m/kg^(1/3), TNT-equivalent), peak_overpressure_pa,
    arrival_time_s, positive_duration_s, decay_coefficient (Friedlander b), impulse_pa_s,
    reflected_overpressure_pa and reflected_impulse_pa_s (normal reflection off a rigid
    surface facing the charge).
    """
    from blastvox.blast import (
        BURST_TITLES,
        Z_MAX,
        Z_MIN,
        Z_MIN_SURFACE,
        blast_parameters,
        tnt_equivalent,
    )

    mass = parse_charge(charge)
    distances = parse_distances(distance)
    if plot is not None:
        from blastvox.preview.plots import check_plot_path

        check_plot_path(plot)
        from blastvox.io.outputs import check_output

        check_output(plot, label="--plot")
    factor = tnt_equivalent(explosive)
    burst_name = Burst(burst).value
    z_min = Z_MIN_SURFACE if burst_name == "surface" else Z_MIN
    params = blast_parameters(distances, mass, explosive, burst_name)
    records = params.records()
    if plot is not None:
        from blastvox.preview.plots import write_blast_plot

        write_blast_plot(plot, mass, explosive, distances, burst_name)
    if as_json:
        typer.echo(json.dumps(records, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    title = (f"{mass:g} kg {explosive} = {mass * factor:.4g} kg TNT (factor {factor:g}); "
             f"{BURST_TITLES[burst_name]}")
    caption = ("Z scaled distance m/kg^(1/3); Ps peak incident overpressure; ta arrival; "
               "Td positive duration; b Friedlander decay; I positive impulse; Pr, Ir "
               "normally reflected overpressure and impulse")
    table = Table(title=title, caption=caption, title_justify="left", caption_justify="left")
    headers = ("R m", "Z", "Ps kPa", "ta ms", "Td ms", "b", "I Pa s", "Pr kPa", "Ir Pa s",
               "note")
    rows = []
    for row in records:
        z = row["scaled_distance"]
        note = "in charge" if z < z_min else "far field" if z > Z_MAX else ""
        rows.append((f"{row['distance_m']:g}", f"{z:.4g}",
                     f"{row['peak_overpressure_pa'] / 1e3:.4g}",
                     f"{row['arrival_time_s'] * 1e3:.4g}",
                     f"{row['positive_duration_s'] * 1e3:.4g}",
                     f"{row['decay_coefficient']:.4g}", f"{row['impulse_pa_s']:.4g}",
                     f"{row['reflected_overpressure_pa'] / 1e3:.4g}",
                     f"{row['reflected_impulse_pa_s']:.4g}", note))
    widths = [max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(headers)]
    for header, width in zip(headers, widths, strict=True):
        table.add_column(header, justify="left" if header == "note" else "right", no_wrap=True,
                         min_width=width)
    for r in rows:
        table.add_row(*r)
    # never a number cut to fit a narrow terminal or an 80-column pipe: wider lines wrap
    Console(width=max(Console().width, sum(widths) + 3 * len(widths) + 1)).print(table)
    if any(r["scaled_distance"] < z_min or r["scaled_distance"] > Z_MAX for r in records):
        Console(stderr=True, highlight=False).print(
            f"note: data cover Z {z_min:g}-{Z_MAX:g} m/kg^(1/3); in charge = held at the "
            "charge surface, far field = acoustic 1/R decay")
