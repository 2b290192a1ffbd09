"""Performance in one command: throughput against memory bandwidth, Mazarak Table 5-1,
PyBullet side by side, start-up, and the targets.

    python benchmarks/performance.py            # everything (about 10 minutes on 2 cores)
    python benchmarks/performance.py --quick    # no 1M block, no 10,000 pieces, no cold start

Prints the machine line and load average, then markdown tables:

(a) Blast + fracture + dynamics throughput of ``simulate(model, settings)`` on
    ``benchmarks/simulate.py``'s block (10 m of reinforced concrete, 1 kg TNT 1 m
    from its +X face, 0.25 s at 1/240 s, collisions off) at 5^3, 10^3, 22^3, 46^3
    and 100^3 voxels, each in its own process, beside a memory-bandwidth bound
    measured in that process: NumPy copying, step by step, the bytes the run's
    sweeps must at least read and write (the byte model is ``SWEEPS`` below: per
    voxel and per link for each kernel that sweeps them, counted per call in an
    untimed run, plus ``BODY_BYTES`` per live body per step). The ratio is the
    loop's time (steps and frame recording: ``simulate`` less building the run and
    packing the cache) over the bound's; then where the largest block's run spends
    its time, phase by phase.
(b) Frames per second against boundary voxels, collisions on and off, laid out
    like Mazarak 1999 Table 5-1 with the paper's figures (``benchmarks/_debris.py``,
    shared with ``benchmarks/contacts.py``).
(c) The same debris in blastvox and PyBullet, in this process: K = 100, 1,000
    (and 10,000) 0.2 m boxes thrown about over a ground plane for 2 s at
    1/240 s; time of the stepping loops, their ratio, the per-phase profile of
    blastvox's step when it is behind, and a check that both end alike. See
    ``FAIRNESS`` for how the two are set up alike.
(d) Start-up: ``blastvox simulate`` of the house example with a fresh, empty
    ``NUMBA_CACHE_DIR`` (cold: numba compiles every kernel the house calls, on
    first call, into that cache; no manifest) and warm, the floor any
    numba-run simulator pays before its own code (Python's start, ``import
    numba`` with its target set-up, loading the house's kernels from the cache:
    a fresh process's first ``simulate()`` less a warm one), and ``blastvox --help``.

Then the targets, pass or FAIL. The script reports, it does not gate: it exits
0 even when a target is missed, and 1 only if a case crashes.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np
from _debris import (
    PIECE_M,
    Debris,
    cubes,
    debris,
    debris_settings,
    lattice,
    print_table_5_1,
    rotations,
    runner,
    table_5_1,
)
from _machine import (  # benchmarks/ is on sys.path when run as a script
    machine,
    repeat_count,
    verdict,
)
from simulate import Case, cli, make_model, settings_for, start_up

from blastvox.model import VoxelModel

ROOT = Path(__file__).resolve().parent.parent
HOUSE = ROOT / "examples" / "house" / "scene.toml"
BLOCK_CELLS = (5, 10, 22, 46, 100)  # voxels along the block's edge: ~1e2 ... 1e6 voxels
BLOCK_DURATION = 0.25  # s of shot, as benchmarks/simulate.py's blocks
PIECES = (100, 1_000, 10_000)  # PyBullet comparison
PIECE_STEPS = 480  # 2 s at 1/240 s
TARGET_BOUND_RATIO = 3.0
TARGET_HELP_S = 0.3
TARGET_HOUSE_S = 1.0


# --------------------------------------------------------------------------- (a) bandwidth


@dataclass(frozen=True)
class Sweep:
    """Bytes one call of a kernel must at least read plus write, per voxel and per link."""

    per_voxel: int
    per_link: int
    what: str


#: The byte model: each kernel that sweeps voxels or links (called by the engine's phases
#: through the module attributes in ``_homes``), and what one call must at least touch per
#: voxel / link.
SWEEPS: dict[str, Sweep] = {
    "fracture_wave": Sweep(35, 17, "voxels: alive 1, body 8, centroid 24 read, crossed "
                                   "flag 1 written, destroyed flag 1 cleared; links: 2 CSR "
                                   "ids 16, alive 1 read"),
    "blast_impulses": Sweep(18, 0, "alive 1, body 8, link mask 1, conform slot 8 read"),
    "link_masks": Sweep(2, 25, "links: alive 1, voxel pair 16, face 8 read; voxels: "
                               "link mask 1 cleared, 1 written"),
    "split_bodies": Sweep(25, 0, "body 8 and its dirty flag 1 read, component 8 written "
                                 "and 8 read"),
    "body_radii": Sweep(41, 0, "body 8, alive 1, centroid 24, radius 8 read"),
    "boundary_lists": Sweep(18, 0, "body 8, alive 1, link mask 1, conform slot 8 read"),
    "link_alive_counts": Sweep(50, 18, "once a frame with the recorder: per voxel link "
                                       "offsets 8 read, counts 8 written, yield 8, initial "
                                       "yield 8, damage 8, alive 1, damage level 1 + 1; per "
                                       "link 2 ids 16 and 2 alive flags 2 read"),
}
#: Per live body and step (velocities, contacts' sleep test, positions, rotation matrix):
#: mass 8, inverse inertia 72, flags 4, radius 8 read; position 24, quaternion 32,
#: linear and angular momentum 24 + 24 read and written; rotation 72 written.
BODY_BYTES = 8 + 72 + 4 + 8 + 2 * (24 + 32 + 24 + 24) + 72


def _homes() -> dict[str, tuple[ModuleType, ...]]:
    """The modules through which the step's phases call each swept kernel (a kernel
    the engine also calls while building the run, outside the counted loop, is
    wrapped there as well)."""
    from blastvox.simulate import boundary, engine, forces, fracture, topology

    return {"fracture_wave": (fracture,),
            "blast_impulses": (forces,), "link_masks": (topology, engine),
            "split_bodies": (topology,), "body_radii": (topology, engine),
            "boundary_lists": (boundary,), "link_alive_counts": (engine,)}


@contextlib.contextmanager
def patched(targets: list[tuple], make: Callable[[str, Callable], Callable]
            ) -> Iterator[list[str]]:
    """Replace ``getattr(obj, name)`` by ``make(label, original)`` for each target
    ``(obj, name)`` or ``(obj, name, label)`` (label defaults to name) that exists, and
    restore them on exit (a class's own descriptor, e.g. a classmethod, as it was);
    yields the names that were missing."""
    saved, missing = [], []
    for obj, name, *label in targets:
        original = getattr(obj, name, None)
        if original is None:
            missing.append(name)
            continue
        saved.append((obj, name, vars(obj).get(name, original)))
        setattr(obj, name, make(label[0] if label else name, original))
    try:
        yield missing
    finally:
        for obj, name, raw in reversed(saved):
            setattr(obj, name, raw)


#: Phases of a run for the profile: (module in blastvox.simulate, class or None, attribute),
#: each wrapped where the engine (``simulate``, ``Run.start``, ``step``, ``split``) or a
#: phase calls it. A phase called inside another is listed under it.
PHASES = (("engine", "Run", "start"), ("engine", None, "build_model"),
          ("engine", None, "initial_state"), ("engine", None, "body_rotations"),
          ("engine", None, "bodies_in_shell"), ("engine", None, "fracture_phase"),
          ("fracture", None, "mark_in_shell"), ("fracture", None, "fracture_wave"),
          ("fracture", None, "fracture_damage"),
          ("engine", None, "ignite_phase"), ("engine", None, "split"),
          ("topology", None, "kill_links_of"), ("topology", None, "link_masks"),
          ("topology", None, "split_bodies"), ("topology", None, "body_radii"),
          ("recorder", "Recorder", "link_breaks"), ("recorder", "Recorder", "voxels_destroyed"),
          ("engine", None, "burn_phase"), ("effects", "Effects", "shock_dust"),
          ("effects", "Effects", "voxel_dust"), ("effects", "Effects", "collision_dust"),
          ("effects", "Effects", "ground_ring"), ("effects", "Effects", "fireball"),
          ("effects", "Effects", "flames"), ("engine", None, "blast_phase"),
          ("forces", None, "blast_impulses"), ("boundary", None, "boundary_lists"),
          ("engine", None, "integrate_velocities"), ("engine", None, "collide_phase"),
          ("contact.fragments", None, "static_hash"), ("contact.fragments", None, "rest_grid"),
          ("contact.fragments", None, "collide_bodies"),
          ("contact.fragments", None, "damp_resting"),
          ("engine", None, "ground_phase"), ("contact.ground", None, "ground_contacts"),
          ("engine", None, "settle"), ("engine", None, "integrate_positions"),
          ("engine", None, "_still_step"), ("recorder", "Recorder", "frame"),
          ("engine", None, "link_alive_counts"), ("limits", "LimitMonitor", "check"),
          ("recorder", "Recorder", "pack"), ("cues", None, "shock_opacity"),
          ("cues", None, "camera_shake"))


class Phases:
    """Wall time per phase of blastvox runs (wrappers on the attributes in PHASES).

    A call made while another wrapped call runs is booked under that caller as
    well as in its own right, so top-level phases add up to at most the total.
    """

    def __init__(self) -> None:
        self.spent: dict[tuple[str, ...], float] = {}
        self.stack: list[str] = []

    def wrap(self, name: str, original: Callable) -> Callable:
        """``original`` timed under ``name``."""
        def wrapper(*args, **kwargs):
            key = (*self.stack[:1], name) if self.stack else (name,)
            self.stack.append(name)
            started = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.spent[key] = self.spent.get(key, 0.0) + time.perf_counter() - started
                self.stack.pop()
        return wrapper

    def installed(self) -> contextlib.AbstractContextManager:
        """Context manager: the wrappers in place (those that exist)."""
        import importlib

        targets = []
        for module, cls, attribute in PHASES:
            home = importlib.import_module(f"blastvox.simulate.{module}")
            targets.append((getattr(home, cls), attribute, f"{cls}.{attribute}") if cls
                           else (home, attribute))
        return patched(targets, self.wrap)

    def table(self, total: float) -> dict[str, float]:
        """{label: seconds}: top-level phases, those called within them indented, and
        "other" (the total less the top-level phases), largest first within each group."""
        top = {k[0]: t for k, t in self.spent.items() if len(k) == 1}
        out: dict[str, float] = {}
        for name, t in sorted(top.items(), key=lambda item: -item[1]):
            out[name] = t
            inner = {k[1]: u for k, u in self.spent.items() if len(k) == 2 and k[0] == name}
            for sub, u in sorted(inner.items(), key=lambda item: -item[1]):
                out[f"  {sub} (in {name})"] = u
        out["other (Python glue, untimed kernels)"] = total - sum(top.values())
        return out


def print_phases(spent: dict[str, float], total: float) -> None:
    """Markdown table of :meth:`Phases.table`."""
    print("| phase | s | share |")
    print("|---|--:|--:|")
    for label, t in spent.items():
        name = f"&nbsp;&nbsp;{label.strip()}" if label.startswith(" ") else f"`{label}`" \
            if not label.startswith("other") else label
        print(f"| {name} | {t:.3f} | {100 * t / total:.0f} % |")


def count_sweeps(model: VoxelModel, settings) -> dict:
    """One untimed ``simulate`` that counts each swept kernel's calls in its loop (from
    the first step's set-up to packing the cache) and the live bodies of every step;
    returns the counts and the byte total of the model."""
    from blastvox.simulate import engine
    from blastvox.simulate.recorder import Recorder

    calls = dict.fromkeys(SWEEPS, 0)
    bodies = [0, 0]  # live bodies summed over steps, steps
    looping = [False]  # between the first step's set-up and packing the cache

    def counting(name: str, original: Callable) -> Callable:
        def wrapper(*args, **kwargs):
            calls[name] += looping[0]
            return original(*args, **kwargs)
        return wrapper

    def started(name: str, original: Callable) -> Callable:
        def wrapper(*args, **kwargs):
            out = original(*args, **kwargs)
            looping[0] = True  # the run is built (model, state, first link masks, radii)
            return out
        return wrapper

    def stopped(name: str, original: Callable) -> Callable:
        def wrapper(*args, **kwargs):
            looping[0] = False
            return original(*args, **kwargs)
        return wrapper

    def counting_step(name: str, original: Callable) -> Callable:
        def wrapper(run, *args, **kwargs):
            n = run.state.n_bodies
            bodies[0] += int(np.count_nonzero(run.state.bodies.live[:n]))
            bodies[1] += 1
            return original(run, *args, **kwargs)
        return wrapper

    homes = _homes()
    kernels = [(home, name) for name in SWEEPS for home in homes[name]]
    missing = sorted(name for name in SWEEPS
                     if not any(hasattr(home, name) for home in homes[name]))
    with patched(kernels, counting), patched([(engine, "step")], counting_step), \
            patched([(engine.Run, "start")], started), patched([(Recorder, "pack")], stopped):
        engine.simulate(model, settings)
    n, links = model.voxel_count, len(model.arrays["link_voxels"])
    total = sum(calls[k] * (s.per_voxel * n + s.per_link * links) for k, s in SWEEPS.items())
    total += BODY_BYTES * bodies[0]
    return {"calls": calls, "body_steps": bodies[0], "steps": bodies[1], "bytes": total,
            "missing": missing}


def copy_seconds(nbytes: int, steps: int, repeat: int = 3) -> float:
    """Best of ``repeat``: NumPy copying ``nbytes`` (read + write) in ``steps`` equal copies."""
    half = max(1, nbytes // (2 * max(steps, 1)))
    src = np.ones(half, dtype=np.uint8)
    dst = np.empty_like(src)
    np.copyto(dst, src)
    best = math.inf
    for _ in range(repeat):
        started = time.perf_counter()
        for _ in range(steps):
            np.copyto(dst, src)
        best = min(best, time.perf_counter() - started)
    return best


def stream_gbs(mib: int = 256, repeat: int = 3) -> float:
    """Machine copy bandwidth, GB/s of bytes read + written, by a ``mib`` MiB NumPy copy."""
    nbytes = mib << 20
    return 2 * nbytes / copy_seconds(2 * nbytes, 1, repeat) / 1e9


def peak_cell(r: dict) -> str:
    """The peak RSS cell of table (a): one simulate()'s (the timing worker's)."""
    alone = r.get("simulate_peak_mib")
    worker = f"{r['peak_mib']:,.0f}"
    return worker if alone is None else f"{alone:,.0f} ({worker})"


#: One ``simulate()`` of a block in a process that imports only blastvox and the
#: block's settings (benchmarks/simulate.py: the standard library): the benchmark's own
#: imports, trimesh and pybullet among them, are ~50 MiB that a user's run does not hold.
#: argv: model path, benchmarks folder, duration (s).
MEMORY_PROBE = """
import resource, sys
sys.path.insert(0, sys.argv[2])
from simulate import Case, settings_for
from blastvox.model import VoxelModel
from blastvox.simulate import engine
model = VoxelModel.load(sys.argv[1])
engine.simulate(model, settings_for(Case("block", cells=1, duration=float(sys.argv[3]))))
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def simulate_peak_mib(model_path: Path) -> float | None:
    """Peak resident set (MiB) of one ``simulate()`` of a block (:func:`settings_for`)
    in a process of its own (:data:`MEMORY_PROBE`): Python, numba and its cached
    kernels, the model as loaded, and the run. None if it failed."""
    proc = subprocess.run([sys.executable, "-c", MEMORY_PROBE, str(model_path),
                           str(Path(__file__).resolve().parent), repr(BLOCK_DURATION)],
                          capture_output=True, text=True)
    return float(proc.stdout.split()[-1]) if proc.returncode == 0 else None


def throughput_worker(cells: int, model_path: Path, repeat: int, profile: bool) -> dict:
    """Count, then time ``simulate`` of one block; measure its bandwidth bound; with
    ``profile``, one more run timed phase by phase (called in a worker process)."""
    from blastvox.simulate import engine
    from blastvox.simulate.recorder import Recorder

    model = VoxelModel.load(model_path)
    settings = settings_for(Case(f"block{cells}", cells=cells, duration=BLOCK_DURATION))
    # also loads numba's cache, or compiles: the wrapped kernels are called from Python
    # only (no compiled function calls them), so compiling does not see the wrappers
    counted = count_sweeps(model, settings)
    seconds, loops = [], []
    loop = [0.0]

    def timed(name: str, original: Callable) -> Callable:
        def wrapper(*args, **kwargs):
            started = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                loop[0] += time.perf_counter() - started
        return wrapper

    for _ in range(repeat):
        loop[0] = 0.0
        with patched([(engine, "step"), (Recorder, "frame"), (engine, "link_alive_counts")],
                     timed):
            started = time.perf_counter()
            cache = engine.simulate(model, settings)
            seconds.append(time.perf_counter() - started)
        loops.append(loop[0])
    steps = int(cache.meta["steps"])
    phases = None
    if profile:
        profiler = Phases()
        with profiler.installed():
            started = time.perf_counter()
            engine.simulate(model, settings)
            total = time.perf_counter() - started
        phases = {"total": total, "spent": profiler.table(total)}
    from blastvox.simulate.settings import run_memory_bytes

    estimate = run_memory_bytes(model, len(settings.charges))
    return {"phases": phases, "voxels": model.voxel_count,
            "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "estimate_mib": estimate / 2**20,
            "links": len(model.arrays["link_voxels"]), "steps": steps, "seconds": seconds,
            "loops": loops, "bytes": counted["bytes"],
            "calls": counted["calls"], "missing": counted["missing"],
            "bound": copy_seconds(counted["bytes"], steps), "gbs": stream_gbs(),
            "pieces": cache.summary()["piece_count"]}


def throughput(directory: Path, quick: bool, repeat: int) -> tuple[dict[int, dict], bool]:
    """(a): one worker process per block size; prints the table."""
    print("## (a) Blast + fracture + dynamics throughput against memory bandwidth\n")
    print(f"`simulate()` of the 10 m reinforced-concrete block, 1 kg TNT 1 m off its +X "
          f"face, {BLOCK_DURATION:g} s at 1/240 s, collisions off; best of {repeat} after one "
          "counting run (at least 5 up to 10^4 voxels). Loop: the steps and the frame "
          "recording, i.e. `simulate()` less building the run and packing the cache. Bound: "
          "NumPy copying the bytes the loop's sweeps must at least read and write (byte model "
          "in `performance.py`), step by step, in the same process. Peak RSS: one `simulate()` "
          "in a process of its own (Python, numba's cached kernels, the model and the run; "
          "the timing worker's, which also holds its counting run, in brackets); estimate: "
          "the memory budget's "
          "figure for the run (`blastvox.simulate.settings.run_memory_bytes`: the model, the "
          "run's arrays and the kernels, not the interpreter's ~100 MiB).\n")
    print("| voxels | links | steps | simulate s | voxel-steps/s | loop s | model MB/step | "
          "bound s | loop / bound | pieces | peak RSS MiB | estimate MiB |")
    print("|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|", flush=True)
    results, crashed, gbs, missing = {}, False, [], set()
    sizes = [cells for cells in BLOCK_CELLS if not (quick and cells >= 100)]
    for cells in sizes:
        case = Case(f"block{cells}", cells=cells, duration=BLOCK_DURATION)
        try:
            model = make_model(case, directory)
            proc = subprocess.run([sys.executable, __file__, "--worker", str(cells), "--model",
                                   str(model), "--repeat", str(repeat if cells > 22 else
                                                               max(repeat, 5)),
                                   *(["--profile"] if cells == sizes[-1] else [])],
                                  capture_output=True, text=True)
            if proc.returncode != 0:
                lines = proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"]
                raise RuntimeError(f"worker crashed: {lines[-1]}")
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            r["simulate_peak_mib"] = simulate_peak_mib(model)
        except (RuntimeError, ValueError, IndexError) as exc:
            crashed = True
            print(f"| {cells ** 3:,} | — | — | — | — | — | — | — | error: {exc} | — | — | — |",
                  flush=True)
            continue
        best = min(r["seconds"])
        loop = r["loops"][r["seconds"].index(best)]
        results[cells] = {**r, "best": best, "loop": loop, "ratio": loop / r["bound"]}
        gbs.append(r["gbs"])
        missing.update(r["missing"])
        print(f"| {r['voxels']:,} | {r['links']:,} | {r['steps']} | {best:.3f} | "
              f"{r['voxels'] * r['steps'] / best / 1e6:,.2f}M | {loop:.3f} | "
              f"{r['bytes'] / r['steps'] / 1e6:,.2f} | {r['bound']:.4f} | "
              f"{loop / r['bound']:,.1f}× | {r['pieces']:,} | {peak_cell(r)} | "
              f"{r['estimate_mib']:,.0f} |", flush=True)
    if missing:
        print(f"\nByte model: kernels not found in blastvox.simulate, so not counted: "
              f"{', '.join(sorted(missing))}.")
    if gbs:
        print(f"\nNumPy copy bandwidth of this machine (256 MiB, read + write): "
              f"{np.median(gbs):.1f} GB/s.")
    largest = results.get(sizes[-1])
    if largest and largest["phases"]:
        total = largest["phases"]["total"]
        print(f"\nWhere the {largest['voxels']:,}-voxel run spends its time (a separate, "
              f"profiled run, {total:.2f} s):\n")
        print_phases(largest["phases"]["spent"], total)
    return results, crashed


# --------------------------------------------------------------------------- (c) PyBullet


FAIRNESS = """\
How the two are set up alike:

* the same K pieces: 0.2 m boxes of stone's density ({mass:g} kg, inertia m s^2/6), the
  same seeded start (`_debris.debris`: positions, orientations, velocities, spins),
  gravity 9.81 m/s^2, a ground plane at z = 0, dt = 1/240 s, the same number of steps,
  one thread each, in this process, after a warm-up; building the scenes is not timed;
* PyBullet: `p.DIRECT`, maximal-coordinate rigid bodies (`btRigidBody`, box shapes),
  `setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0, numSolverIterations=8)`
  (blastvox solves ground and box contacts together, up to 64 sweeps until no velocity
  changes by more than 1 cm/s; pybullet's default is 50), a
  `stepSimulation()` loop; blastvox: `engine.step` in a loop (what `simulate()` runs,
  without recording frames);
* restitution {e:g} and friction {mu:g} at the ground in both: Bullet multiplies the two
  bodies' coefficients, so box and plane each get sqrt(e) and sqrt(mu) (box on box in
  Bullet: e {e:g}, mu {mu:g}; in blastvox the smaller restitution of the two voxels,
  {e:g}, and its own friction model); Bullet's restitution velocity threshold is
  blastvox's bounce threshold, {bounce:.3f} m/s;
* sleeping "on" is each engine's own rule: blastvox puts to sleep pieces slower than
  {sleep:g} m/s for 0.5 s, or balanced on the ground; Bullet (`URDF_ENABLE_SLEEPING`,
  sleepThreshold {sleep:g} m/s) after 2 s below it, a constant pybullet does not expose,
  so within these 2 s no Bullet box sleeps and one Bullet time serves both rows;
  sleeping "off" is blastvox with sleep_speed = 0 (no clamping to rest, no resting
  damping): the strictly comparable pair;
* margins: Bullet's box collision margin is {margin:g} m (pybullet's default for boxes,
  inside the box), its contact breaking threshold 0.02 m; blastvox uses speculative
  contacts (within one step's travel, at most half a voxel) between boxes and with the
  ground, no margin."""


def import_pybullet() -> ModuleType | None:
    """pybullet, imported without its build-time banner (C stdio); None if missing."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
            try:
                import pybullet
            finally:
                with contextlib.suppress(OSError, AttributeError):
                    ctypes.CDLL(None).fflush(None)
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
    except ImportError:
        return None
    finally:
        for fd in saved:
            os.close(fd)
    return pybullet


@dataclass
class Outcome:
    """Time of the stepping loop and the pieces' final state (world, Z up)."""

    seconds: float
    pos: np.ndarray
    quat: np.ndarray  # (w, x, y, z)
    vel: np.ndarray

    def summary(self) -> dict[str, float]:
        """Fraction of pieces touching the ground (lowest corner within 1 cm), mean
        centre height, mean speed and rms horizontal spread about the mean, m."""
        rot = rotations(self.quat)
        lowest = self.pos[:, 2] - 0.5 * PIECE_M * np.abs(rot[:, 2, :]).sum(axis=1)
        spread = self.pos[:, :2] - self.pos[:, :2].mean(axis=0)
        return {"ground": float(np.mean(lowest < 0.01)), "height": float(self.pos[:, 2].mean()),
                "speed": float(np.linalg.norm(self.vel, axis=1).mean()),
                "spread": float(np.sqrt((spread ** 2).sum(axis=1).mean()))}


def bullet_run(p: ModuleType, start: Debris, mass: float, steps: int, settings,
               restitution: float) -> tuple[Outcome, float]:
    """PyBullet's run of ``start``; returns the outcome and the boxes' collision margin."""
    c = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -settings.gravity, physicsClientId=c)
        p.setPhysicsEngineParameter(fixedTimeStep=settings.dt, numSubSteps=0,
                                    numSolverIterations=8,
                                    restitutionVelocityThreshold=bounce_speed(settings),
                                    physicsClientId=c)
        surface = {"restitution": math.sqrt(restitution),
                   "lateralFriction": math.sqrt(settings.friction)}
        plane = p.createMultiBody(0.0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=c),
                                  physicsClientId=c)
        p.changeDynamics(plane, -1, **surface, physicsClientId=c)
        box = p.createCollisionShape(p.GEOM_BOX, halfExtents=[PIECE_M / 2] * 3,
                                     physicsClientId=c)
        ids = []
        for k in range(start.count):
            w, x, y, z = start.quat[k]
            b = p.createMultiBody(mass, box, basePosition=start.pos[k].tolist(),
                                  baseOrientation=[x, y, z, w], useMaximalCoordinates=True,
                                  flags=p.URDF_ENABLE_SLEEPING, physicsClientId=c)
            p.changeDynamics(b, -1, sleepThreshold=settings.sleep_speed, **surface,
                             physicsClientId=c)
            p.resetBaseVelocity(b, start.vel[k].tolist(), start.omega[k].tolist(),
                                physicsClientId=c)
            ids.append(b)
        margin = float(p.getDynamicsInfo(ids[0], -1, physicsClientId=c)[-1]) if ids else 0.0
        started = time.perf_counter()
        for _ in range(steps):
            p.stepSimulation(physicsClientId=c)
        seconds = time.perf_counter() - started
        pos, quat, vel = [], [], []
        for b in ids:
            where, (x, y, z, w) = p.getBasePositionAndOrientation(b, physicsClientId=c)
            pos.append(where)
            quat.append((w, x, y, z))
            vel.append(p.getBaseVelocity(b, physicsClientId=c)[0])
        return Outcome(seconds, np.array(pos), np.array(quat), np.array(vel)), margin
    finally:
        p.disconnect(c)


def bounce_speed(settings) -> float:
    """blastvox's ground bounce threshold, m/s: slower impacts come to rest."""
    return settings.sleep_speed + 2.0 * 9.81 * settings.dt


def blastvox_run(model: VoxelModel, start: Debris, steps: int, sleep: bool,
                 profile: bool = False) -> tuple[Outcome, dict[str, float]]:
    """blastvox's run of ``start``: the outcome and, with ``profile``, seconds per phase
    (:class:`Phases`)."""
    from blastvox.simulate.engine import step

    run = runner(model, debris_settings(sleep=sleep), start)
    phases = Phases()
    with phases.installed() if profile else contextlib.nullcontext():
        started = time.perf_counter()
        for n in range(1, steps + 1):
            step(run, n, 0)
        seconds = time.perf_counter() - started
    bodies = run.state.bodies
    k = start.count
    mass = bodies.mass[:k, None]
    return Outcome(seconds, bodies.pos[:k].copy(), bodies.quat[:k].copy(),
                   bodies.lin[:k] / mass), phases.table(seconds) if profile else {}


def pybullet_side_by_side(directory: Path, quick: bool) -> tuple[dict[int, dict], bool]:
    """(c): prints the timing, profile and end-state tables."""
    print("## (c) The same debris in blastvox and PyBullet\n")
    p = import_pybullet()
    if p is None:
        print("pybullet is not installed (`pip install -e '.[bench]'`): not run.")
        return {}, False
    settings = debris_settings()
    pieces = [k for k in PIECES if not (quick and k > 1_000)]
    # warm-up: numba kernels compiled or loaded, both sleep settings; Bullet's first world
    warm_model = cubes(lattice(100), directory)
    mass = float(warm_model.arrays["voxel_mass"][0])
    restitution = float(warm_model.arrays["material_restitution"][
        warm_model.arrays["voxel_material"][0]])
    for sleep in (True, False):
        blastvox_run(warm_model, debris(100), 240, sleep)
    _, margin = bullet_run(p, debris(100), mass, 10, settings, restitution)
    print(FAIRNESS.format(mass=mass, e=restitution, mu=settings.friction,
                          bounce=bounce_speed(settings), sleep=settings.sleep_speed,
                          margin=margin) + "\n")
    print(f"{PIECE_STEPS} steps (2 s at 1/240 s); wall seconds of the stepping loop; "
          "ratio = blastvox / PyBullet (below 1: blastvox ahead).\n")
    print("| pieces | PyBullet s | blastvox s, sleeping off | ratio, off | "
          "blastvox s, sleeping on | ratio, on |")
    print("|--:|--:|--:|--:|--:|--:|", flush=True)
    results: dict[int, dict] = {}
    crashed = False
    for k in pieces:
        try:
            model, start = cubes(lattice(k), directory), debris(k)
            bullet, _ = bullet_run(p, start, mass, PIECE_STEPS, settings, restitution)
            off, _ = blastvox_run(model, start, PIECE_STEPS, sleep=False)
            on, _ = blastvox_run(model, start, PIECE_STEPS, sleep=True)
        except Exception as exc:  # report the crash, go on with the other sizes
            crashed = True
            print(f"| {k:,} | error: {type(exc).__name__}: {exc} | — | — | — | — |", flush=True)
            continue
        results[k] = {"model": model, "start": start, "bullet": bullet, "off": off, "on": on,
                      "ratio_off": off.seconds / bullet.seconds,
                      "ratio_on": on.seconds / bullet.seconds}
        print(f"| {k:,} | {bullet.seconds:.2f} | {off.seconds:.2f} | "
              f"{results[k]['ratio_off']:.2f} | {on.seconds:.2f} | "
              f"{results[k]['ratio_on']:.2f} |", flush=True)

    print("\nEnd state after 2 s (on the ground: lowest corner within 1 cm of it; spread: "
          "rms horizontal distance from the mean):\n")
    print("| pieces | run | on the ground | mean height m | mean speed m/s | spread m |")
    print("|--:|---|--:|--:|--:|--:|")
    for k, r in results.items():
        for name, outcome in (("PyBullet", r["bullet"]), ("blastvox, sleeping off", r["off"]),
                              ("blastvox, sleeping on", r["on"])):
            s = outcome.summary()
            print(f"| {k:,} | {name} | {100 * s['ground']:.1f} % | {s['height']:.3f} | "
                  f"{s['speed']:.3f} | {s['spread']:.2f} |")

    behind = [(k, sleep) for k, r in results.items() for sleep in (False, True)
              if r["ratio_on" if sleep else "ratio_off"] >= 1.0]
    for k, sleep in behind:
        r = results[k]
        outcome, spent = blastvox_run(r["model"], r["start"], PIECE_STEPS, sleep, profile=True)
        print(f"\nblastvox is behind at {k:,} pieces, sleeping {'on' if sleep else 'off'}: "
              f"where its step spends the time (a separate, profiled run, "
              f"{outcome.seconds:.2f} s):\n")
        print_phases(spent, outcome.seconds)
    for r in results.values():
        del r["model"], r["start"]
    return results, crashed


# --------------------------------------------------------------------------- (d) start-up


def start_ups(directory: Path, quick: bool) -> tuple[dict | None, bool]:
    """(d): cold and warm ``blastvox simulate`` of the house, ``blastvox --help``."""
    print("## (d) Start-up\n")
    model = directory / "house.npz"
    try:
        cli("voxelize", "--scene", HOUSE, "-o", model, "-q")
        result = start_up(model, directory, scene=HOUSE, duration=None, cold=not quick,
                          warm_runs=3)
        result["in_process"] = house_in_process(model)
        result["floor"] = numba_floor(model, result["in_process"])
    except (RuntimeError, subprocess.CalledProcessError) as exc:
        print(f"start-up measurement failed: {exc}\n")
        return None, True
    print("| start-up | wall s |")
    print("|---|--:|")
    shot = "`blastvox simulate` house (examples/house, its 4 s of shot)"
    if result["cold"] is None:
        print(f"| {shot}, fresh NUMBA_CACHE_DIR (cold, compiles) | not run (--quick) |")
    else:
        print(f"| {shot}, fresh NUMBA_CACHE_DIR (cold, compiles) | {result['cold']:.2f} |")
    print(f"| {shot}, warm (best of 3) | {result['warm']:.2f} |")
    print(f"| of which `simulate()` in-process, warm (best of 3; no start-up, no file I/O) | "
          f"{result['in_process']:.2f} |")
    floor = result["floor"]
    print(f"| floor of any numba program with these kernels (best of 3): Python start | "
          f"{floor['python']:.2f} |")
    print(f"| + `import numba` and numba's target set-up | {floor['numba']:.2f} |")
    print(f"| + loading the house's {floor['count']} kernels from numba's cache (first "
          f"`simulate()` of a fresh process less a warm one) | {floor['kernels']:.2f} |")
    print(f"| + the shot itself (`simulate()` in-process, above) | {result['in_process']:.2f} |")
    print(f"| = floor of a numba-run simulate of the house, before any other code (CLI, "
          f"scene, model, output) | {floor['total'] + result['in_process']:.2f} |")
    print(f"| `{result['help_command']} --help` (best of 5) | {result['help']:.3f} |\n")
    return result, False


_FLOOR = """
import json, sys, time
started = time.perf_counter()
import numba
from numba.core.registry import cpu_target
cpu_target.target_context.refresh()
imported = time.perf_counter()
from numba.core.dispatcher import Dispatcher
from blastvox.model import VoxelModel
from blastvox.scene import load_scene
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import settings_from_scene
model = VoxelModel.load(sys.argv[1])
settings = settings_from_scene(load_scene(sys.argv[2]))
first = time.perf_counter()
simulate(model, settings)
first = time.perf_counter() - first
kernels = {id(d): d for name, module in list(sys.modules.items())
           if name.startswith("blastvox") for d in vars(module).values()
           if isinstance(d, Dispatcher) and d.overloads}
compiled = sum(sum(d.stats.cache_misses.values()) for d in kernels.values())
print(json.dumps({"numba": imported - started, "first": first, "count": len(kernels),
                  "compiled": compiled}))
"""


def numba_floor(model_path: Path, in_process: float, repeat: int = 3) -> dict:
    """What any warm numba-run ``simulate`` of the house pays before its own code, in
    fresh processes (best of ``repeat`` each): Python's start, ``import numba`` with
    numba's target set-up, and loading the kernels the house needs from numba's cache:
    the first ``simulate()`` of a fresh process (imports done) less ``in_process``, a
    warm one (s). The kernels are the blastvox dispatchers that run (numba's own
    cache, no manifest); it raises if any had to compile (the cache was not warm)."""
    python = math.inf
    for _ in range(repeat + 1):  # the first one warms the file system
        started = time.perf_counter()
        subprocess.run([sys.executable, "-c", "pass"], check=True)
        python = min(python, time.perf_counter() - started)
    runs = []
    for _ in range(repeat):
        proc = subprocess.run([sys.executable, "-c", _FLOOR, str(model_path), str(HOUSE)],
                              capture_output=True, text=True, check=True)
        runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    if any(r["compiled"] for r in runs):
        raise RuntimeError("the floor measurement compiled kernels: the cache is not warm")
    numba_s = min(r["numba"] for r in runs)
    kernels = max(0.0, min(r["first"] for r in runs) - in_process)
    return {"python": python, "numba": numba_s, "kernels": kernels, "count": runs[0]["count"],
            "total": python + numba_s + kernels}


def house_in_process(model_path: Path, repeat: int = 3) -> float:
    """Best of ``repeat`` warm ``simulate()`` calls of the house in this process, s."""
    from blastvox.scene import load_scene
    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import settings_from_scene

    model = VoxelModel.load(model_path)
    settings = settings_from_scene(load_scene(HOUSE))
    simulate(model, settings)  # warm-up
    best = math.inf
    for _ in range(repeat):
        started = time.perf_counter()
        simulate(model, settings)
        best = min(best, time.perf_counter() - started)
    return best


# --------------------------------------------------------------------------- report



def targets(blocks: dict[int, dict], bullet: dict[int, dict], startup: dict | None,
            quick: bool) -> None:
    """The targets table."""
    print("## Targets\n")
    print("| target | measured | result |")
    print("|---|--:|---|")
    for k in PIECES[1:]:
        for sleep in ("off", "on"):
            label = (f"blastvox ahead of PyBullet at {k:,} pieces, sleeping {sleep} in both "
                     "(ratio < 1)")
            r = bullet.get(k)
            if r is None:
                print(f"| {label} | not run{' (--quick)' if quick else ''} | — |")
            else:
                ratio = r[f"ratio_{sleep}"]
                print(f"| {label} | {ratio:.2f} | {verdict(ratio < 1.0)} |")
    big = blocks.get(max(BLOCK_CELLS))
    label = (f"kernels (the loop) within {TARGET_BOUND_RATIO:g}× of the bandwidth bound, "
             "1M voxels")
    if big is None:
        print(f"| {label} | not run{' (--quick)' if quick else ''} | — |")
    else:
        print(f"| {label} | {big['ratio']:.1f}× | "
              f"{verdict(big['ratio'] <= TARGET_BOUND_RATIO)} |")
    if startup is not None:
        print(f"| `blastvox --help` < {TARGET_HELP_S:g} s | {startup['help']:.3f} s | "
              f"{verdict(startup['help'] < TARGET_HELP_S)} |")
        print(f"| warm `blastvox simulate` of the house < {TARGET_HOUSE_S:g} s | "
              f"{startup['warm']:.2f} s | {verdict(startup['warm'] < TARGET_HOUSE_S)} |")
        floor = startup["floor"]["total"] + startup["in_process"]
        if startup["warm"] >= TARGET_HOUSE_S and floor >= TARGET_HOUSE_S:
            print(f"\nThe house's warm start cannot meet {TARGET_HOUSE_S:g} s while the "
                  f"simulator runs on numba: Python, numba, the cached kernels and the shot "
                  f"itself take {floor:.2f} s here, before the CLI, the scene, the model and "
                  "the output (see (d)).")


def main(argv: list[str] | None = None) -> int:
    """Run every part and print the tables; 1 if a case crashed, else 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="no 1M-voxel block, no 10,000 pieces, no cold start")
    parser.add_argument("--repeat", type=int, help="timed runs per block, best counts "
                        "(default: 3, or 1 with --quick; at least 5 up to 10^4 voxels)")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--model", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--profile", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    args.repeat = repeat_count(parser, args)
    if args.worker is not None:
        print(json.dumps(throughput_worker(args.worker, args.model, args.repeat,
                                           args.profile)))
        return 0

    started = time.perf_counter()
    print(machine(("blastvox", "numpy", "numba", "pybullet")))
    print(f"\nCommand: `python benchmarks/performance.py{' --quick' if args.quick else ''}`\n",
          flush=True)
    with tempfile.TemporaryDirectory(prefix="blastvox-perf-") as tmp:
        directory = Path(tmp)
        blocks, crashed_a = throughput(directory, args.quick, args.repeat)
        print("\n## (b) Frames per second against boundary voxels (Mazarak 1999 Table 5-1)\n")
        print("One-voxel pieces thrown about over the ground (`_debris.debris`, the scene "
              "of (c)), first 0.5 s; 24 fps at 1/240 s, 10 steps a frame; the paper's "
              "figures on a 333 MHz Pentium II.\n")
        crashed_b = False
        try:
            print_table_5_1(table_5_1(directory))
        except Exception as exc:  # report, go on
            crashed_b = True
            print(f"Table 5-1 measurement failed: {type(exc).__name__}: {exc}")
        print()
        bullet, crashed_c = pybullet_side_by_side(directory, args.quick)
        print()
        startup, crashed_d = start_ups(directory, args.quick)
    targets(blocks, bullet, startup, args.quick)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"\nLoad average at the end: {load}; wall time of this run "
          f"{time.perf_counter() - started:.0f} s.")
    return 1 if crashed_a or crashed_b or crashed_c or crashed_d else 0


if __name__ == "__main__":
    sys.exit(main())
