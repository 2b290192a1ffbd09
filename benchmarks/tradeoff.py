"""Speed/accuracy trade: voxel size x time step x fracture model against the finest run.

    python benchmarks/tradeoff.py                 # 4 voxel sizes x 4 dt x 2 models (minutes)
    python benchmarks/tradeoff.py --quick         # 2 sizes x 2 dt x 2 models (smoke check)
    python benchmarks/tradeoff.py --markdown out/tradeoff.md --plot out/tradeoff.png

The reference scene: a reinforced-concrete wall, 3.0 m wide, 0.3 m thick and
2.4 m high, standing on the ground (Z up, its bottom layer founded), with
50 g of TNT 0.2 m in front of its centre at 1.2 m height; gravity, ground and
collisions on, every other setting at its ``SimSettings`` default; 1 s of shot
at 20 fps (so that every dt divides the frame interval exactly). The wall is
voxelized at 0.1, 0.075, 0.06 and 0.05 m (2,160 to 17,280 voxels; every size
divides every edge) and simulated at dt = 1/60, 1/240, 1/1000 and 1/4000 s with
``fracture = "yield"`` and ``"damage"``.

Everything runs in this process through the real API
(``blastvox.voxelize.pipeline.voxelize`` then ``blastvox.simulate.engine.simulate``),
after one warm-up run per fracture model (imports and numba compilation, or
loading numba's cache, are not timed). ``wall s`` is ``simulate()`` alone.

Each run is compared with the finest run of its fracture model (finest voxel
size and smallest dt) by ``blastvox.analysis.tradeoff``: momentum (relative
error of the horizontal momentum of all pieces and dust at the first frame,
t = 0.05 s), centre-of-mass trajectories of the 5 largest pieces matched by mass
rank (RMS over the 21 frames, divided by the wall's bounding-box diagonal),
the mass-weighted Wasserstein distance between log10 piece masses (decades),
and the absolute difference of the broken-link fractions; ``combined`` is the
mean of the last three (momentum is not converged in dt even at 1/4000 s, so
the finest run is no reference for it; see the README). ``Pareto``: no run of
the same fracture model is both faster and more accurate (combined).
``warned``: ``simulate()`` issued a warning (a dt too large for the voxel size
and the fragments' speeds, say).

Prints the machine line (with the load average before and after the sweep) and
markdown tables; writes a PNG of wall time against error (``--plot``) and the
same markdown to a file (``--markdown``). Timings on a shared machine are noisy.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from _machine import machine, revision  # benchmarks/ is on sys.path when run as a script

from blastvox.analysis.tradeoff import (
    METRICS,
    RunErrors,
    RunSummary,
    compare,
    pareto_front,
    summarize_cache,
)

ROOT = Path(__file__).resolve().parent.parent
WALL = (3.0, 0.3, 2.4)  # m, width (x), thickness (y), height (z, up)
MATERIAL = "reinforced_concrete"
CHARGE_KG = 0.05  # TNT
STANDOFF = 0.2  # m, from the wall's front face
CHARGE_HEIGHT = 1.2  # m
FPS = 20.0  # divides 1/dt for every dt below
DURATION = 1.0  # s
K_LARGEST = 5
SIZES = (0.1, 0.075, 0.06, 0.05)  # m, coarse to fine
STEPS = (60, 240, 1000, 4000)  # dt = 1 / steps, s
QUICK_SIZES = (0.1, 0.075)
QUICK_STEPS = (60, 240)
FRACTURES = ("yield", "damage")
SCALE = float(np.linalg.norm(WALL))  # m, normalises the COM error


@dataclass
class Run:
    """One simulated configuration and what it measured."""

    fracture: str
    size: float  # m
    voxels: int
    steps_per_s: int  # 1 / dt
    seconds: float  # wall s of simulate(), best of --repeat
    pieces: int
    dust: int
    summary: RunSummary
    warned: bool = False  # simulate() warned (e.g. dt too large for the voxel size)
    errors: RunErrors | None = None
    pareto: bool = False
    reference: bool = False


# --------------------------------------------------------------------------- scene


def wall_mesh(directory: Path) -> Path:
    """Write the wall as an STL standing on z = 0, centred on x = y = 0."""
    import trimesh

    path = directory / "wall.stl"
    box = trimesh.creation.box(extents=WALL)
    box.apply_translation((0.0, 0.0, WALL[2] / 2))
    box.export(path)
    return path


def make_model(mesh: Path, size: float):
    """Voxelize the wall at ``size`` m (ground auto, Z up, seed 0)."""
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    return voxelize([ObjectRequest(mesh=mesh, voxel_size=(size,) * 3, material=MATERIAL)],
                    VoxelizeSettings(up_axis="Z"))


def settings_for(fracture: str, steps_per_s: int):
    """The shot's SimSettings at dt = 1/steps_per_s s."""
    from blastvox.simulate.settings import ChargeSpec, SimSettings

    charge = ChargeSpec((0.0, -(WALL[1] / 2 + STANDOFF), CHARGE_HEIGHT), CHARGE_KG)
    return SimSettings(dt=1.0 / steps_per_s, fps=FPS, duration=DURATION, fracture=fracture,
                       charges=(charge,))


# --------------------------------------------------------------------------- sweep


def sweep(sizes: tuple[float, ...], steps: tuple[int, ...], repeat: int) -> list[Run]:
    """Voxelize, warm up, then simulate every configuration; errors filled in."""
    from blastvox.simulate.engine import simulate

    runs: list[Run] = []
    with tempfile.TemporaryDirectory(prefix="blastvox-tradeoff-") as tmp:
        mesh = wall_mesh(Path(tmp))
        models = {}
        for size in sizes:
            started = time.perf_counter()
            models[size] = make_model(mesh, size)
            log(f"voxelized at {size:g} m: {models[size].voxel_count:,} voxels in "
                f"{time.perf_counter() - started:.2f} s")
    coarse = models[max(sizes)]
    for fracture in FRACTURES:  # warm-up: compile or load the numba kernels
        simulate(coarse, replace(settings_for(fracture, 240), duration=0.2))
    for fracture in FRACTURES:
        for size in sizes:
            model = models[size]
            for per_s in steps:
                settings = settings_for(fracture, per_s)
                best = float("inf")
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    for _ in range(repeat):
                        started = time.perf_counter()
                        cache = simulate(model, settings)
                        best = min(best, time.perf_counter() - started)
                if abs(cache.meta["dt"] * per_s - 1.0) > 1e-9:
                    raise RuntimeError(f"dt 1/{per_s} was changed to {cache.meta['dt']:g} s")
                dust = int(np.count_nonzero(cache.piece_end_frame < cache.frame_count))
                runs.append(Run(fracture, size, model.voxel_count, per_s, best,
                                cache.piece_count - dust, dust,
                                summarize_cache(cache, K_LARGEST), bool(caught)))
                log(f"{fracture} {size:g} m 1/{per_s} s: {best:.2f} s"
                    + "".join(f"; warning: {w.message}" for w in caught[:1]))
                del cache
    score(runs)
    return runs


def score(runs: list[Run]) -> None:
    """Errors against each fracture model's finest run, and its Pareto front."""
    for fracture in FRACTURES:
        group = [r for r in runs if r.fracture == fracture]
        ref = min(group, key=lambda r: (r.size, -r.steps_per_s))
        ref.reference = True
        for run in group:
            run.errors = compare(run.summary, ref.summary, SCALE)
        front = pareto_front(np.array([r.seconds for r in group]),
                             np.array([r.errors.combined for r in group]))
        for run, on in zip(group, front, strict=True):
            run.pareto = bool(on)


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- report


def load() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"


def tables(runs: list[Run]) -> list[str]:
    """The results table, then the reference runs' own values."""
    heads = " | ".join(h for _, h in METRICS)
    lines = [f"| fracture | voxel m | voxels | dt s | warned | wall s | pieces | dust | {heads} | "
             "combined | Pareto |",
             "|---|--:|--:|--:|:-:|--:|--:|--:|--:|--:|--:|--:|--:|:-:|"]
    for r in runs:
        e = r.errors
        if r.reference:
            errors = " | ".join("ref" for _ in METRICS) + " | ref"
        else:
            errors = " | ".join(f"{getattr(e, key):.3g}" for key, _ in METRICS)
            errors += f" | {e.combined:.3g}"
        lines.append(f"| {r.fracture} | {r.size:g} | {r.voxels:,} | 1/{r.steps_per_s} | "
                     f"{'⚠' if r.warned else ''} | {r.seconds:.2f} | {r.pieces:,} | {r.dust:,} | "
                     f"{errors} | "
                     f"{'✓' if r.pareto else ''} |")
    lines += ["", f"| reference run | horizontal \\|p\\| at {1 / FPS:g} s, kg m/s | "
              f"broken-link fraction | {K_LARGEST} largest pieces, kg |", "|---|--:|--:|---|"]
    for r in runs:
        if r.reference:
            s = r.summary
            lines.append(f"| {r.fracture}, {r.size:g} m, 1/{r.steps_per_s} s | "
                         f"{np.linalg.norm(s.momentum):.3g} | {s.broken_fraction:.3f} | "
                         f"{', '.join(f'{m:.1f}' for m in largest(s.piece_mass))} |")
    return lines


def largest(masses: np.ndarray) -> np.ndarray:
    return np.sort(masses)[::-1][:K_LARGEST]


def plot(runs: list[Run], path: Path) -> None:
    """Wall time (log x) against combined and per-metric errors (log y), Pareto fronts."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    sizes = sorted({r.size for r in runs})
    colours = {s: plt.get_cmap("viridis")(i / max(1, len(sizes) - 1))
               for i, s in enumerate(sizes)}
    markers = {"yield": "o", "damage": "s"}
    fig = plt.figure(figsize=(12, 6), layout="constrained")
    grid = fig.add_gridspec(2, 4)
    panels = [("combined", "combined error (mean of COM, mass W1, broken-link Δ)",
               fig.add_subplot(grid[:, :2]))]
    for i, (key, head) in enumerate(METRICS):
        panels.append((key, head, fig.add_subplot(grid[i // 2, 2 + i % 2])))
    for key, head, ax in panels:
        values = [getattr(r.errors, key) for r in runs if not r.reference]
        positive = [v for v in values if v > 0]
        floor = min(positive) / 3 if positive else 1e-6
        for r in runs:
            value = getattr(r.errors, key)
            ref_like = r.reference or value <= 0
            ax.scatter(r.seconds, floor if ref_like else value, marker=markers[r.fracture],
                       s=36, facecolors="none" if ref_like else colours[r.size],
                       edgecolors=colours[r.size], linewidths=1.2, zorder=3)
        if key == "combined":
            for fracture in FRACTURES:
                front = sorted((r for r in runs if r.fracture == fracture and r.pareto
                                and not r.reference), key=lambda r: r.seconds)
                if front:
                    ax.step([r.seconds for r in front], [r.errors.combined for r in front],
                            where="post", color="black",
                            linestyle="-" if fracture == "yield" else "--", linewidth=1,
                            zorder=2)
                    ax.scatter([r.seconds for r in front], [r.errors.combined for r in front],
                               s=120, facecolors="none", edgecolors="black", linewidths=0.8,
                               zorder=4)
            ax.text(0.01, 0.01, "hollow markers at the bottom: the reference runs (error 0)",
                    transform=ax.transAxes, fontsize=8, va="bottom")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(head, fontsize=10)
        ax.set_xlabel("wall s (simulate)", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=8)
    handles = [Line2D([], [], marker=markers[f], linestyle="", color="grey",
                      label=f"fracture = {f}") for f in FRACTURES]
    handles += [Line2D([], [], marker="o", linestyle="", color=colours[s],
                       label=f"voxel {s:g} m") for s in sizes]
    handles += [Line2D([], [], color="black", linestyle="-" if f == "yield" else "--",
                       marker="o", markerfacecolor="none", label=f"Pareto front, {f}")
                for f in FRACTURES]
    panels[0][2].legend(handles=handles, fontsize=8, loc="lower right",
                        bbox_to_anchor=(1.0, 0.07))
    panels[0][2].set_ylabel("error against the finest run")
    fig.suptitle(f"Wall {WALL[0]:g} x {WALL[1]:g} x {WALL[2]:g} m {MATERIAL}, "
                 f"{CHARGE_KG * 1000:g} g TNT at {STANDOFF:g} m, {DURATION:g} s of shot; "
                 "dt = 1/60 ... 1/4000 s within each colour", fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="2 voxel sizes x 2 time steps (a smoke check, seconds)")
    parser.add_argument("--plot", type=Path, default=ROOT / "out" / "tradeoff.png",
                        help="PNG of wall time against error (default: out/tradeoff.png)")
    parser.add_argument("--markdown", type=Path, help="also write the report to this file")
    parser.add_argument("--repeat", type=int, default=1,
                        help="timed runs per configuration, the best counts (default 1)")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    sizes, steps = (QUICK_SIZES, QUICK_STEPS) if args.quick else (SIZES, STEPS)

    header = f"{machine(('blastvox', 'numpy', 'numba'))}; {revision()}"
    print(header, flush=True)
    started = time.perf_counter()
    runs = sweep(sizes, steps, args.repeat)
    total = time.perf_counter() - started
    command = "python benchmarks/tradeoff.py" + (" --quick" if args.quick else "")
    report = [header, f"Load average after the sweep: {load()} (1, 5, 15 min); the sweep took "
              f"{total:.0f} s.", "",
              f"`{command}`: wall {WALL[0]:g} x {WALL[1]:g} x {WALL[2]:g} m {MATERIAL} on the "
              f"ground, {CHARGE_KG * 1000:g} g TNT {STANDOFF:g} m in front at "
              f"{CHARGE_HEIGHT:g} m; gravity, ground and collisions on; {DURATION:g} s at "
              f"{FPS:g} fps. In-process, after a warm-up run per fracture model (no numba "
              f"compilation timed); wall s = simulate() only"
              f"{f', best of {args.repeat}' if args.repeat > 1 else ', one run each'}. "
              "Errors against the finest run of the same fracture model.", ""]
    report += tables(runs)
    print("\n".join(report[1:]))
    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text("\n".join(report) + "\n", encoding="utf-8")
    plot(runs, args.plot)
    print(f"\nplot: {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
