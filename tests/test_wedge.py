"""``blastvox wedge``: VALUES and KEY parsing, the plan and its content keys, and whole
wedges on a Dask LocalCluster of two workers (same files as shots run one by one,
resume after Ctrl-C, a failed shot among good ones, bad keys and schedulers).

The scene is the real Duck.glb (Khronos sample, tests/data) voxelized coarsely, with
a small charge and a short shot, so a shot takes about a second with warm kernels.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from bad_input import assert_clean_failure, run_blastvox, unchanged

from blastvox.errors import BlastvoxError, BudgetError, SceneError, WedgeError
from blastvox.scene import Scene
from blastvox.wedge.keys import check_key, split_key, valid_keys, with_values
from blastvox.wedge.plan import plan_wedge
from blastvox.wedge.values import parse_values

ROOT = Path(__file__).resolve().parents[1]
SCENE = """\
seed = 0
up_axis = "Y"

[[objects]]
name = "duck"
mesh = "Duck.glb"
resolution = 6
material = "wood"

[[charges]]
position = [0.0, 0.5, 2.5]
mass_kg = 1.0

[simulation]
duration = 0.25
fps = 24

[effects]
fire = false
fireball = false

[output]
model = "out/model.npz"
cache = "out/sim.npz"
export = "out/shot.glb"
"""


@pytest.fixture
def duck_scene(tmp_path: Path, data_dir: Path) -> Path:
    """A scene directory with the duck and the scene file above; returns the scene path."""
    shutil.copy(data_dir / "Duck.glb", tmp_path / "Duck.glb")
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    return scene


# --- VALUES ------------------------------------------------------------------------

@pytest.mark.parametrize(("text", "expected"), [
    ("10,50,100", [10, 50, 100]),
    ("0.5, 2.5", [0.5, 2.5]),
    ("brick,stone", ["brick", "stone"]),
    ('"brick", "stone"', ["brick", "stone"]),
    ("[1,0,1],[2,0,1]", [[1, 0, 1], [2, 0, 1]]),
    ("true,false", [True, False]),
    ("0:3:4", [0, 1, 2, 3]),
    ("0:1:5", [0.0, 0.25, 0.5, 0.75, 1.0]),
    ("0:1:3", [0.0, 0.5, 1.0]),
    ("1:100:3:log", [1.0, 10.0, 100.0]),
    ("0.001:0.004:4", [0.001, 0.002, 0.003, 0.004]),
    ("5:5:1", [5]),
])
def test_values_lists_and_ranges(text: str, expected: list) -> None:
    values = parse_values(text, "--vary k")
    assert values == expected
    assert [type(v) for v in values] == [type(v) for v in expected]


@pytest.mark.parametrize(("text", "words"), [
    ("", "no values"),
    ("1,,2", "empty value"),
    ("nan,1", "not a finite"),
    ("inf", "not a finite"),
    ("0:1:0", "COUNT"),
    ("0:1:5000", "COUNT"),
    ("0:10:3:log", "log range"),
    ("[1,2", "cannot read"),
])
def test_bad_values_are_one_line(text: str, words: str) -> None:
    with pytest.raises(WedgeError, match=words) as caught:
        parse_values(text, "--vary k")
    assert "\n" not in str(caught.value) and "--vary k" in str(caught.value)


# --- KEY ---------------------------------------------------------------------------

def test_valid_keys_follow_the_schema_and_the_written_lists(duck_scene: Path) -> None:
    import tomllib

    raw = tomllib.loads(duck_scene.read_text())
    keys = valid_keys(Scene, raw, ["wood", "brick"], ["density", "link_yield_mean"])
    for key in ("seed", "charges.0.mass_kg", "charges.0.position", "simulation.dt",
                "objects.0.voxel_size", "objects.0.transform.translate", "camera.position",
                "materials.brick.link_yield_mean", "output.layout", "effects.dust"):
        assert key in keys, key
    for key in ("charges.1.mass_kg", "output.model", "output.cache", "output.export",
                "wedge.sample", "objects.0.rules.0.material"):
        assert key not in keys, key
    assert split_key("charges[0].mass_kg") == ["charges", "0", "mass_kg"]
    assert check_key("charges[0].mass_kg", keys, "--vary") == "charges.0.mass_kg"


@pytest.mark.parametrize(("key", "nearest"), [
    ("charges.0.mass", "charges.0.mass_kg"),
    ("charges.2.mass_kg", "charges.0.mass_kg"),
    ("simulation.dtt", "simulation.dt"),
    ("sed", "seed"),
])
def test_unknown_key_names_the_nearest(duck_scene: Path, key: str, nearest: str) -> None:
    with pytest.raises(WedgeError) as caught:
        plan_wedge(duck_scene, [f"{key}=1,2"])
    line = str(caught.value)
    assert f"unknown key '{key}'" in line and nearest in line.split("nearest:")[1], line


def test_a_part_name_with_dots_is_quoted(duck_scene: Path) -> None:
    duck_scene.write_text(SCENE.replace('material = "wood"',
                                        'material = "wood"\nmaterial_map = { "Wheels.001" = '
                                        '"steel" }'))
    key = 'objects.0.material_map."Wheels.001"'
    assert split_key(key) == ["objects", "0", "material_map", "Wheels.001"]
    plan = plan_wedge(duck_scene, [f"{key}=brick,stone"])
    assert [s.scene["objects"][0]["material_map"] for s in plan.shots] == [
        {"Wheels.001": "brick"}, {"Wheels.001": "stone"}]
    assert plan.shots[0].label() == f"shot 0: {key}=brick"
    with pytest.raises(WedgeError) as caught:  # unquoted: the quoted key is suggested
        plan_wedge(duck_scene, ["objects.0.material_map.Wheels.001=brick"])
    assert key in str(caught.value)
    for bad in ('charges..mass_kg', 'charges.0.', '"\\q".x', "[0]"):
        with pytest.raises(WedgeError, match="dotted path"):
            split_key(bad)


def test_outputs_are_not_a_wedge_key(duck_scene: Path) -> None:
    with pytest.raises(WedgeError, match="outputs itself"):
        plan_wedge(duck_scene, ["output.cache=a.npz,b.npz"])


def test_with_values_creates_tables_and_leaves_the_input_alone() -> None:
    data = {"charges": [{"mass_kg": 1.0}], "seed": 0}
    out = with_values(data, {"charges.0.mass_kg": 5, "simulation.dt": 0.001, "seed": 3})
    assert out == {"charges": [{"mass_kg": 5}], "seed": 3, "simulation": {"dt": 0.001}}
    assert data == {"charges": [{"mass_kg": 1.0}], "seed": 0}


# --- the plan and its keys -----------------------------------------------------------

def test_grid_order_sample_and_keys(duck_scene: Path, tmp_path: Path) -> None:
    plan = plan_wedge(duck_scene, ["charges.0.mass_kg=1,2,4", "seed=0:1:2"])
    assert plan.grid_size == 6 and len(plan.shots) == 6
    assert [s.params for s in plan.shots[:3]] == [
        {"charges.0.mass_kg": 1, "seed": 0}, {"charges.0.mass_kg": 1, "seed": 1},
        {"charges.0.mass_kg": 2, "seed": 0}]
    assert len({s.key for s in plan.shots}) == 6
    assert plan.out == duck_scene.parent / "out" / "wedge"
    # keys do not depend on where the wedge writes, and come out the same every time
    again = plan_wedge(duck_scene, ["charges.0.mass_kg=1,2,4", "seed=0:1:2"],
                       out=tmp_path / "elsewhere")
    assert [s.key for s in again.shots] == [s.key for s in plan.shots]
    sample = plan_wedge(duck_scene, ["charges.0.mass_kg=1,2,4", "seed=0:1:2"], sample=3,
                        sample_seed=7)
    assert [s.index for s in sample.shots] == sorted(s.index for s in sample.shots)
    assert len(sample.shots) == 3 and sample.grid_size == 6
    assert {s.key for s in sample.shots} <= {s.key for s in plan.shots}
    same = plan_wedge(duck_scene, ["charges.0.mass_kg=1,2,4", "seed=0:1:2"], sample=3,
                      sample_seed=7)
    assert [s.index for s in same.shots] == [s.index for s in sample.shots]


def test_a_material_property_overrides_that_field_only(duck_scene: Path) -> None:
    from blastvox.materials import MaterialLibrary
    from blastvox.scene import scene_from_dict

    plan = plan_wedge(duck_scene, ["materials.wood.link_yield_mean=1e5,4e5"])
    builtin = MaterialLibrary.builtin()["wood"]
    for shot, expected in zip(plan.shots, (1e5, 4e5), strict=True):
        wood = scene_from_dict(shot.scene, "s", duck_scene.parent).material_library()["wood"]
        assert wood.link_yield_mean == expected != builtin.link_yield_mean
        assert wood.density == builtin.density  # the rest of wood is the built-in's
    assert plan.shots[0].key != plan.shots[1].key


def test_key_follows_the_input_bytes(duck_scene: Path) -> None:
    before = plan_wedge(duck_scene, ["seed=0,1"]).shots[0].key
    mesh = duck_scene.parent / "Duck.glb"
    mesh.write_bytes(mesh.read_bytes() + b"\0")
    assert plan_wedge(duck_scene, ["seed=0,1"]).shots[0].key != before


def test_wedge_table_and_options(duck_scene: Path) -> None:
    duck_scene.write_text(SCENE + '\n[wedge]\nsample = 2\nout = "sweep"\n'
                          '[wedge.vary]\n"charges.0.mass_kg" = [1, 2, 3]\nseed = "0:2:3"\n')
    plan = plan_wedge(duck_scene)
    assert [a.key for a in plan.axes] == ["charges.0.mass_kg", "seed"]
    assert plan.grid_size == 9 and len(plan.shots) == 2
    assert plan.out == duck_scene.parent / "sweep"
    plan = plan_wedge(duck_scene, ["seed=5,6"], sample=100)
    assert plan.axes[1].values == [5, 6] and len(plan.shots) == 6


@pytest.mark.parametrize(("vary", "error", "words"), [
    (["charges.0.mass_kg=1,-2"], SceneError, "charges[0].mass_kg"),
    (["seed=1,1"], WedgeError, "listed twice"),
    (["charges.0.mass_kg=1,1.0"], WedgeError, "value 1.0 listed twice (as 1)"),  # one shot
    (["simulation.dt=0.001,1e-9"], BudgetError, "simulation.dt=1e-09): simulation.duration"),
    (["charges.0.mass_kg=1,1e300"], BlastvoxError, "mass_kg=1e+300): charges[0].mass_kg"),
    ([], WedgeError, "nothing to vary"),
    (["seed"], WedgeError, "KEY=VALUES"),
    (["seed=0:999:1000", "simulation.fps=1:100:100"], WedgeError, "at most 10,000"),
])
def test_bad_wedges_are_refused_before_anything_runs(duck_scene: Path, vary: list[str],
                                                     error: type, words: str) -> None:
    with pytest.raises(error) as caught:
        plan_wedge(duck_scene, vary)
    assert words in str(caught.value) and "\n" not in str(caught.value)
    assert not (duck_scene.parent / "out").exists()


def test_a_refused_value_names_the_shot(duck_scene: Path) -> None:
    with pytest.raises(SceneError, match=r"shot 1: charges.0.mass_kg=-2\).*must be > 0"):
        plan_wedge(duck_scene, ["charges.0.mass_kg=1,-2"])


def test_budgets_reach_every_shot_and_stay_out_of_its_key(duck_scene: Path) -> None:
    """--max-voxels and --max-memory (issue 37's 10 M-voxel city block is over both
    defaults) travel with each shot to its worker; they never change a shot's files."""
    from blastvox.wedge.shot import run_shot

    plain = plan_wedge(duck_scene, ["seed=0,1"])
    tight = plan_wedge(duck_scene, ["seed=0,1"], max_voxels=5, max_memory_gib=64.0)
    assert [s.key for s in tight.shots] == [s.key for s in plain.shots]
    assert (plain.shots[0].max_voxels, plain.shots[0].max_memory_gib) == (None, None)
    assert (tight.shots[1].max_voxels, tight.shots[1].max_memory_gib) == (5, 64.0)
    result = run_shot(tight.shots[0])
    assert result["status"] == "failed"
    assert "budget of 5" in result["error"] and "--max-voxels" in result["error"]
    assert not Path(tight.shots[0].scene["output"]["model"]).exists()
    outcome = run_blastvox("wedge", duck_scene, "--vary", "seed=0,1", "--max-voxels",
                           "20000000", "--max-memory", "32", "--dry-run")
    assert outcome.code == 0, outcome.stderr


def test_cache_stats_count_what_moved_and_how_it_broke() -> None:
    """Three pieces of 1 kg voxels: a 10-voxel piece that flies (one of its voxels turned
    to dust), a single voxel that flies, a single voxel that stays."""
    from types import SimpleNamespace

    import numpy as np

    from blastvox.wedge.shot import cache_stats

    position = np.zeros((2, 3, 3))
    position[1, :2, 0] = [2.0, 0.5]  # pieces 0 and 1 move, piece 2 stays
    destroyed = np.full(12, -1)
    destroyed[3] = 5
    cache = SimpleNamespace(
        arrays={"piece_position": position, "piece_mass": np.array([10.0, 1.0, 1.0]),
                "voxel_piece": np.array([0] * 10 + [1, 2]), "voxel_destroyed_frame": destroyed,
                "link_break_link": np.arange(4)},
        model=SimpleNamespace(arrays={"voxel_mass": np.ones(12)}))
    stats = cache_stats(cache)
    assert stats["pieces"] == 3 and stats["moving_pieces"] == 2 and stats["broken_links"] == 4
    assert stats["dust_voxels"] == 1
    assert stats["mass_kg"] == 12.0 and stats["moved_mass_kg"] == 11.0
    assert stats["moved_fraction"] == pytest.approx(11 / 12)
    assert stats["single_voxel_fraction"] == 0.5
    assert stats["chunky_mass_fraction"] == pytest.approx(9 / 10)


# --- the CLI: errors ----------------------------------------------------------------

def test_cli_unknown_key_is_one_line(duck_scene: Path) -> None:
    with unchanged(duck_scene.parent, [duck_scene]):
        outcome = run_blastvox("wedge", duck_scene, "--vary", "charges.0.mas_kg=1,2")
    assert_clean_failure(outcome, ["charges.0.mas_kg", "charges.0.mass_kg"],
                         words=["unknown key"])


def test_cli_unreachable_scheduler_is_one_line(duck_scene: Path) -> None:
    with unchanged(duck_scene.parent, [duck_scene]):
        outcome = run_blastvox("wedge", duck_scene, "--vary", "seed=0,1", "--scheduler",
                               "tcp://127.0.0.1:9", "--connect-timeout", "1")
    assert_clean_failure(outcome, ["tcp://127.0.0.1:9"], words=["connection refused"])


def test_cli_dry_run_lists_the_shots(duck_scene: Path) -> None:
    with unchanged(duck_scene.parent, [duck_scene]):
        outcome = run_blastvox("wedge", duck_scene, "--vary", "seed=0:2:3", "--dry-run")
    assert outcome.code == 0, outcome.stderr
    assert [line.split(":")[0] for line in outcome.stdout.splitlines()] == [
        "shot 0", "shot 1", "shot 2"]


# --- whole wedges on Dask -------------------------------------------------------------

@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of two single-threaded worker processes, for the whole module."""
    import logging

    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None, scheduler_kwargs={"dashboard": False},
                      silence_logs=logging.ERROR) as local:
        yield local


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def test_wedge_makes_the_files_of_its_shots_run_one_by_one(duck_scene: Path, tmp_path: Path,
                                                          cluster) -> None:
    out = tmp_path / "wedge"
    outcome = run_blastvox("wedge", duck_scene, "--vary", "charges.0.mass_kg=0.5,8",
                           "--vary", "seed=0,3", "-o", out, "--scheduler",
                           cluster.scheduler_address, "-q")
    assert outcome.code == 0, outcome.stderr
    summary = _summary(out)
    shots = summary["shots"]
    assert [s["status"] for s in shots] == ["ran"] * 4
    assert len({s["worker"] for s in shots}) == 2  # both workers took shots
    assert shots[3]["stats"]["broken_links"] > shots[0]["stats"]["broken_links"]
    rows = (out / "summary.csv").read_text().splitlines()
    assert rows[0].startswith("shot,key,charges.0.mass_kg,seed,status,error,pieces")
    assert len(rows) == 5
    from PIL import Image

    with Image.open(out / "sheet.png") as sheet:
        assert sheet.height > 4 * 180
    # a shot, run by itself from a scene file with its values, gives the same bytes
    for shot in (shots[3],):
        solo = tmp_path / f"solo{shot['shot']}"
        solo.mkdir()
        shutil.copy(duck_scene.parent / "Duck.glb", solo / "Duck.glb")
        mass, seed = shot["params"]["charges.0.mass_kg"], shot["params"]["seed"]
        (solo / "scene.toml").write_text(SCENE.replace("mass_kg = 1.0", f"mass_kg = {mass}")
                                         .replace("seed = 0", f"seed = {seed}"))
        assert run_blastvox("run", solo / "scene.toml", "-q").code == 0
        for name in ("model.npz", "sim.npz", "shot.glb"):
            wedge_file = Path(shot["directory"]) / name
            assert wedge_file.read_bytes() == (solo / "out" / name).read_bytes(), name


def test_a_failed_shot_does_not_stop_the_others(duck_scene: Path, tmp_path: Path,
                                               cluster) -> None:
    out = tmp_path / "wedge"
    outcome = run_blastvox("wedge", duck_scene, "--vary", "objects.0.mesh=Duck.glb,Goose.glb",
                           "-o", out, "--scheduler", cluster.scheduler_address, "-q")
    assert outcome.code == 1
    shots = _summary(out)["shots"]
    assert [s["status"] for s in shots] == ["ran", "failed"]
    assert "Goose.glb" in shots[1]["error"] and "\n" not in shots[1]["error"]
    assert not (Path(shots[1]["directory"]) / "result.json").exists()
    assert "Goose.glb" in (Path(shots[1]["directory"]) / "log.txt").read_text()
    assert (out / "sheet.png").is_file()
    csv = (out / "summary.csv").read_text()
    assert "failed" in csv and "Goose.glb" in csv


def test_an_interrupted_wedge_resumes_with_the_missing_shots(duck_scene: Path,
                                                            tmp_path: Path) -> None:
    """Ctrl-C a wedge on its own LocalCluster after its first shot, as a terminal does (to
    the whole process group: the wedge and its workers); the re-run runs only the shots
    that had not finished and leaves the finished ones' files alone."""
    out = tmp_path / "wedge"
    args = [sys.executable, "-m", "blastvox", "wedge", str(duck_scene), "--vary",
            "seed=0:5:6", "-o", str(out), "--workers", "1", "--no-preview"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=env, preexec_fn=_default_sigint, start_new_session=True)
    deadline = time.monotonic() + 900  # the first shot's end, however loaded the host
    while (not list(out.glob("shots/*/result.json")) and time.monotonic() < deadline
           and child.poll() is None):  # a wedge that died early fails at once
        time.sleep(0.05)
    os.killpg(child.pid, signal.SIGINT)
    _, stderr = child.communicate(timeout=60)
    assert child.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert stderr.splitlines()[-1] == "blastvox: interrupted; no partial output left"
    finished = {p.parent.name: p.parent.joinpath("sim.npz").stat().st_mtime_ns
                for p in out.glob("shots/*/result.json")}
    assert 1 <= len(finished) < 6
    assert not (out / "summary.json").exists()
    again = subprocess.run(args[:-1] + ["--workers", "2", "--no-preview", "-q"],
                           capture_output=True, text=True, env=env, timeout=300)
    assert again.returncode == 0, again.stderr
    shots = _summary(out)["shots"]
    assert sorted(s["key"] for s in shots if s["status"] == "cached") == sorted(finished)
    assert sum(s["status"] == "ran" for s in shots) == 6 - len(finished)
    for key, mtime in finished.items():
        assert (out / "shots" / key / "sim.npz").stat().st_mtime_ns == mtime
    # and a third run has nothing left to do
    third = run_blastvox("wedge", duck_scene, "--vary", "seed=0:5:6", "-o", out,
                         "--workers", "1", "--no-preview")
    assert third.code == 0 and "0 ran, 6 up to date" in third.stderr


def _default_sigint() -> None:
    """Ctrl-C's default action in the child even if this process ignores SIGINT (as a
    background job of a non-interactive shell does), so the test sends a real Ctrl-C."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
