"""Plots with matplotlib's Agg canvas (headless, no pyplot state): shared helpers and
the blast calculator's curves.

Helpers any part of blastvox (or a benchmark) can reuse:

* :func:`check_plot_path` refuses an output whose suffix matplotlib is not asked
  to write here (``.png``, ``.svg``, ``.pdf``) with a one-line BlastvoxError;
* :func:`new_figure` makes a Figure on an Agg canvas, styled alike;
* :func:`save_figure` writes it atomically and reproducibly (no timestamps or
  version stamps: the same figure gives the same bytes);
* :func:`line_plot` is a one-call, one-panel chart of named series (log axes
  optional), e.g. a trade-off curve of error against run time.

:func:`blast_figure` draws, for a charge and the requested distances, the
pressure-time curves a face sees (modified Friedlander positive phase, then
Granström's cubic negative phase, as the simulator loads faces) and the peak
overpressure and impulses against distance (log-log), straight from
:mod:`blastvox.blast`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from blastvox.errors import BlastvoxError
from blastvox.io.atomic import atomic_path

PLOT_SUFFIXES = (".png", ".svg", ".pdf")
DPI = 100
#: Pressure-time curves drawn at most (each costs ~0.1 s and a legend line); with more
#: distances, this many spread over them are drawn and the panel's title says so.
MAX_CURVES = 12


@dataclass(frozen=True)
class Series:
    """One line of a :func:`line_plot`: x (N,), y (N,), legend label; style: a
    matplotlib format string ("o-", "--", ...)."""

    x: Sequence[float] | np.ndarray
    y: Sequence[float] | np.ndarray
    label: str
    style: str = "-"


def check_plot_path(path: str | Path, option: str = "--plot") -> str:
    """The plot's suffix (lower case) if matplotlib writes it here, else BlastvoxError."""
    suffix = Path(path).suffix.lower()
    if suffix not in PLOT_SUFFIXES:
        raise BlastvoxError(f"{option} {path}: unknown plot format {suffix or '(no suffix)'!r};"
                            f" use {', '.join(PLOT_SUFFIXES)}")
    return suffix


def new_figure(width_in: float = 10.0, height_in: float = 6.0, dpi: int = DPI) -> Any:
    """A matplotlib Figure on an Agg canvas (no display, no pyplot), ``width_in`` x
    ``height_in`` inches at ``dpi``, with a grid on every axes it gets."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def style_axes(ax: Any, xlabel: str, ylabel: str, title: str | None = None) -> None:
    """Labels, title, a light grid and a legend if anything is labelled."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize="medium")
    ax.grid(True, which="major", alpha=0.35)  # (minor grids cost seconds on log axes)
    if any(not h.get_label().startswith("_") for h in ax.get_lines()):
        ax.legend(fontsize="small")


def save_figure(fig: Any, path: str | Path) -> None:
    """Write ``fig`` to ``path`` (.png, .svg or .pdf) atomically, with no date or
    software stamps, so that the same figure gives the same bytes."""
    suffix = check_plot_path(path, "plot")
    metadata = {".png": {"Software": None}, ".svg": {"Date": None, "Creator": None},
                ".pdf": {"CreationDate": None, "Creator": None, "Producer": None}}[suffix]
    import matplotlib

    with matplotlib.rc_context({"svg.hashsalt": "blastvox"}), atomic_path(path) as tmp:
        fig.savefig(tmp, format=suffix[1:], metadata=metadata)


def line_plot(path: str | Path, series: Sequence[Series], xlabel: str, ylabel: str,
              title: str | None = None, logx: bool = False, logy: bool = False,
              size_in: tuple[float, float] = (8.0, 5.0)) -> None:
    """One panel of named ``series``, written to ``path`` (see :func:`save_figure`)."""
    check_plot_path(path, "plot")
    fig = new_figure(*size_in)
    ax = fig.add_subplot()
    for s in series:
        ax.plot(np.asarray(s.x, dtype=float), np.asarray(s.y, dtype=float), s.style,
                label=s.label)
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    style_axes(ax, xlabel, ylabel, title)
    save_figure(fig, path)


# -- the blast calculator's figure ----------------------------------------------------------



def pressure_time(distance_m: float, charge_kg: float, explosive: str = "TNT",
                  samples: int = 1200, burst: str = "air") -> tuple[np.ndarray, np.ndarray]:
    """(t (N,) s after detonation, p - p0 (N,) Pa) at ``distance_m`` of an "air" or
    "surface" burst, as the simulator loads a face: the modified Friedlander positive
    phase, then Granström's cubic negative phase (:mod:`blastvox.blast.underpressure`),
    from just before arrival to after the negative phase ends, the jump at arrival
    included."""
    import blastvox.blast as blast

    p = blast.blast_parameters(distance_m, charge_kg, explosive, burst)
    ta, td = float(p.arrival_time_s), float(p.positive_duration_s)
    z = distance_m / float(np.cbrt(charge_kg * blast.tnt_equivalent(explosive)))
    p_min, _, td_neg = (float(v) for v in blast.negative_parameters(z, p.impulse_pa_s))
    end = ta + td + td_neg
    lead = 0.1 * (end - ta)
    t = np.concatenate([[max(0.0, ta - lead)], [ta], np.linspace(ta, end + lead, samples)])
    s = (t - ta - td) / td_neg if td_neg > 0.0 else np.full_like(t, 2.0)
    under = np.where((s > 0.0) & (s < 1.0), -p_min * 6.75 * s * (1.0 - s) ** 2, 0.0)
    pressure = np.where(t <= ta + td, p.overpressure(t), under)
    pressure[:2] = 0.0  # before arrival; the jump to Ps is at t = ta
    return t, pressure


def curve_distances(distances: Sequence[float], most: int = MAX_CURVES) -> list[float]:
    """The distinct ``distances`` in order, or, when there are more than ``most``, ``most``
    of them spread evenly over the sorted list (the nearest and the farthest included)."""
    unique = sorted(set(float(r) for r in distances))
    if len(unique) <= most:
        return [float(r) for r in dict.fromkeys(float(r) for r in distances)]
    picks = np.unique(np.round(np.linspace(0, len(unique) - 1, most)).astype(int))
    return [unique[i] for i in picks]


def blast_figure(charge_kg: float, explosive: str, distances: Sequence[float],
                 burst: str = "air") -> Any:
    """Pressure-time curves at ``distances`` (m; at most :data:`MAX_CURVES`, see
    :func:`curve_distances`), and Ps, Pr and the incident, reflected and negative-phase
    impulses against distance (every distance marked), for an "air" or "surface" burst."""
    import blastvox.blast as blast

    factor = blast.tnt_equivalent(explosive)
    cube = float(np.cbrt(charge_kg * factor))
    z_min = blast.Z_MIN_SURFACE if burst == "surface" else blast.Z_MIN
    fig = new_figure(11.0, 8.0)
    grid = fig.add_gridspec(2, 2, height_ratios=(1.15, 1.0))
    ax_pt = fig.add_subplot(grid[0, :])
    peaks = []
    drawn = curve_distances(distances)
    given_count = len(set(float(r) for r in distances))
    for r in drawn:
        t, pressure = pressure_time(r, charge_kg, explosive, burst=burst)
        peaks.append(float(np.max(np.abs(pressure))))
        ax_pt.plot(t * 1e3, pressure / 1e3, label=f"R = {r:g} m")
    ax_pt.axhline(0.0, color="0.3", linewidth=0.8)
    positive = [p for p in peaks if p > 0]
    if positive and max(positive) / min(positive) > 30.0:  # several decades: symmetric log
        ax_pt.set_yscale("symlog", linthresh=min(positive) / 1e3 / 10.0)
    fig.suptitle(f"{charge_kg:g} kg {explosive} = {charge_kg * factor:.4g} kg TNT, "
                 f"{blast.BURST_TITLES[burst]} (Kingery-Bulmash, modified Friedlander, "
                 f"Granström negative phase)",
                 fontsize="medium")
    which = ("each distance" if len(drawn) == given_count else
             f"{len(drawn)} of the {given_count:,} distances, spread over them")
    style_axes(ax_pt, "time after detonation (ms)", "overpressure p - p0 (kPa)",
               f"incident pressure at {which}, negative phase included")

    given = np.unique(np.array([r for r in distances if r > 0], dtype=float))
    # from a third of the nearest distance, but not below a tenth of the fits' reach (a
    # distance deep in the charge, 1e-300 m, would span hundreds of decades)
    lo = max((given.min() if len(given) else z_min * cube) / 3.0, z_min * cube / 10.0)
    hi = max((given.max() if len(given) else blast.Z_MAX * cube) * 3.0, 10.0 * lo)
    r = np.geomspace(lo, hi, 400)
    p = blast.blast_parameters(r, charge_kg, explosive, burst)
    _, negative, _ = blast.negative_parameters(r / cube, p.impulse_pa_s)
    ax_ps = fig.add_subplot(grid[1, 0])
    ax_i = fig.add_subplot(grid[1, 1])
    ax_ps.loglog(r, p.peak_overpressure_pa / 1e3, label="incident Ps")
    ax_ps.loglog(r, p.reflected_overpressure_pa / 1e3, label="normally reflected Pr")
    ax_i.loglog(r, p.impulse_pa_s, label="incident positive impulse")
    ax_i.loglog(r, p.reflected_impulse_pa_s, label="normally reflected impulse Ir")
    ax_i.loglog(r, np.where(negative > 0, negative, np.nan), "--",
                label="negative-phase impulse (magnitude)")
    if len(given):
        at = blast.blast_parameters(given, charge_kg, explosive, burst)
        ax_ps.loglog(given, at.peak_overpressure_pa / 1e3, "o", color="C3",
                     label="requested distances")
        ax_ps.loglog(given, at.reflected_overpressure_pa / 1e3, "o", color="C3")
        ax_i.loglog(given, at.impulse_pa_s, "o", color="C3", label="requested distances")
        ax_i.loglog(given, at.reflected_impulse_pa_s, "o", color="C3")
    for ax in (ax_ps, ax_i):  # where the Kingery-Bulmash fits do not reach
        ax.axvspan(lo, max(lo, z_min * cube), color="0.85", zorder=0)
        ax.axvspan(min(hi, blast.Z_MAX * cube), hi, color="0.85", zorder=0)
        ax.set_xlim(lo, hi)
    style_axes(ax_ps, "distance R (m)", "overpressure (kPa)", "peak overpressure "
               "(grey: outside the fits)")
    style_axes(ax_i, "distance R (m)", "impulse (Pa s)", "positive impulse")
    return fig


def write_blast_plot(path: str | Path, charge_kg: float, explosive: str,
                     distances: Sequence[float], burst: str = "air") -> None:
    """:func:`blast_figure` written to ``path`` (.png, .svg or .pdf), atomically."""
    check_plot_path(path)
    save_figure(blast_figure(charge_kg, explosive, distances, burst), path)
