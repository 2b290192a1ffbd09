"""State containers for numba kernels: compile, cache-load, dispatch and run time.

    python benchmarks/containers.py            # best of 3 of each measurement
    python benchmarks/containers.py --quick    # one of each (about a minute)

Issue 14 groups the simulator's state into a few typed containers so that no
kernel takes dozens of arrays, and asks to measure the candidates and pick.
This compares one representative kernel written four ways:

(a) positional arrays: the kernel and its helpers take every array as its own
    argument (blastvox before issue 14; the kernel below takes 20);
(b) ``typing.NamedTuple`` of arrays (what ``blastvox.simulate.state`` uses);
(c) ``numba.experimental.structref`` (built by a cached ``@njit`` factory);
(d) ``numba.experimental.jitclass``. numba's cache cannot hold a function that
    takes a jitclass: the jitclass type is keyed by the class object's address,
    new in every process, so with ``cache=True`` every process misses and
    appends yet another entry to the cache file. Its kernel and helpers are
    therefore compiled without ``cache=True``, and its "warm" column is one more
    full compile (so is its ``__init__``, which numba never caches).

The kernel is a velocity and position integration over B bodies in the
simulator's style: 14 body arrays (mass, inverse inertia, rotation, position,
quaternion, linear and angular momentum, impulses, four flags and the count),
unpacked at the top of the kernel; two helpers called per body that take the
container and the body's index (a moving test and the rotation: omega = R I^-1
R^T L, quaternion step, rotation matrix), as ``blastvox.jit.helper`` functions
(no CPython wrapper; copied, so that nothing imports blastvox, whose import
moves numba's cache directory). Each candidate's module is generated from the same body
of code, so they differ only in how the arrays reach it; a checksum of the end
state after 20 calls shows that all four compute the same bits.

Columns (each measurement in a fresh Python process, after ``import numba`` and
numba's one-off set-up, i.e. compiling a trivial function, which every
candidate pays alike and which is printed on its own):

* cold: with an empty ``NUMBA_CACHE_DIR``, s: import the candidate module
  (define the types), build the container from NumPy arrays, first call with
  B = 10 (numba compiles the kernel, its helpers and any constructor);
* warm: the same in a second fresh process with the same cache directory;
* dispatch: wall time of one call from Python with B = 10 bodies (unboxing the
  arguments dominates), µs;
* run: one call with B = 100,000 bodies, ms.

Best of ``--repeat`` (default 3, 1 with ``--quick``), each repeat with new cache
directories. Prints the machine line, the table, the breakdown and the load
average at the end. Exits 1 only if a worker crashes.

Three runs on 2 shared cores (AMD EPYC, numba 0.68.1, load average 0.7 to
3.0), (a) / (b) / (c) / (d): cold 1.4 / 1.6 / 1.9 / 3.3 s; warm 0.03 / 0.03 /
0.04 / 3.3 s; dispatch 3.5 / 6.2 to 6.4 / 2.8 / 2.0 to 3.2 µs; run 7.4 / 5.2
to 5.4 / 5.3 to 5.5 / 5.3 to 5.9 ms.

For the NamedTuples of ``blastvox.simulate.state`` that means: numba caches
them like plain arrays (as fast warm), they need no compiled constructor and no
compiled accessors (Python reads and replaces fields directly), and the kernel
runs as fast as with a structref or a jitclass (faster than with 20 positional
arrays here). Their price: about 0.2 s (15 %) more compilation than positional
arrays for this kernel, and about 3 µs more per call from Python: numba's
dispatcher types a NamedTuple argument more slowly than the same arrays passed
one by one. In the simulator that shows on small shots: ``any_moving`` takes
6.6 µs a call with the 19-array ``Bodies`` against 2.1 µs with the four flag
arrays it took before, a step of 5 debris pieces 76 µs against 40 µs, the
house's 960 steps 0.22 s in-process against 0.15 s. A structref dispatches
faster, but needs a compiled constructor (+0.6 s cold) and a compiled getter
or setter for each field Python touches; a jitclass compiles again in every
process (3.3 s for this one kernel), which the start-up targets rule out.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _machine import machine, repeat_count  # benchmarks/ is on sys.path when run as a script

CANDIDATES = ("positional", "namedtuple", "structref", "jitclass")
LABELS = {"positional": "(a) positional arrays", "namedtuple": "(b) typing.NamedTuple",
          "structref": "(c) numba structref", "jitclass": "(d) numba jitclass"}
FIELDS = ("mass", "inv_inertia", "rot", "pos", "quat", "lin", "ang", "impulse", "angular",
          "fixed", "live", "dust", "asleep", "count")
JITCLASS_SPEC = {"mass": "float64[::1]", "inv_inertia": "float64[:, :, ::1]",
                 "rot": "float64[:, :, ::1]", "pos": "float64[:, ::1]",
                 "quat": "float64[:, ::1]", "lin": "float64[:, ::1]", "ang": "float64[:, ::1]",
                 "impulse": "float64[:, ::1]", "angular": "float64[:, ::1]",
                 "fixed": "boolean[::1]", "live": "boolean[::1]", "dust": "boolean[::1]",
                 "asleep": "boolean[::1]", "count": "int64[::1]"}
SMALL, LARGE = 10, 100_000
DISPATCH_CALLS = 20_000
SCALARS = (1.0 / 240.0, 0.0, 0.0, -9.81, 0.999, 0.998)  # dt, gravity, drag decays

# --------------------------------------------------------------------------- the kernel

_SPIN = """\
    l0, l1, l2 = ang[b, 0], ang[b, 1], ang[b, 2]
    r0 = rot[b, 0, 0] * l0 + rot[b, 1, 0] * l1 + rot[b, 2, 0] * l2
    r1 = rot[b, 0, 1] * l0 + rot[b, 1, 1] * l1 + rot[b, 2, 1] * l2
    r2 = rot[b, 0, 2] * l0 + rot[b, 1, 2] * l1 + rot[b, 2, 2] * l2
    s0 = inv[b, 0, 0] * r0 + inv[b, 0, 1] * r1 + inv[b, 0, 2] * r2
    s1 = inv[b, 1, 0] * r0 + inv[b, 1, 1] * r1 + inv[b, 1, 2] * r2
    s2 = inv[b, 2, 0] * r0 + inv[b, 2, 1] * r1 + inv[b, 2, 2] * r2
    wx = rot[b, 0, 0] * s0 + rot[b, 0, 1] * s1 + rot[b, 0, 2] * s2
    wy = rot[b, 1, 0] * s0 + rot[b, 1, 1] * s1 + rot[b, 1, 2] * s2
    wz = rot[b, 2, 0] * s0 + rot[b, 2, 1] * s1 + rot[b, 2, 2] * s2
    h = 0.5 * dt
    qw, qx, qy, qz = quat[b, 0], quat[b, 1], quat[b, 2], quat[b, 3]
    nw = qw - h * (wx * qx + wy * qy + wz * qz)
    nx = qx + h * (wx * qw + wy * qz - wz * qy)
    ny = qy + h * (wy * qw + wz * qx - wx * qz)
    nz = qz + h * (wz * qw + wx * qy - wy * qx)
    k = 1.0 / math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    qw, qx, qy, qz = nw * k, nx * k, ny * k, nz * k
    quat[b, 0], quat[b, 1], quat[b, 2], quat[b, 3] = qw, qx, qy, qz
    rot[b, 0, 0] = 1.0 - 2.0 * (qy * qy + qz * qz)
    rot[b, 0, 1] = 2.0 * (qx * qy - qw * qz)
    rot[b, 0, 2] = 2.0 * (qx * qz + qw * qy)
    rot[b, 1, 0] = 2.0 * (qx * qy + qw * qz)
    rot[b, 1, 1] = 1.0 - 2.0 * (qx * qx + qz * qz)
    rot[b, 1, 2] = 2.0 * (qy * qz - qw * qx)
    rot[b, 2, 0] = 2.0 * (qx * qz - qw * qy)
    rot[b, 2, 1] = 2.0 * (qy * qz + qw * qx)
    rot[b, 2, 2] = 1.0 - 2.0 * (qx * qx + qy * qy)
"""

_LOOP = """\
    for b in range(count[0]):
        if not {moving}:
            continue
        m = mass[b]
        lin[b, 0] = (lin[b, 0] + impulse[b, 0] + m * gx * dt) * lin_decay
        lin[b, 1] = (lin[b, 1] + impulse[b, 1] + m * gy * dt) * lin_decay
        lin[b, 2] = (lin[b, 2] + impulse[b, 2] + m * gz * dt) * lin_decay
        for a in range(3):
            ang[b, a] = (ang[b, a] + angular[b, a]) * ang_decay
            pos[b, a] += lin[b, a] / m * dt
        {spin}
"""

_SCALARS = "dt, gx, gy, gz, lin_decay, ang_decay"

#: ``blastvox.jit.helper``, copied so that no candidate imports blastvox (whose import
#: points numba's cache at a directory keyed on blastvox's own sources)
_HELPER = '''from numba.core.registry import CPUDispatcher


class HelperDispatcher(CPUDispatcher):
    def __call__(self, *args, **kwargs):
        raise TypeError("compiled for other numba functions only")


def helper(func):
    dispatcher = HelperDispatcher(py_func=func, locals={}, targetoptions={
        "nopython": True, "boundscheck": None, "no_cpython_wrapper": True,
        "no_cfunc_wrapper": True})
    dispatcher.enable_caching()
    return dispatcher
'''


def _container_functions(cache: str) -> str:
    """Helpers and kernel taking one container ``bodies``."""
    unpack = "    " + ", ".join(FIELDS) + " = " + ", ".join(f"bodies.{f}" for f in FIELDS)
    return f'''
@helper
def moving(bodies, b):
    return bodies.live[b] & (not (bodies.fixed[b] | bodies.dust[b] | bodies.asleep[b]))


@helper
def spin(bodies, b, dt):
    rot, inv, ang, quat = bodies.rot, bodies.inv_inertia, bodies.ang, bodies.quat
{_SPIN}

@nb.njit(cache={cache})
def integrate(bodies, {_SCALARS}):
{unpack}
{_LOOP.format(moving="moving(bodies, b)", spin="spin(bodies, b, dt)")}

def call_args(container, scalars):
    return (container, *scalars)
'''


def _source(name: str) -> str:
    """The candidate module ``name``'s source."""
    head = ("import math\n\nimport numba as nb\nimport numpy as np  # noqa: F401\n"
            + _HELPER + "\n\n")
    if name == "positional":
        return head + f'''

@helper
def moving(live, fixed, dust, asleep, b):
    return live[b] & (not (fixed[b] | dust[b] | asleep[b]))


@helper
def spin(rot, inv, ang, quat, b, dt):
{_SPIN}

@nb.njit(cache=True)
def integrate({", ".join(FIELDS)}, {_SCALARS}):
{_LOOP.format(moving="moving(live, fixed, dust, asleep, b)",
              spin="spin(rot, inv_inertia, ang, quat, b, dt)")}

def build(arrays):
    return tuple(arrays)


def call_args(container, scalars):
    return (*container, *scalars)
'''
    if name == "namedtuple":
        fields = "\n".join(f"    {f}: np.ndarray" for f in FIELDS)
        return head + f'''from typing import NamedTuple


class Bodies(NamedTuple):
{fields}


def build(arrays):
    return Bodies(*arrays)
{_container_functions("True")}'''
    if name == "structref":
        args = ", ".join(FIELDS)
        return head + f'''from numba.core import types
from numba.experimental import structref


@structref.register
class BodiesType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class Bodies(structref.StructRefProxy):
    pass


structref.define_proxy(Bodies, BodiesType, {list(FIELDS)!r})


@nb.njit(cache=True)
def make({args}):
    return Bodies({args})


def build(arrays):
    return make(*arrays)
{_container_functions("True")}'''
    if name == "jitclass":
        spec = ", ".join(f"({f!r}, nb.{JITCLASS_SPEC[f]})" for f in FIELDS)
        init = "\n".join(f"        self.{f} = {f}" for f in FIELDS)
        head = head.replace("    dispatcher.enable_caching()\n", "")  # see the module doc
        return head + f'''from numba.experimental import jitclass


@jitclass([{spec}])
class Bodies:
    def __init__(self, {", ".join(FIELDS)}):
{init}


def build(arrays):
    return Bodies(*arrays)
{_container_functions("False")}'''
    raise ValueError(name)


def write_candidates(directory: Path) -> None:
    """One module ``candidate_<name>.py`` per candidate in ``directory``."""
    for name in CANDIDATES:
        (directory / f"candidate_{name}.py").write_text(_source(name))


# --------------------------------------------------------------------------- the worker


def bodies(count: int, seed: int = 0) -> list[np.ndarray]:
    """The 14 arrays of ``count`` bodies (seeded): a tenth fixed, a twentieth asleep."""
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=(count, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    w, x, y, z = quat.T
    rot = np.ascontiguousarray(np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)],
        axis=-2))
    inv = np.zeros((count, 3, 3))
    inv[:, [0, 1, 2], [0, 1, 2]] = rng.uniform(0.5, 2.0, (count, 3))
    arrays = {"mass": rng.uniform(1.0, 10.0, count), "inv_inertia": inv, "rot": rot,
              "pos": rng.normal(size=(count, 3)), "quat": quat,
              "lin": rng.normal(size=(count, 3)), "ang": rng.normal(size=(count, 3)),
              "impulse": 0.01 * rng.normal(size=(count, 3)),
              "angular": 0.01 * rng.normal(size=(count, 3)),
              "fixed": rng.random(count) < 0.1, "live": np.ones(count, dtype=bool),
              "dust": np.zeros(count, dtype=bool), "asleep": rng.random(count) < 0.05,
              "count": np.array([count], dtype=np.int64)}
    return [np.ascontiguousarray(arrays[f]) for f in FIELDS]


def _cache_counts(module) -> tuple[int, int]:
    """(compiled, loaded): cache misses and hits of the module's numba functions."""
    from numba.core.dispatcher import Dispatcher

    misses = hits = 0
    for obj in vars(module).values():
        if isinstance(obj, Dispatcher):
            misses += sum(obj.stats.cache_misses.values())
            hits += sum(obj.stats.cache_hits.values())
    return misses, hits


def worker(name: str, directory: Path, measure: bool, repeat: int) -> dict:
    """First use of candidate ``name`` (imported from ``directory``); with ``measure``,
    also dispatch overhead, run time and the end-state checksum."""
    import numba

    # numba's one-off set-up (LLVM, the CPU target) is not the candidate's: done first,
    # by compiling a trivial function (never cached)
    started = time.perf_counter()
    numba.njit(lambda x: x + 1)(1)
    setup = time.perf_counter() - started
    sys.path.insert(0, str(directory))
    small = bodies(SMALL)
    started = time.perf_counter()
    module = importlib.import_module(f"candidate_{name}")
    defined = time.perf_counter()
    container = module.build(small)
    built = time.perf_counter()
    module.integrate(*module.call_args(container, SCALARS))
    first = time.perf_counter()
    compiled, loaded = _cache_counts(module)
    out = {"setup": setup, "define": defined - started, "build": built - defined,
           "first": first - built, "total": first - started, "compiled": compiled, "loaded": loaded}
    if not measure:
        return out
    kernel = module.integrate
    args = module.call_args(container, SCALARS)
    best = float("inf")
    for _ in range(max(repeat, 3)):
        started = time.perf_counter()
        for _ in range(DISPATCH_CALLS):
            kernel(*args)
        best = min(best, (time.perf_counter() - started) / DISPATCH_CALLS)
    out["dispatch_us"] = 1e6 * best
    args = module.call_args(module.build(bodies(LARGE)), SCALARS)
    kernel(*args)
    best = float("inf")
    for _ in range(max(repeat, 3)):
        started = time.perf_counter()
        kernel(*args)
        best = min(best, time.perf_counter() - started)
    out["run_ms"] = 1e3 * best
    check = bodies(1_000, seed=1)
    args = module.call_args(module.build(check), SCALARS)
    for _ in range(20):
        kernel(*args)
    digest = hashlib.sha1()
    for array in check:
        digest.update(array.tobytes())
    out["checksum"] = digest.hexdigest()[:12]
    return out


def run_worker(name: str, directory: Path, cache: Path, measure: bool, repeat: int) -> dict:
    """:func:`worker` in a fresh process with NUMBA_CACHE_DIR = ``cache``."""
    proc = subprocess.run(
        [sys.executable, __file__, "--worker", name, "--dir", str(directory),
         "--repeat", str(repeat), *(["--measure"] if measure else [])],
        capture_output=True, text=True, env={**os.environ, "NUMBA_CACHE_DIR": str(cache)})
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"]
        raise RuntimeError(f"{name} worker crashed: {lines[-1]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------- report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one run of each measurement")
    parser.add_argument("--repeat", type=int, help="cold/warm pairs per candidate, best "
                        "counts (default: 3, or 1 with --quick)")
    parser.add_argument("--worker", choices=CANDIDATES, help=argparse.SUPPRESS)
    parser.add_argument("--dir", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    args.repeat = repeat_count(parser, args)
    if args.worker is not None:
        print(json.dumps(worker(args.worker, args.dir, args.measure, args.repeat)))
        return 0

    started = time.perf_counter()
    print(machine(("blastvox", "numpy", "numba")))
    print(f"\nCommand: `python benchmarks/containers.py{' --quick' if args.quick else ''}`\n",
          flush=True)
    cold: dict[str, list[dict]] = {n: [] for n in CANDIDATES}
    warm: dict[str, list[dict]] = {n: [] for n in CANDIDATES}
    crashed = False
    with tempfile.TemporaryDirectory(prefix="blastvox-containers-") as tmp:
        directory = Path(tmp)
        write_candidates(directory)
        for r in range(args.repeat):  # candidates interleaved: load changes hit all alike
            for name in CANDIDATES:
                cache = directory / f"cache-{name}-{r}"
                cache.mkdir()
                try:
                    cold[name].append(run_worker(name, directory, cache, False, args.repeat))
                    warm[name].append(run_worker(name, directory, cache, r == 0,
                                                 args.repeat))
                except RuntimeError as exc:
                    crashed = True
                    print(f"error: {exc}", flush=True)
    setup = min((x["setup"] for runs in (*cold.values(), *warm.values()) for x in runs),
                default=float("nan"))
    print(f"Kernel: velocity and position integration of B bodies, 14 body arrays, two "
          f"helpers per body; best of {args.repeat} for cold and warm (fresh processes, "
          f"after `import numba` and numba's one-off set-up, {setup:.2f} s at best: its "
          f"first compile, of a trivial function), of {max(args.repeat, 3)} for dispatch "
          f"and run.\n")
    print("| container | numba cache | cold s (empty cache: define, build, first call) | "
          f"warm s (2nd process) | dispatch µs/call, B = {SMALL} | "
          f"run ms, B = {LARGE:,} |")
    print("|---|---|--:|--:|--:|--:|")
    rows = {}
    for name in CANDIDATES:
        if not cold[name] or not warm[name]:
            print(f"| {LABELS[name]} | — | error | — | — | — |")
            continue
        c = min(cold[name], key=lambda x: x["total"])
        w = min(warm[name], key=lambda x: x["total"])
        m = next(x for x in warm[name] if "run_ms" in x)
        rows[name] = (c, w, m)
        cached = "no (compiles in every process)" if name == "jitclass" else "yes"
        print(f"| {LABELS[name]} | {cached} | {c['total']:.2f} | {w['total']:.2f} | "
              f"{m['dispatch_us']:.1f} | {m['run_ms']:.2f} |")
    print("\nBreakdown (s; the best cold and warm runs), numba functions compiled / loaded "
          "from the cache, and the end state's checksum after 20 calls with B = 1,000:\n")
    print("| container | cold: define | build | first call | compiled | warm: define | "
          "build | first call | compiled / loaded | checksum |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|---|")
    for name, (c, w, m) in rows.items():
        print(f"| {LABELS[name]} | {c['define']:.3f} | {c['build']:.3f} | {c['first']:.2f} | "
              f"{c['compiled']} | {w['define']:.3f} | {w['build']:.3f} | {w['first']:.3f} | "
              f"{w['compiled']} / {w['loaded']} | `{m['checksum']}` |")
    sums = {m["checksum"] for _, _, m in rows.values()}
    if len(sums) > 1:
        print("\nThe candidates' end states differ: they do not run the same arithmetic.")
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"\nLoad average at the end: {load}; wall time of this run "
          f"{time.perf_counter() - started:.0f} s.")
    return 1 if crashed else 0


if __name__ == "__main__":
    sys.exit(main())
