"""Compile the simulator's kernels before a first run, on every core.

numba compiles a kernel on its first call, one after another in one process
(the global compiler lock), so the first run of a scene with every effect
costs about 45 s of compilation on one core. Later runs load the compiled code
from numba's on-disk cache in about 15 ms per kernel.

This module keeps a manifest of the kernels the simulator calls from Python
(``blastvox/data/simulate_kernels.tsv``: feature, seconds to compile, kernel,
argument types) and :func:`ensure_compiled` spreads the kernels a run needs over
worker processes, each compiling its share into the on-disk cache, while the
calling process compiles its own. The first run then waits for the largest
share instead of the sum. With a warm cache it costs one cache load.

The manifest is recorded by running reference scenes with an empty cache::

    python -m blastvox.simulate.precompile --record

and ``tests/test_precompile.py`` checks that it covers what the simulator
calls, so a kernel whose arguments change cannot silently fall back to
compiling one at a time.

Workers are forked where that is safe (Linux, one thread): a forked worker
starts compiling at once with numba and the simulator already imported, where
a new interpreter spends about a second importing them first, and all processes
take kernels from one queue, so none waits on a badly estimated share.
Elsewhere workers are new interpreters, each with a fixed share.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from importlib import import_module
from pathlib import Path

MANIFEST = Path(__file__).resolve().parent.parent / "data" / "simulate_kernels.tsv"

# what turns a group of kernels on (a kernel belongs to the first group whose
# reference run compiled it); "core" is always needed
FEATURES = ("core", "ground", "collisions", "damage", "fire")


@dataclass(frozen=True)
class Kernel:
    """One compiled specialisation of a simulator kernel.

    feature: the group that needs it (see FEATURES); seconds: compile time
    measured when the manifest was recorded (only used to balance the
    workers); name: ``module.function``; signature: numba argument types, as
    numba prints them.
    """

    feature: str
    seconds: float
    name: str
    signature: str

    def line(self) -> str:
        return f"{self.feature}\t{self.seconds:.2f}\t{self.name}\t{self.signature}"


def load_manifest(path: Path = MANIFEST) -> list[Kernel]:
    """The kernels of the manifest file, in file order."""
    kernels = []
    for line in path.read_text().splitlines():
        if line and not line.startswith("#"):
            feature, seconds, name, signature = line.split("\t")
            kernels.append(Kernel(feature, float(seconds), name, signature))
    return kernels


def features_of(settings, model) -> set[str]:
    """The manifest groups a run of VoxelModel ``model`` with these SimSettings needs
    (fire only if some voxel can burn)."""
    import numpy as np

    combustible = bool(np.isfinite(model.arrays["voxel_combustibility"]).any())
    needed = {"core"}
    if settings.ground:
        needed.add("ground")
    if settings.collisions:
        needed.add("collisions")
    if settings.fracture == "damage":
        needed.add("damage")
    if settings.fire and combustible:
        needed.add("fire")
    return needed


def dispatcher(name: str):
    """The numba dispatcher ``module.function``."""
    module, _, function = name.rpartition(".")
    return getattr(import_module(module), function)


def argument_types(signature: str) -> tuple:
    """numba types from their printed form, e.g. ``(Array(float64, 1, 'C', False,
    aligned=True), int64)``."""
    from numba.core import types

    namespace = {**vars(types), "bool": types.boolean, "__builtins__": {}}
    value = eval(signature, namespace)  # our own manifest, built from numba's repr
    return value if isinstance(value, tuple) else (value,)


def compile_kernels(kernels: Iterable[Kernel]) -> int:
    """Compile (or load from the cache) each kernel; returns how many this call
    compiled (cache misses), not counting kernels loaded or already in memory."""
    compiled = 0
    for kernel in kernels:
        disp = dispatcher(kernel.name)
        args = argument_types(kernel.signature)
        misses = disp.stats.cache_misses.get(args, 0)
        disp.compile(args)
        compiled += disp.stats.cache_misses.get(args, 0) > misses
    return compiled


def partition(kernels: list[Kernel], parts: int) -> list[list[Kernel]]:
    """Longest-first greedy split of ``kernels`` into ``parts`` lists of similar
    total compile time; part 0 (the caller's) gets the lightest load."""
    shares: list[list[Kernel]] = [[] for _ in range(parts)]
    loads = [0.0] * parts
    for kernel in sorted(kernels, key=_longest_first):
        i = min(range(parts), key=lambda j: (loads[j], -j))
        shares[i].append(kernel)
        loads[i] += kernel.seconds
    return shares


def _longest_first(kernel: Kernel) -> tuple:
    """Sort key: longest recorded compile first, then by name (deterministic)."""
    return -kernel.seconds, kernel.name, kernel.signature


def cpu_count() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def ensure_compiled(features: set[str], notify: Callable[[str], None] | None = None,
                    processes: int | None = None) -> bool:
    """Make sure the kernels of ``features`` are compiled, using ``processes``
    processes (default: the CPUs available) when they are not in the cache.

    Asks numba's cache for the cheapest kernel first (loading it, not compiling
    it): if it is there, the cache is warm and nothing else happens here
    (kernels load lazily as usual).
    ``notify`` receives one line when compilation starts. Returns whether it
    compiled. The environment variable BLASTVOX_PRECOMPILE=0 switches it off
    (kernels then compile one by one on first use).
    """
    if (os.environ.get("BLASTVOX_PRECOMPILE") == "0" or os.environ.get("NUMBA_DISABLE_JIT") == "1"
            or not MANIFEST.exists()):
        return False
    manifest = load_manifest()
    kernels = [k for k in manifest if k.feature in features]
    if not kernels:
        return False
    probe = min(kernels, key=lambda k: (k.seconds, k.name))
    cached = _in_cache(probe)
    probed = cached is None
    if probed:  # numba cannot be asked: compile the probe to find out
        cached = not compile_kernels([probe])
    if cached:
        return False
    rest = [k for k in kernels if k is not probe] if probed else kernels
    parts = max(1, min(processes or cpu_count(), len(rest)))
    if notify is not None:
        notify(f"compiling {len(kernels)} simulation kernels on {parts} "
               f"process{'es' if parts > 1 else ''} (first run only)")
    if parts > 1 and _can_fork():
        _compile_forked(rest, parts)
        return True
    shares = partition(rest, parts)
    index = {k: i for i, k in enumerate(manifest)}
    workers = [_start_worker([index[k] for k in share]) for share in shares[1:]]
    compile_kernels(shares[0])
    for worker in workers:
        worker.wait()  # a failed worker only leaves its kernels to compile lazily
    return True


def _compile_forked(kernels: list[Kernel], parts: int) -> None:
    """Compile ``kernels`` in this process and ``parts - 1`` forked ones.

    All take the next kernel, longest first, from one pipe holding the kernels'
    indices (one byte each: reads of one byte are atomic), so they finish within
    a kernel of each other however wrong the recorded times are. A worker that
    fails only leaves its kernel to compile lazily.
    """
    order = sorted(range(len(kernels)), key=lambda i: _longest_first(kernels[i]))
    if len(order) > 256:  # one byte per index
        raise ValueError(f"{len(order)} kernels: more than a one-byte queue holds")
    read, write = os.pipe()
    os.write(write, bytes(order))
    os.close(write)
    sys.stdout.flush()
    sys.stderr.flush()
    children = []
    for _ in range(parts - 1):
        with warnings.catch_warnings():
            # Python >= 3.12 warns when the process has other OS threads: here those
            # are NumPy's BLAS pool (fork-safe, and the child never calls BLAS)
            warnings.simplefilter("ignore", DeprecationWarning)
            pid = os.fork()
        if pid == 0:  # the child: compile, then leave without running the parent's exit code
            code = 1
            try:
                _compile_queued(read, kernels)
                code = 0
            finally:
                os._exit(code)
        children.append(pid)
    try:
        _compile_queued(read, kernels)
    finally:
        os.close(read)
        for pid in children:
            os.waitpid(pid, 0)


def _compile_queued(read: int, kernels: list[Kernel]) -> None:
    """Compile the kernels whose indices come out of pipe ``read``, one at a time."""
    while index := os.read(read, 1):
        compile_kernels([kernels[index[0]]])


def _in_cache(kernel: Kernel) -> bool | None:
    """Does numba's on-disk cache (or this process) hold ``kernel``? None if numba
    cannot be asked (its cache interface is internal and may change)."""
    disp = dispatcher(kernel.name)
    args = argument_types(kernel.signature)
    if args in disp.overloads:
        return True
    try:
        return disp._cache.load_overload(args, disp.targetctx) is not None
    except Exception:  # noqa: BLE001 - any failure only means "ask by compiling"
        return None


def _start_worker(lines: list[int]) -> subprocess.Popen:
    """A new interpreter compiling the kernels at these indices of the manifest."""
    return subprocess.Popen([sys.executable, "-m", "blastvox.simulate.precompile", "--worker",
                             ",".join(map(str, lines))], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def _can_fork() -> bool:
    """fork() keeps only the calling thread, so a lock another thread holds would stay
    locked in the child: fork only when no other Python thread runs (a progress bar's
    refresh thread, say), and only on Linux (macOS system libraries are not
    fork-safe)."""
    import threading

    return sys.platform.startswith("linux") and threading.active_count() == 1


# --------------------------------------------------------------------------- recording


def compile_times(make_runs: Callable[[], Iterable[tuple[str, Callable[[], None]]]]
                  ) -> dict[tuple[str, str], float]:
    """Seconds each (kernel, signature) took to compile while ``make_runs()`` sets
    the runs up (voxelizing calls some kernels) and they execute, nested
    compilations included; needs an empty numba cache (set NUMBA_CACHE_DIR to a
    new directory before numba is imported)."""
    import time

    from numba.core import event

    seconds: dict[tuple[str, str], float] = {}
    starts: list[float] = []

    class Listener(event.Listener):
        def on_start(self, ev) -> None:
            starts.append(time.perf_counter())

        def on_end(self, ev) -> None:
            disp = ev.data["dispatcher"]
            key = (f"{disp.py_func.__module__}.{disp.py_func.__qualname__}",
                   str(tuple(ev.data["args"])))
            seconds.setdefault(key, time.perf_counter() - starts.pop())

    listener = Listener()
    event.register("numba:compile", listener)
    try:
        for _, run in make_runs():
            run()
    finally:
        event.unregister("numba:compile", listener)
    return seconds


def loaded_kernels() -> set[tuple[str, str]]:
    """(kernel, signature) of every simulator kernel this process compiled or loaded
    through a call from Python. With a warm cache these are exactly the kernels
    the simulator calls from Python (nested ones come inside their callers)."""
    import importlib
    import pkgutil

    import numba

    import blastvox.simulate as package

    seen = set()
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"blastvox.simulate.{info.name}")
        for name, value in vars(module).items():
            if isinstance(value, numba.core.registry.CPUDispatcher) \
                    and value.__module__ == module.__name__:
                stats = value.stats
                for args in set(stats.cache_hits) | set(stats.cache_misses):
                    seen.add((f"{module.__name__}.{name}", str(args)))
    return seen


def called_kernels(runs: Iterable[tuple[str, Callable[[], None]]]) -> dict[tuple[str, str], str]:
    """The feature of the first run that loads each kernel; run with a warm cache."""
    features: dict[tuple[str, str], str] = {}
    for feature, run in runs:
        run()
        for key in loaded_kernels():
            features.setdefault(key, feature)
    return features


def reference_runs(tmp: Path) -> list[tuple[str, Callable[[], None]]]:
    """Scenes that call every kernel, one feature group at a time: the bundled
    house (brick and plaster, founded, 1 kg TNT at the door) and a wooden wall
    (fire). ``tmp``: a directory for the wall's mesh."""
    from dataclasses import replace

    import trimesh

    from blastvox.scene import load_scene
    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, settings_from_scene
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize
    from blastvox.voxelize.requests import requests_from_scene
    from blastvox.voxelize.requests import settings_from_scene as voxelize_settings

    spec = load_scene(Path(__file__).resolve().parents[2] / "examples" / "house" / "scene.toml")
    house = voxelize(requests_from_scene(spec), voxelize_settings(spec))
    base = replace(settings_from_scene(spec), duration=1.0)
    core = replace(base, ground=False, collisions=False, fire=False, dust=False,
                   fireball=False, shock_sphere=False, camera_shake=False)
    mesh = tmp / "wall.stl"
    trimesh.creation.box(extents=(3.0, 0.25, 3.0)).apply_translation((0, 0, 1.5)).export(mesh)
    wall = voxelize([ObjectRequest(mesh=mesh, voxel_size=(0.25,) * 3, material="wood")],
                    VoxelizeSettings(up_axis="Z", ground=0.0))
    # a weak wave, read ten times stronger by the fire model: the wall burns, unbroken
    burn = replace(base, duration=0.5, fire_pressure_scale=10.0,
                   charges=(ChargeSpec((0.0, -4.0, 1.5), 0.2),))
    return [
        ("core", lambda: simulate(house, core)),
        ("ground", lambda: simulate(house, replace(core, ground=True))),
        ("collisions", lambda: simulate(house, replace(base, fire=False))),
        ("damage", lambda: simulate(house, replace(base, fracture="damage", fire=False))),
        ("fire", lambda: simulate(wall, burn)),
    ]


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--record", action="store_true",
                        help="rewrite the manifest from the reference runs (compiles them "
                        "into a temporary cache, about a minute)")
    parser.add_argument("--record-times", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--record-calls", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--jobs", type=int, help="processes (default: CPUs available)")
    args = parser.parse_args(argv)
    if args.record_times or args.record_calls:
        return _record_phase("times" if args.record_times else "calls",
                             args.record_times or args.record_calls)
    if args.worker is not None:
        kernels = load_manifest()
        compile_kernels(kernels[int(i)] for i in args.worker.split(",") if i)
        return 0
    if args.record:
        return _record_manifest()
    import time

    started = time.perf_counter()
    done = ensure_compiled(set(FEATURES), notify=print, processes=args.jobs)
    print(f"{'compiled' if done else 'cache already warm'} in "
          f"{time.perf_counter() - started:.1f} s")
    return 0


def _record_manifest() -> int:
    """Compile the reference runs into an empty cache (timing every kernel), then
    run them again from that cache to see which kernels they call from Python."""
    import json
    import tempfile

    with tempfile.TemporaryDirectory(prefix="blastvox-record-") as tmp:
        env = {**os.environ, "NUMBA_CACHE_DIR": str(Path(tmp) / "cache"),
               "BLASTVOX_PRECOMPILE": "0"}  # one process, or compile events go missing
        for phase in ("times", "calls"):
            subprocess.run([sys.executable, "-m", "blastvox.simulate.precompile",
                            f"--record-{phase}", str(Path(tmp) / f"{phase}.json")],
                           env=env, check=True)
        times = {(k, s): t for k, s, t in json.loads((Path(tmp) / "times.json").read_text())}
        calls = json.loads((Path(tmp) / "calls.json").read_text())
    kernels = [Kernel(feature, times.get((name, signature), 0.0), name, signature)
               for name, signature, feature in calls]
    order = {f: i for i, f in enumerate(FEATURES)}
    kernels.sort(key=lambda k: (order[k.feature], k.name, k.signature))
    header = ("# blastvox simulate kernels: feature, compile seconds (recorded), kernel, "
              "argument types\n# written by: python -m blastvox.simulate.precompile --record\n")
    MANIFEST.write_text(header + "".join(k.line() + "\n" for k in kernels))
    print(f"{MANIFEST}: {len(kernels)} kernels, {sum(k.seconds for k in kernels):.1f} s "
          f"of compilation")
    return 0


def _record_phase(phase: str, out: Path) -> int:
    import json
    import tempfile

    with tempfile.TemporaryDirectory(prefix="blastvox-record-") as tmp:
        if phase == "times":
            times = compile_times(lambda: reference_runs(Path(tmp)))
            rows = [[k, s, t] for (k, s), t in times.items()]
        else:
            rows = [[k, s, f] for (k, s), f in called_kernels(reference_runs(Path(tmp))).items()]
    out.write_text(json.dumps(sorted(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
