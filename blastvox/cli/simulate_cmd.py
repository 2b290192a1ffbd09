"""``blastvox simulate``: VoxelModel + scene -> SimCache."""

from __future__ import annotations

import time
from enum import StrEnum
from pathlib import Path

import typer

from blastvox.bounds import (
    CHARGE_KG,
    CHARGE_TIME_S,
    COORDINATE,
    MAX_FRAMES,
    MAX_MEMORY_GIB,
    MAX_PARTICLES,
    MAX_STEPS,
)
from blastvox.cli.interrupt import check_interrupt
from blastvox.errors import BlastvoxError


class ChargeBurst(StrEnum):
    """--burst choices."""

    auto = "auto"
    air = "air"
    surface = "surface"


def _parse_charge(text: str) -> tuple[tuple[float, float, float], float, float]:
    """'X,Y,Z:KG[@T]' -> (position m, mass kg, time s), each within its bound
    (:mod:`blastvox.bounds`)."""
    try:
        where, rest = text.split(":", 1)
        mass, at, when = rest.partition("@")
        x, y, z = (float(v) for v in where.split(","))
        kg = float(mass)
        t = float(when) if at else 0.0  # "KG@" with no time is refused, not read as 0
    except ValueError:
        raise BlastvoxError(f"--charge {text!r}: expected X,Y,Z:KG or X,Y,Z:KG@T "
                            f"(metres, kg TNT, seconds)") from None
    flag = f"--charge {text!r}:"
    CHARGE_KG.named(kg, f"{flag} mass")
    CHARGE_TIME_S.named(t, f"{flag} time")
    for axis, value in zip("XYZ", (x, y, z), strict=True):
        COORDINATE.named(value, f"{flag} {axis}")
    return (x, y, z), kg, t


def scene_model_mismatch(spec, model_meta: dict, scene: Path, model_path: Path) -> list[str]:
    """Warnings for a scene whose explicit up_axis or ground height differs from the
    model's: the simulation follows the model, so the scene's charges may be placed in
    another frame than its author meant."""
    lines = []
    model_up, model_ground = model_meta.get("up_axis"), model_meta.get("ground_height")
    if "up_axis" in spec.model_fields_set and spec.up_axis != model_up:
        lines.append(f"{scene}: up_axis is {spec.up_axis} but {model_path} was voxelized "
                     f"{model_up}-up: the simulation follows the model, and reads the "
                     f"scene's charge positions in its frame")
    ground = spec.ground
    if (isinstance(ground, float) and model_ground is not None
            and abs(ground - float(model_ground)) > 1e-9 * max(1.0, abs(ground))):
        lines.append(f"{scene}: ground is {ground:g} m but {model_path} was voxelized with "
                     f"its ground at {float(model_ground):g} m: the simulation uses the "
                     f"model's")
    return lines


def simulate(
    model_path: Path = typer.Argument(..., metavar="MODEL", help="VoxelModel .npz from "
                                      "`blastvox voxelize`."),
    output: Path = typer.Option(None, "-o", "--output", help="SimCache file to write (.npz). "
                                "Default: the scene's output.cache."),
    scene: Path = typer.Option(None, "--scene", help="Scene TOML: charges, [simulation] and "
                               "[effects]."),
    charge: list[str] = typer.Option(None, "--charge", help="X,Y,Z:KG[@T] of TNT at metres, "
                                     "detonated at T s; repeatable; replaces the scene's "
                                     "charges (1e-9 to 1e9 kg, within 1e6 m, T 0 to 1e9 s)."),
    explosive: str = typer.Option("TNT", "--explosive", help="Explosive of --charge masses."),
    dt: float = typer.Option(None, "--dt", help="Fixed step, s, at least 1e-9 [default: "
                             "1/240]."),
    fps: float = typer.Option(None, "--fps", help="Output frames per second, 0.001 to 1e6 "
                              "[default: 24]."),
    duration: float = typer.Option(None, "--duration", help="Simulated seconds, > 0 (see "
                                   "--max-steps, --max-frames) [default: 5]."),
    gravity: float = typer.Option(None, "--gravity", help="m/s^2 along -up, 0 to 1000; 0 "
                                  "switches it off [default: 9.81]."),
    fracture: str = typer.Option(None, "--fracture", help="pressure-impulse, yield (the "
                                 "papers' peak overpressure) or damage (Davison-Stevens) "
                                 "[default: pressure-impulse]."),
    burst: ChargeBurst = typer.Option(ChargeBurst.auto, "--burst", case_sensitive=False,
                                       help="Burst of --charge "
        "charges: air (free-air sphere), surface (hemisphere on the ground) or auto "
        "(surface within 0.2 W^(1/3) m of the ground)."),
    no_ground: bool = typer.Option(False, "--no-ground", help="No ground: foundations are "
                                   "ignored and the model floats free."),
    seed: int = typer.Option(None, "--seed", help="Seed of the particles' random streams, "
                             "0 to 2**64 - 1 [default: the scene's or 0]."),
    contact_substeps: int = typer.Option(None, "--contact-substeps", help="Sub-steps of the "
                                         "contact solver a step, 1 to 1000: more hold tall "
                                         "stacks and deep piles stiffer, and cost more "
                                         "[default: 4]."),
    max_steps: int = typer.Option(MAX_STEPS, "--max-steps", help="Refuse a run of more fixed "
                                  "steps (duration / dt)."),
    max_frames: int = typer.Option(MAX_FRAMES, "--max-frames", help="Refuse a run of more "
                                   "output frames (duration x fps + 1)."),
    max_particles: int = typer.Option(MAX_PARTICLES, "--max-particles", help="Refuse particle "
                                      "budgets (the scene's [particles]) that add up to more."),
    max_memory: float = typer.Option(MAX_MEMORY_GIB, "--max-memory", metavar="GIB",
                                     help="Refuse a run that would need more memory, "
                                     "GiB: its arrays (estimated from the model's voxels, "
                                     "links and charges before it starts) and its recorded "
                                     "frames (pieces x frames, as pieces appear)."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="No progress bar or summary."),
) -> None:
    """Blow up a voxel model: blast wave, fracture, fragments, rigid-body motion.

    Runs at a fixed step, writes piece transforms at --fps, destroyed voxels,
    damage, link breaks, dust emitters and shock radii. Settings outside their bounds
    and runs over a budget (--max-steps, --max-frames, --max-particles, --max-memory)
    are refused with one line before anything is computed (docs/user-guide.md, "Limits
    and exit codes").
    """
    from dataclasses import replace

    from blastvox.cli.console import cli_warnings, err_console
    from blastvox.model import VoxelModel
    from blastvox.simulate.engine import simulate as run
    from blastvox.simulate.settings import (
        Budget,
        ChargeSpec,
        SimSettings,
        check_settings,
        settings_from_scene,
    )

    model = VoxelModel.load(model_path)
    settings = SimSettings()
    if scene is not None:
        from blastvox.scene import load_scene

        spec = load_scene(scene)
        settings = settings_from_scene(spec, str(scene))
        if output is None:
            output = spec.output.cache
    if output is None:
        raise BlastvoxError(f"{model_path}: no output file: give -o SIM.npz")
    from blastvox.io.outputs import check_npz_output, check_output

    from_scene = scene is not None and output == spec.output.cache
    label = "output.cache" if from_scene else "-o"
    check_output(output, [model_path, scene], make_dirs=from_scene, label=label)
    check_npz_output(output, label, "SimCache")
    fracture = fracture.lower() if fracture is not None else None  # as a scene's value
    overrides = {k: v for k, v in {"dt": dt, "fps": fps, "duration": duration,
                                   "gravity": gravity, "fracture": fracture, "seed": seed,
                                   "contact_substeps": contact_substeps}.items()
                 if v is not None}
    if overrides.get("fracture", "yield") not in ("pressure-impulse", "yield", "damage"):
        raise BlastvoxError(f"--fracture must be pressure-impulse, yield or damage "
                            f"(got {fracture!r})")
    if no_ground:
        overrides["ground"] = False
    if charge:
        specs = []
        for text in charge:
            position, kg, t = _parse_charge(text)
            specs.append(ChargeSpec(position, kg, explosive, t, ChargeBurst(burst).value))
        overrides["charges"] = tuple(specs)
    flagged = [*overrides, "charges"] if charge or scene is None else list(overrides)
    if scene is None:  # every value is a flag's (given or its default)
        flagged += ["dt", "fps", "duration", "gravity", "seed"]
    names = {k: "--charge" if k == "charges" else f"--{k.replace('_', '-')}" for k in flagged}
    settings = replace(settings, **overrides,
                       budget=Budget(max_steps, max_frames, max_particles, max_memory),
                       origin=settings.origin.renamed(names, str(scene or model_path)))
    check_settings(settings)  # bounds and budgets, before anything is computed
    if charge:
        from blastvox.blast.explosives import tnt_equivalent

        try:
            tnt_equivalent(explosive)
        except BlastvoxError as exc:
            raise BlastvoxError(f"--explosive: {exc}") from None
    if not settings.charges:
        raise BlastvoxError(f"{scene or model_path}: no charges: give --charge X,Y,Z:KG or "
                            f"[[charges]] in the scene")

    console = err_console()
    if scene is not None:
        for line in scene_model_mismatch(spec, model.meta, scene, model_path):
            console.print(f"blastvox: warning: {line}", markup=False, highlight=False)
    started = time.perf_counter()
    progress = _Progress(enabled=not quiet and console.is_terminal, console=console,
                         notes=not quiet)
    with progress, cli_warnings(console):
        cache = run(model, settings, progress=progress,
                    warn=lambda m: console.print(f"blastvox: warning: {m}", markup=False,
                                                  highlight=False))
    cache.save(output)
    if not quiet:
        s = cache.summary()
        seconds = time.perf_counter() - started
        console.print(f"{output}: {s['piece_count']:,} pieces ({s['moving_piece_count']:,} "
                      f"moving), {s['broken_link_count']:,} broken links, "
                      f"{s['destroyed_voxel_count']:,} voxels to dust, {s['frame_count']} frames, "
                      f"{seconds:.2f} s wall", markup=False, highlight=False)


class _Progress:
    """Rich progress bar showing simulated time and steps per second."""

    def __init__(self, enabled: bool, console, notes: bool = True) -> None:
        self.enabled, self.console, self.notes = enabled, console, notes
        self._bar = self._task = None
        self._start, self._done = 0.0, 0  # at the first update: compilation is not stepping

    def __enter__(self):
        return self

    def _start_bar(self) -> None:
        # on the first update, not on entry: compilation is not stepping
        from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

        self._bar = Progress(TextColumn("simulating"), BarColumn(),
                             TextColumn("{task.fields[sim]}"), TimeRemainingColumn(),
                             console=self.console, transient=True)
        self._bar.start()
        self._task = self._bar.add_task("sim", total=1, sim="")

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.stop()

    def note(self, line: str) -> None:
        """A status line (first-run compilation), also when stderr is not a terminal."""
        if self.notes:
            self.console.print(line, markup=False, highlight=False)

    def update(self, sim_time: float, done: int, total: int) -> None:
        check_interrupt()  # one that library code swallowed stops the run here
        if not self.enabled:
            return
        if self._bar is None:
            self._start_bar()
            self._start, self._done = time.perf_counter(), done
        elapsed = time.perf_counter() - self._start
        rate = f", {(done - self._done) / elapsed:,.0f} steps/s" if done > self._done else ""
        self._bar.update(self._task, completed=done, total=total,
                         sim=f"t = {sim_time:.3f} s{rate}")
