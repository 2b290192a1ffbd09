"""End-to-end tests of ``blastvox simulate`` (and ``info`` on SimCache files).

Every test runs the real command line in a subprocess (``python -m blastvox``),
each run in its own temporary directory, on small real models: boxes written
with trimesh and voxelized with ``blastvox voxelize`` (a few hundred voxels),
and the example building from ``examples/building``. Shots are a fraction of a
second, so a run costs little more than its imports once numba's on-disk cache
is warm (the very first compile of the simulator takes ~20 s; timeouts are
generous). The module fixtures start every run at once on a thread pool: first
the voxelize runs, then every simulate run; the tests check the results.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import tomllib
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from blastvox.cache import SimCache
from blastvox.model import VoxelModel

BUILDING = Path(__file__).resolve().parent.parent / "examples" / "building"
OUT = "out/sim.npz"  # every simulate run writes here, relative to its own directory
MODEL = "model.npz"  # every simulate run finds its model here
TIMEOUT_S = 300
G = 9.81
PREVIOUS = b"a previous output, to be left alone by a failed run"

Result = subprocess.CompletedProcess[str]


def run_cli(*args: str | Path, cwd: Path, env: dict[str, str] | None = None) -> Result:
    """Run ``python -m blastvox ARGS`` in ``cwd``; never raises on a non-zero exit."""
    return subprocess.run([sys.executable, "-m", "blastvox", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=TIMEOUT_S,
                          env=None if env is None else {**os.environ, **env})


def ok(result: Result) -> Result:
    assert result.returncode == 0, (
        f"exit {result.returncode}\nstdout:\n{result.stdout}\nstderr:\n{result.stderr}")
    return result


def info_json(path: Path) -> dict:
    return json.loads(ok(run_cli("info", path.name, "--json", cwd=path.parent)).stdout)


def assert_one_line_error(result: Result, *needles: str) -> str:
    """A failed run: exit != 0 and exactly one stderr line, ``blastvox: error: ...``,
    containing every needle."""
    assert result.returncode != 0, f"expected failure, got exit 0; stderr:\n{result.stderr}"
    assert "Traceback" not in result.stderr + result.stdout, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, f"expected one stderr line, got {len(lines)}:\n{result.stderr}"
    line = lines[0]
    assert line.startswith("blastvox: error: "), line
    for needle in needles:
        assert needle in line, f"{needle!r} not in error line {line!r}"
    return line


def listing(directory: Path) -> list[str]:
    """Every name in ``directory``, hidden ``.*.partial`` temporaries included."""
    return sorted(os.listdir(directory))


# --------------------------------------------------------------------------- inputs

#: Box meshes written with trimesh: file name -> extents, m (centred on the origin).
BOXES = {"wall.stl": (1.5, 0.75, 0.75), "box.stl": (1.0, 1.0, 1.0)}

#: Models: name -> voxelize arguments (``-o model.npz`` is added).
MODELS: dict[str, tuple[str, ...]] = {
    # 12 x 6 x 6 = 432 voxels, Z up, standing on the ground (72 foundation voxels)
    "wall": ("wall.stl", "--voxel-size", "0.125", "--up-axis", "Z", "-q"),
    # 4 x 4 x 4 = 64 voxels, free-floating, Z up and Y up
    "free_z": ("box.stl", "--voxel-size", "0.25", "--up-axis", "Z", "--ground", "none", "-q"),
    "free_y": ("box.stl", "--voxel-size", "0.25", "--up-axis", "Y", "--ground", "none", "-q"),
    # examples/building/scene.toml: ~4,600 conform voxels
    "building": ("--scene", "scene.toml", "-q"),
}

FAR = ("--charge", "1000,0,0:1")  # a shock that never arrives within the shot
SCENE_RUN = ("--scene", "scene.toml", "--duration", "0.2", "-q")


@dataclass(frozen=True)
class Spec:
    model: str | None  # MODELS key copied to ``model.npz`` (None: no model file)
    args: tuple[str, ...]  # simulate arguments (``-o out/sim.npz`` is added unless output=False)
    needles: tuple[str, ...] = ()  # for failing runs: what the error line must contain
    env: dict[str, str] = field(default_factory=dict)
    extra: tuple[str, ...] = ()  # extra inputs: "scene" (building files), "mesh", "truncated"
    output: bool = True
    existing: bool = False  # a previous output is already at out/sim.npz


#: Runs that must succeed: name -> Spec.
GOOD_RUNS: dict[str, Spec] = {
    "basic": Spec("wall", (MODEL, "--charge", "0,-3,0:5@0.05", "--duration", "0.23",
                           "--fps", "40", "--dt", "0.0025")),
    "damage_odd_dt": Spec("wall", (MODEL, "--charge", "0,-5,0:1", "--duration", "0.1",
                                   "--fps", "30", "--dt", "0.002", "--fracture", "DAMAGE",
                                   "--seed", "11", "--contact-substeps", "7")),
    "scene": Spec("building", (MODEL, *SCENE_RUN), extra=("scene",)),
    "threads1": Spec("building", (MODEL, *SCENE_RUN), extra=("scene",),
                     env={"NUMBA_NUM_THREADS": "1", "PYTHONHASHSEED": "1"}),
    "threads2": Spec("building", (MODEL, *SCENE_RUN), extra=("scene",),
                     env={"NUMBA_NUM_THREADS": "2", "PYTHONHASHSEED": "2"}),
    "still": Spec("wall", (MODEL, *FAR, "--gravity", "0", "--no-ground", "--duration", "0.5",
                           "-q")),
    "founded": Spec("wall", (MODEL, *FAR, "--duration", "0.5", "-q")),
    "fall_z": Spec("free_z", (MODEL, *FAR, "--no-ground", "--duration", "0.5", "--fps", "24",
                              "--dt", str(1 / 240), "-q")),
    "fall_y": Spec("free_y", (MODEL, *FAR, "--no-ground", "--duration", "0.5", "--fps", "24",
                              "--dt", str(1 / 240), "-q")),
}

CHARGE = ("--charge", "0,-5,0:1")

#: Runs that must fail with one error line containing the needles, writing nothing.
BAD_RUNS: dict[str, Spec] = {
    "missing_model": Spec(None, ("missing.npz", *CHARGE), ("missing.npz",)),
    "mesh_as_model": Spec(None, ("wall.stl", *CHARGE), ("wall.stl",), extra=("mesh",)),
    "truncated_model": Spec(None, ("truncated.npz", *CHARGE), ("truncated.npz",),
                            extra=("truncated",)),
    "charge_malformed": Spec("wall", (MODEL, "--charge", "1,2:5"), ("--charge", "1,2:5")),
    "charge_negative_mass": Spec("wall", (MODEL, "--charge", "0,0,0:-1"), ("--charge",)),
    "charge_negative_time": Spec("wall", (MODEL, "--charge", "0,0,0:1@-1"), ("--charge",)),
    "charge_empty_time": Spec("wall", (MODEL, "--charge", "0,0,0:1@"), ("--charge", "X,Y,Z:KG@T")),
    "dt_zero": Spec("wall", (MODEL, *CHARGE, "--dt", "0"), ("--dt",)),
    "fps_negative": Spec("wall", (MODEL, *CHARGE, "--fps", "-1"), ("--fps",)),
    "duration_nan": Spec("wall", (MODEL, *CHARGE, "--duration", "nan"), ("--duration",)),
    "gravity_negative": Spec("wall", (MODEL, *CHARGE, "--gravity", "-1"), ("--gravity",)),
    "contact_substeps_zero": Spec("wall", (MODEL, *CHARGE, "--contact-substeps", "0"),
                                ("--contact-substeps", ">= 1")),
    "fracture_foo": Spec("wall", (MODEL, *CHARGE, "--fracture", "foo"), ("--fracture", "foo")),
    "no_charges": Spec("wall", (MODEL,), (MODEL, "--charge")),
    "no_output": Spec("wall", (MODEL, *CHARGE), (MODEL, "-o"), output=False),
    "unknown_explosive": Spec("wall", (MODEL, *CHARGE, "--explosive", "unobtainium"),
                              ("unobtainium", "explosive")),
    "dt_zero_over_existing": Spec("wall", (MODEL, *CHARGE, "--dt", "0"), ("--dt",),
                                  existing=True),
    "unknown_explosive_over_existing": Spec(
        "wall", (MODEL, *CHARGE, "--explosive", "unobtainium"), ("unobtainium",),
        existing=True),
}


# --------------------------------------------------------------------------- fixtures


@dataclass
class Run:
    cwd: Path
    before: list[str]  # listing of cwd just before the run
    future: Future[Result]

    @property
    def result(self) -> Result:
        return self.future.result()

    @property
    def sim(self) -> Path:
        ok(self.result)
        return self.cwd / OUT


def write_boxes(directory: Path) -> None:
    import trimesh

    for name, extents in BOXES.items():
        trimesh.creation.box(extents=extents).export(directory / name)


@pytest.fixture(scope="module")
def pool() -> Iterator[ThreadPoolExecutor]:
    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1)) as executor:
        yield executor


@pytest.fixture(scope="module")
def meshes(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("meshes")
    write_boxes(directory)
    return directory


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory, pool: ThreadPoolExecutor,
           meshes: Path) -> dict[str, Path]:
    """Voxelize every model of :data:`MODELS` concurrently; name -> VoxelModel path."""
    futures = {}
    for name, args in MODELS.items():
        cwd = tmp_path_factory.mktemp(f"model_{name}")
        for file in BOXES:
            shutil.copy(meshes / file, cwd / file)
        for file in ("scene.toml", "building.glb"):
            shutil.copy(BUILDING / file, cwd / file)
        futures[name] = (cwd, pool.submit(run_cli, "voxelize", *args, "-o", MODEL, cwd=cwd))
    paths = {}
    for name, (cwd, future) in futures.items():
        ok(future.result())
        paths[name] = cwd / MODEL
    return paths


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory, pool: ThreadPoolExecutor,
         models: dict[str, Path], meshes: Path) -> dict[str, Run]:
    """Start every simulate run of this module concurrently; name -> Run."""
    started: dict[str, Run] = {}
    for name, spec in {**GOOD_RUNS, **BAD_RUNS}.items():
        cwd = tmp_path_factory.mktemp(name)
        (cwd / OUT).parent.mkdir()
        if spec.model is not None:
            shutil.copy(models[spec.model], cwd / MODEL)
        if "scene" in spec.extra:
            for file in ("scene.toml", "building.glb"):
                shutil.copy(BUILDING / file, cwd / file)
        if "mesh" in spec.extra:
            shutil.copy(meshes / "wall.stl", cwd / "wall.stl")
        if "truncated" in spec.extra:
            data = models["wall"].read_bytes()
            (cwd / "truncated.npz").write_bytes(data[: len(data) // 2])
        if spec.existing:
            (cwd / OUT).write_bytes(PREVIOUS)
        args = (*spec.args, "-o", OUT) if spec.output else spec.args
        started[name] = Run(cwd, listing(cwd),
                            pool.submit(run_cli, "simulate", *args, cwd=cwd, env=spec.env))
    return started


# --------------------------------------------------------------------------- help


def test_root_help_lists_simulate(tmp_path: Path) -> None:
    result = ok(run_cli("--help", cwd=tmp_path))
    assert "simulate" in result.stdout


def test_simulate_help_lists_flags(tmp_path: Path) -> None:
    result = ok(run_cli("simulate", "--help", cwd=tmp_path))
    for flag in ("--charge", "--dt", "--fps", "--duration", "--gravity", "--no-ground",
                 "--seed", "--scene", "--fracture", "--explosive", "--output"):
        assert flag in result.stdout, f"{flag} not in simulate --help"
    assert listing(tmp_path) == []


# --------------------------------------------------------------------------- good runs


def test_basic_run_info(runs: dict[str, Run], models: dict[str, Path]) -> None:
    run = runs["basic"]
    sim = run.sim
    assert listing(sim.parent) == ["sim.npz"]  # no temporaries left beside it
    assert "out/sim.npz" in run.result.stderr  # the summary line names the output
    model = VoxelModel.load(models["wall"]).summary()
    s = info_json(sim)
    assert s["kind"] == "SimCache"
    assert s["frame_count"] == math.floor(0.23 * 40) + 1 == 10
    assert s["fps"] == 40 and s["duration_s"] == 0.23
    assert math.isclose(s["dt_s"], 0.0025, rel_tol=1e-12)
    assert s["voxel_count"] == model["voxel_count"] == 432
    assert s["charge_count"] == 1
    assert s["fracture"] == "pressure-impulse" and s["seed"] == 0  # the default
    assert 1 <= s["piece_count"] <= s["voxel_count"]
    assert 0 <= s["moving_piece_count"] <= s["piece_count"]
    assert 0 < s["broken_link_count"] <= model["link_count"]  # 5 kg at 3 m breaks concrete
    assert 0 <= s["destroyed_voxel_count"] <= s["voxel_count"]
    assert s["moving_piece_count"] > 0

    cache = SimCache.load(sim)
    assert cache.model.voxel_count == 432
    np.testing.assert_allclose(cache.frame_time, np.arange(10) / 40, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(cache.charge_position, [[0.0, -3.0, 0.0]])
    np.testing.assert_array_equal(cache.charge_tnt_kg, [5.0])
    np.testing.assert_array_equal(cache.charge_time, [0.05])
    # the shock front starts at the detonation time and then only grows
    radius = cache.shock_radius[:, 0]
    assert np.all(radius[cache.frame_time < 0.05] == 0)
    assert np.all(radius[cache.frame_time > 0.05] > 0)
    assert np.all(np.diff(radius) >= 0)
    assert cache.piece_position.shape == (10, s["piece_count"], 3)
    assert np.all(np.isfinite(cache.piece_position))
    q = cache.piece_orientation.astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-5)
    assert cache.voxel_piece.min() >= 0 and cache.voxel_piece.max() < s["piece_count"]


def test_info_table_for_simcache(runs: dict[str, Run]) -> None:
    sim = runs["basic"].sim
    s = info_json(sim)
    text = ok(run_cli("info", sim.name, cwd=sim.parent)).stdout
    assert "SimCache" in text
    assert "piece_count" in text and str(s["piece_count"]) in text
    assert "frame_count" in text


def test_odd_dt_is_shortened_and_damage_fracture_recorded(runs: dict[str, Run]) -> None:
    run = runs["damage_odd_dt"]
    s = SimCache.load(run.sim).summary()
    stderr = run.result.stderr
    assert "warning" in stderr and "does not divide" in stderr, stderr
    # 1/30 s frames at dt <= 0.002 s: 17 steps per frame
    assert math.isclose(s["dt_s"], 1 / (30 * 17), rel_tol=1e-12)
    assert s["dt_s"] <= 0.002
    assert s["frame_count"] == math.floor(0.1 * 30) + 1
    assert s["fracture"] == "damage"
    assert s["seed"] == 11
    assert s["piece_count"] >= 1
    assert SimCache.load(run.sim).meta["settings"]["contact_substeps"] == 7


def test_scene_charges_come_from_the_scene(runs: dict[str, Run]) -> None:
    run = runs["scene"]
    cache = SimCache.load(run.sim)
    s = cache.summary()
    # the example's charges (their positions, masses and times are edited with the example)
    charges = tomllib.loads((BUILDING / "scene.toml").read_text())["charges"]
    assert s["charge_count"] == len(charges) >= 1
    assert s["seed"] == 7  # the scene's seed
    assert s["frame_count"] == math.floor(0.2 * 24) + 1
    assert s["broken_link_count"] > 0 and s["piece_count"] > 1
    assert all(c.get("explosive", "TNT") == "TNT" for c in charges)  # TNT: mass_kg is TNT kg
    np.testing.assert_array_equal(cache.charge_position, [c["position"] for c in charges])
    np.testing.assert_array_equal(cache.charge_tnt_kg, [c["mass_kg"] for c in charges])
    np.testing.assert_array_equal(cache.charge_time, [c.get("time_s", 0.0) for c in charges])
    assert listing(run.cwd) == ["building.glb", MODEL, "out", "scene.toml"]  # -o wins


def test_thread_count_and_hash_seed_do_not_change_bytes(runs: dict[str, Run]) -> None:
    """Two processes that differ in what commonly breaks determinism: the thread count
    (a parallel kernel's reductions run in a thread-dependent order) and Python's
    string hash seed (set and str-keyed iteration order). A cache that depended on
    either differs here (see the next test: the seeds do reach the runs), and so would
    one that differed from run to run of the same command (``scene`` is a third run)."""
    one, two = (runs[n].sim.read_bytes() for n in ("threads1", "threads2"))
    assert one == two
    assert one == runs["scene"].sim.read_bytes()


def test_the_determinism_runs_see_different_hash_orders() -> None:
    # the environment of threads1/threads2 really changes iteration order, so the
    # comparison above would catch a cache built from a set of names
    code = "print(list({'dust', 'fire', 'smoke', 'fireball', 'house', 'roof', 'wall'}))"
    orders = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             env={**os.environ, "PYTHONHASHSEED": seed},
                             check=True).stdout for seed in ("1", "2")}
    assert len(orders) == 2


def test_no_gravity_far_charge_keeps_everything_still(runs: dict[str, Run]) -> None:
    cache = SimCache.load(runs["still"].sim)
    assert len(cache.link_break_link) == 0
    assert cache.frame_count == 13
    moved = np.abs(cache.piece_position.astype(np.float64)
                   - cache.piece_position[0].astype(np.float64)).max()
    assert moved < 1e-6, moved
    turned = np.abs(cache.piece_orientation.astype(np.float64)
                    - cache.piece_orientation[0].astype(np.float64)).max()
    assert turned < 1e-6, turned


def test_founded_structure_does_not_fall(runs: dict[str, Run]) -> None:
    cache = SimCache.load(runs["founded"].sim)
    moved = np.abs(cache.piece_position.astype(np.float64)
                   - cache.piece_position[0].astype(np.float64)).max()
    assert moved < 1e-6, moved


@pytest.mark.parametrize("case, up", [("fall_z", 2), ("fall_y", 1)])
def test_free_object_falls_along_its_up_axis(case: str, up: int,
                                             runs: dict[str, Run]) -> None:
    cache = SimCache.load(runs[case].sim)
    assert cache.piece_count == 1 and len(cache.link_break_link) == 0
    position = cache.piece_position.astype(np.float64)
    lowest = int(np.argmin(position[-1, :, up]))
    drop = position[-1, lowest] - position[0, lowest]
    t, dt = float(cache.frame_time[-1]), float(cache.meta["dt"])
    assert math.isclose(t, 0.5) and math.isclose(dt, 1 / 240)
    # semi-implicit Euler: exactly -g t (t + dt) / 2 after t/dt steps; allow twice that offset
    assert abs(drop[up] - (-G * t * t / 2)) <= G * t * dt, (drop, -G * t * t / 2)
    assert drop[up] < 0
    sideways = np.delete(drop, up)
    assert np.abs(sideways).max() < 1e-6, drop


# --------------------------------------------------------------------------- bad inputs


@pytest.mark.parametrize("case", list(BAD_RUNS))
def test_bad_input_fails_cleanly(case: str, runs: dict[str, Run]) -> None:
    run = runs[case]
    assert_one_line_error(run.result, *BAD_RUNS[case].needles)
    assert run.result.stdout == ""
    assert listing(run.cwd) == run.before
    if BAD_RUNS[case].existing:
        assert listing(run.cwd / "out") == ["sim.npz"]  # untouched, no temporaries
        assert (run.cwd / OUT).read_bytes() == PREVIOUS
    else:
        assert listing(run.cwd / "out") == [], "a failed run left files in the output directory"


# --------------------------------------------------------------------------- info on SimCache


@pytest.mark.parametrize("kind", ["truncated", "missing", "foreign_schema"])
def test_info_rejects_broken_caches(kind: str, tmp_path: Path, runs: dict[str, Run]) -> None:
    target = tmp_path / f"{kind}.npz"
    if kind == "truncated":
        data = runs["basic"].sim.read_bytes()
        target.write_bytes(data[: len(data) // 2])
    elif kind == "foreign_schema":
        meta = json.dumps({"schema": "someone.Else", "schema_version": 1}).encode()
        np.savez(target, meta=np.frombuffer(meta, dtype=np.uint8))
    for extra in ((), ("--json",)):
        result = run_cli("info", target.name, *extra, cwd=tmp_path)
        assert_one_line_error(result, target.name)
        assert result.stdout == ""


def test_progress_bar_starts_with_stepping_not_with_compilation():
    # the steps/s shown count stepping only, not first-run compilation
    import io
    import threading

    from rich.console import Console

    from blastvox.cli.simulate_cmd import _Progress

    out = io.StringIO()
    console = Console(file=out, force_terminal=True, width=100)
    before = threading.active_count()
    with _Progress(enabled=True, console=console) as progress:
        progress.note("compiling 25 simulation kernels on 2 processes (first run only)")
        assert threading.active_count() == before
        progress.update(0.1, 24, 240)
        assert threading.active_count() == before + 1
        progress.update(1.0, 240, 240)
    text = out.getvalue()
    assert "compiling 25 simulation kernels" in text
    assert "t = 1.000 s" in text and "steps/s" in text


@pytest.mark.parametrize("dt, fps, steps", [(0.0020833333, 120.0, 4), (1 / 480, 120.0, 4),
                                            (0.0041666, 24.0, 11), (0.002, 30.0, 17)])
def test_a_dt_typed_to_a_few_places_divides_the_frame_it_rounds(dt, fps, steps) -> None:
    """0.0020833333 s (1/480 s to ten places) with 120 fps frames ran 5 steps per frame of
    1/600 s, and warned that dt does not divide the frame; a dt within a millionth of
    dividing it now does. One that really does not (0.0041666: 10.0002 per frame at 24 fps)
    is still shortened."""
    from blastvox.simulate.settings import SimSettings

    settings = SimSettings(dt=dt, fps=fps)
    assert settings.steps_per_frame() == steps
    assert settings.step_seconds() <= dt * (1 + 1e-6)
