"""End-to-end tests of ``blastvox voxelize`` / ``info`` / ``materials``.

Every test runs the real command line in a subprocess (``python -m blastvox``)
with a temporary working directory, on the real meshes in ``tests/data``.
Resolutions are small, so a ``voxelize`` run costs about as much as its
imports (~2 s); the module fixture ``runs`` therefore starts every voxelize
run at once on a thread pool, each in its own directory, and the tests check
the results.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import blastvox

DATA = Path(__file__).parent / "data"
BUILDING = Path(__file__).resolve().parent.parent / "examples" / "building"
BUNNY = DATA / "bunny.ply"
SMALL = ("--resolution", "14")
OUT = "out/model.npz"  # every voxelize run writes here, relative to its own directory
SUMMARY_KEYS = {"voxel_count", "link_count", "object_count", "foundation_voxel_count",
                "total_volume_m3", "total_mass_kg", "bounds_m"}
TIMEOUT_S = 300

Result = subprocess.CompletedProcess[str]


def run_cli(*args: str | Path, cwd: Path) -> Result:
    """Run ``python -m blastvox ARGS`` in ``cwd``; never raises on a non-zero exit."""
    return subprocess.run([sys.executable, "-m", "blastvox", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=TIMEOUT_S)


def ok(result: Result) -> Result:
    assert result.returncode == 0, (
        f"exit {result.returncode}\nstdout:\n{result.stdout}\nstderr:\n{result.stderr}")
    return result


def info_json(path: Path) -> dict:
    return json.loads(ok(run_cli("info", path, "--json", cwd=path.parent)).stdout)


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


def squash(text: str) -> str:
    """Collapse whitespace (rich wraps long stderr lines)."""
    return re.sub(r"\s+", " ", text)


def listing(directory: Path) -> list[str]:
    """Every name in ``directory``, hidden ``.*.partial`` temporaries included."""
    return sorted(os.listdir(directory))


# --------------------------------------------------------------------------- inputs

NAN_TETRAHEDRON = """\
v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 nan
f 1 3 2
f 1 2 4
f 2 3 4
f 3 1 4
"""

TYPO_SCENE = """\
seed = 1
[[objects]]
mesh = "{mesh}"
resolutoin = 12
[output]
model = "out/scene.npz"
"""

ZERO_SIZE_SCENE = """\
seed = 1
[[objects]]
mesh = "{mesh}"
voxel_size = 0
[output]
model = "out/scene.npz"
"""

#: Files a run needs in its directory: name -> text (str), bytes, or a file to copy (Path).
INPUT_FILES: dict[str, dict[str, str | bytes | Path]] = {
    "empty": {"empty.stl": b""},
    "nan": {"nan.obj": NAN_TETRAHEDRON},
    "scene_typo": {"typo.toml": TYPO_SCENE.format(mesh=BUNNY.as_posix())},
    "scene_zero_size": {"zero.toml": ZERO_SIZE_SCENE.format(mesh=BUNNY.as_posix())},
    "building": {"scene.toml": BUILDING / "scene.toml",
                 "building.glb": BUILDING / "building.glb"},
}

#: Runs that must succeed: name -> voxelize arguments (``-o out/model.npz`` is added).
GOOD_RUNS: dict[str, tuple[str | Path, ...]] = {
    "bunny": (BUNNY, *SMALL),
    "jitter_seed5_a": (BUNNY, *SMALL, "--jitter", "0.3", "--seed", "5", "-q"),
    "jitter_seed5_b": (BUNNY, *SMALL, "--jitter", "0.3", "--seed", "5", "-q"),
    "jitter_seed6": (BUNNY, *SMALL, "--jitter", "0.3", "--seed", "6", "-q"),
    "ground_none": (BUNNY, *SMALL, "--ground", "none", "-q"),
    "multibody": (DATA / "multibody.stl", "--up-axis", "Z", "--resolution", "16"),
    "truck": (DATA / "CesiumMilkTruck.glb", "--resolution", "16"),
    "building": ("--scene", "scene.toml", "-q"),
}

#: Runs that must fail: name -> (voxelize arguments, what the error line must contain).
BAD_INPUTS: dict[str, tuple[tuple[str | Path, ...], tuple[str, ...]]] = {
    "soup": ((DATA / "soup.stl", *SMALL), ("soup.stl",)),
    "empty": (("empty.stl", *SMALL), ("empty.stl",)),
    "nan": (("nan.obj", *SMALL), ("nan.obj",)),
    "missing": (("missing.stl", *SMALL), ("missing.stl",)),
    "unknown_material": ((BUNNY, *SMALL, "--material", "unobtainium"),
                         ("bunny.ply", "--material", "unobtainium")),
    "voxel_size_zero": ((BUNNY, "--voxel-size", "0"), ("--voxel-size",)),
    "voxel_size_negative": ((BUNNY, "--voxel-size=-1"), ("--voxel-size",)),
    "budget": ((BUNNY, *SMALL, "--max-voxels", "10"), ("bunny.ply", "--max-voxels")),
    "scene_typo": (("--scene", "typo.toml"), ("typo.toml", "resolutoin")),
    "scene_zero_size": (("--scene", "zero.toml"), ("zero.toml", "voxel_size")),
}

#: Failing runs repeated with the bunny model already at the output path.
OVER_EXISTING = ("soup", "budget", "scene_zero_size")


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
    def model(self) -> Path:
        ok(self.result)
        return self.cwd / OUT


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Run]]:
    """Start every voxelize run of this module concurrently; name -> Run."""
    started: dict[str, Run] = {}

    def prepare(name: str, inputs: str) -> Path:
        cwd = tmp_path_factory.mktemp(name)
        for file, content in INPUT_FILES.get(inputs, {}).items():
            if isinstance(content, Path):
                shutil.copy(content, cwd / file)
            elif isinstance(content, bytes):
                (cwd / file).write_bytes(content)
            else:
                (cwd / file).write_text(content)
        (cwd / OUT).parent.mkdir()
        return cwd

    def over_existing(cwd: Path, args: tuple[str | Path, ...]) -> Result:
        shutil.copy(started["bunny"].model, cwd / OUT)
        return run_cli("voxelize", *args, "-o", OUT, cwd=cwd)

    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1)) as pool:
        specs = {**GOOD_RUNS, **{name: args for name, (args, _) in BAD_INPUTS.items()}}
        for name, args in specs.items():  # "bunny" first: over_existing waits for it
            cwd = prepare(name, name)
            started[name] = Run(cwd, listing(cwd),
                                pool.submit(run_cli, "voxelize", *args, "-o", OUT, cwd=cwd))
        for name in OVER_EXISTING:
            cwd = prepare(f"{name}_over_existing", name)
            started[f"{name}_over_existing"] = Run(
                cwd, listing(cwd), pool.submit(over_existing, cwd, BAD_INPUTS[name][0]))
        yield started


@pytest.fixture(scope="module")
def concrete_density(tmp_path_factory: pytest.TempPathFactory) -> float:
    cwd = tmp_path_factory.mktemp("materials")
    table = json.loads(ok(run_cli("materials", "--json", cwd=cwd)).stdout)
    density = float(table["concrete"]["density"])
    assert density > 0
    return density


# --------------------------------------------------------------------------- basics


def test_help_lists_commands(tmp_path: Path) -> None:
    result = ok(run_cli("--help", cwd=tmp_path))
    for command in ("voxelize", "info", "materials"):
        assert re.search(rf"^\W*{command}\b", result.stdout, re.MULTILINE), result.stdout


def test_console_script_help(tmp_path: Path) -> None:
    script = Path(sys.executable).with_name("blastvox")
    if not script.exists():
        pytest.skip("no blastvox console script beside this interpreter")
    result = subprocess.run([str(script), "--help"], cwd=tmp_path, capture_output=True,
                            text=True, timeout=TIMEOUT_S)
    assert result.returncode == 0, result.stderr
    for command in ("voxelize", "info", "materials"):
        assert command in result.stdout


def test_version(tmp_path: Path) -> None:
    result = ok(run_cli("--version", cwd=tmp_path))
    assert result.stdout.strip() == f"blastvox {blastvox.__version__}"


@pytest.mark.parametrize("args, flag", [
    (("voxelize", "x.stl", "--shape", "sphere", "-o", "x.npz"), "--shape"),
    (("voxelize", "x.stl", "--resolution", "many", "-o", "x.npz"), "--resolution"),
    (("voxelize", "x.stl", "--no-such-flag", "-o", "x.npz"), "--no-such-flag"),
    (("explode",), "explode"),
], ids=["bad-choice", "not-an-int", "unknown-flag", "unknown-command"])
def test_usage_error_is_reported_not_raised(args: tuple[str, ...], flag: str,
                                            tmp_path: Path) -> None:
    result = run_cli(*args, cwd=tmp_path)
    assert "Traceback" not in result.stderr, result.stderr
    assert result.returncode == 2, result.stderr
    assert flag in result.stderr
    assert listing(tmp_path) == []


# --------------------------------------------------------------------------- good runs


def test_voxelize_bunny_info(runs: dict[str, Run], concrete_density: float) -> None:
    model = runs["bunny"].model
    assert model.is_file() and model.stat().st_size > 0
    assert listing(model.parent) == ["model.npz"]  # no temporaries left beside it
    summary = info_json(model)
    assert SUMMARY_KEYS <= summary.keys(), SUMMARY_KEYS - summary.keys()
    assert summary["voxel_count"] > 0
    assert summary["link_count"] > 0
    assert summary["object_count"] >= 1
    assert 0 < summary["foundation_voxel_count"] < summary["voxel_count"]
    bounds = np.asarray(summary["bounds_m"], dtype=float)
    assert bounds.shape == (2, 3)
    assert np.all(np.isfinite(bounds)) and np.all(bounds[0] < bounds[1])
    volume, mass = summary["total_volume_m3"], summary["total_mass_kg"]
    assert 0 < volume <= float(np.prod(bounds[1] - bounds[0]))
    assert math.isclose(mass, volume * concrete_density, rel_tol=1e-9)
    assert summary["materials_used"] == ["concrete"]


def test_info_table_mentions_counts(runs: dict[str, Run]) -> None:
    model = runs["bunny"].model
    summary = info_json(model)
    text = ok(run_cli("info", model, cwd=model.parent)).stdout
    assert "voxel_count" in text and str(summary["voxel_count"]) in text


def test_same_seed_gives_identical_bytes(runs: dict[str, Run]) -> None:
    a, b, c = (runs[n].model.read_bytes()
               for n in ("jitter_seed5_a", "jitter_seed5_b", "jitter_seed6"))
    assert a == b
    assert a != c
    # and the difference is in the geometry, not only in the perturbed yields
    with np.load(runs["jitter_seed5_a"].model) as za, np.load(runs["jitter_seed6"].model) as zc:
        va, vc = za["vertices"], zc["vertices"]
        assert va.shape != vc.shape or not np.array_equal(va, vc)


def test_multibody_gives_two_objects(runs: dict[str, Run]) -> None:
    summary = info_json(runs["multibody"].model)
    assert summary["object_count"] == 2
    assert summary["up_axis"] == "Z"


def test_milk_truck_makes_sheets_of_open_parts_with_warning(runs: dict[str, Run]) -> None:
    run = runs["truck"]
    stderr = squash(run.result.stderr)
    assert "warning" in stderr.lower() and "voxelized as a sheet" in stderr, stderr
    assert "open surface" in stderr, stderr
    assert "CesiumMilkTruck.glb" in stderr
    summary = info_json(run.model)
    assert summary["object_count"] >= 1
    assert summary["voxel_count"] > 0


def test_building_scene(runs: dict[str, Run]) -> None:
    run = runs["building"]
    summary = info_json(run.model)
    assert {"brick", "reinforced_concrete"} <= set(summary["materials_used"])
    assert summary["voxel_count"] > 0 and summary["foundation_voxel_count"] > 0
    assert summary["conform_voxel_count"] > 0
    assert summary["seed"] == 7
    assert listing(run.cwd) == ["building.glb", "out", "scene.toml"]


def test_ground_none_has_no_foundations(runs: dict[str, Run]) -> None:
    free = info_json(runs["ground_none"].model)
    grounded = info_json(runs["bunny"].model)
    assert free["foundation_voxel_count"] == 0
    assert free["ground_height_m"] is None
    assert grounded["foundation_voxel_count"] > 0
    assert free["voxel_count"] == grounded["voxel_count"]


# --------------------------------------------------------------------------- bad inputs


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_fails_cleanly(case: str, runs: dict[str, Run]) -> None:
    run = runs[case]
    assert_one_line_error(run.result, *BAD_INPUTS[case][1])
    assert run.result.stdout == ""
    assert listing(run.cwd / "out") == [], "a failed run left files in the output directory"
    assert listing(run.cwd) == run.before


@pytest.mark.parametrize("case", OVER_EXISTING)
def test_failed_run_keeps_existing_output(case: str, runs: dict[str, Run]) -> None:
    run = runs[f"{case}_over_existing"]
    assert_one_line_error(run.result, *BAD_INPUTS[case][1])
    assert listing(run.cwd / "out") == ["model.npz"]
    assert (run.cwd / OUT).read_bytes() == runs["bunny"].model.read_bytes()


# --------------------------------------------------------------------------- info on bad files


@pytest.mark.parametrize("kind", ["foreign", "truncated", "text", "missing"])
def test_info_rejects_non_models(kind: str, tmp_path: Path, runs: dict[str, Run]) -> None:
    target = tmp_path / f"{kind}.npz"
    if kind == "foreign":
        rng = np.random.default_rng(0)
        np.savez(target, a=rng.random((4, 3)), b=rng.integers(0, 9, 10))
    elif kind == "truncated":
        data = runs["bunny"].model.read_bytes()
        target.write_bytes(data[: len(data) // 2])
    elif kind == "text":
        target.write_text("not a zip file\n")
    for extra in ((), ("--json",)):
        result = run_cli("info", target.name, *extra, cwd=tmp_path)
        assert_one_line_error(result, target.name)
        assert result.stdout == ""


def test_a_scene_gives_the_same_model_from_voxelize_and_from_run(
        runs: dict[str, Run], tmp_path: Path) -> None:
    """``blastvox voxelize --scene`` and ``blastvox run`` (a wedge's shots too: both go
    through :func:`blastvox.shot.voxelize_scene`) record the same settings, so a scene
    makes one model file whichever command made it; a budget is not recorded (the
    building's 450 kg city shot differed in its meta only, stop 55)."""
    from blastvox.scene import load_scene
    from blastvox.shot import voxelize_scene

    cli = runs["building"]
    scene_path = cli.cwd / "scene.toml"
    model = voxelize_scene(load_scene(scene_path), scene_path, max_voxels=123_456_789)
    model.save(tmp_path / "run.npz")
    assert (tmp_path / "run.npz").read_bytes() == cli.model.read_bytes()
    assert "max_voxels" not in model.meta["settings"]
    assert model.meta["settings"]["scene"] == "scene.toml"
