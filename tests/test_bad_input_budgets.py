"""Issue 18 part C: resource budgets and numeric bounds of simulate, preview and blast.

Every refusal meets the contract of :mod:`bad_input` (exit 1, or 2 for a usage
error; one line naming the file or flag and the problem; no traceback; inputs
unchanged; nothing left behind) within a few seconds, whatever the value would
have cost. Runs go through the real entry point in-process, with numpy's
RuntimeWarnings turned into errors, so a warning that reaches the user fails the
test. The hypothesis tests feed random floats (NaN, infinities, 1e308, -0.0,
denormals included) to the numeric flags: each run either succeeds quickly or
fails cleanly. Budget flags keep the successful runs tiny.
"""

from __future__ import annotations

import contextlib
import math
import signal
import time
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import trimesh
from bad_input import Outcome, assert_clean_failure, run_blastvox, unchanged
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from blastvox.errors import BlastvoxError, BudgetError

#: A few seconds, whatever a refused value would have cost (--dt 1e-300 ran for ever).
QUICK = 5.0
CHARGE = ("--charge", "0,-2,0.25:1")
SHORT = ("--duration", "0.05")
#: Budgets that keep a hypothesis run that is accepted tiny (the budgets are under test too).
TINY = ("--max-steps", "2000", "--max-frames", "200")
HYPOTHESIS = settings(max_examples=25, deadline=None, derandomize=True,
                      suppress_health_check=[HealthCheck.function_scoped_fixture])


class Overtime(BaseException):
    """A run went on past its deadline (a BaseException: the CLI must not report it)."""


@contextlib.contextmanager
def deadline(seconds: float) -> Iterator[None]:
    """Raise :class:`Overtime` in the block after ``seconds`` (a run that would go on for
    ever, as ``--dt 1e-300`` did, fails instead of hanging the suite)."""
    def expire(signum: int, frame: object) -> None:
        raise Overtime(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


def strict(*args: str | Path, cwd: Path | None = None, seconds: float = 120.0) -> Outcome:
    """run_blastvox with numpy's RuntimeWarnings (overflow, invalid, divide) as errors,
    stopped after ``seconds``."""
    with warnings.catch_warnings(), deadline(seconds):
        warnings.simplefilter("error", RuntimeWarning)
        return run_blastvox(*args, cwd=cwd)


def assert_clean(outcome: Outcome, seconds: float = QUICK) -> None:
    """Success or a clean one-line failure, quickly; never a traceback or a Python warning."""
    text = outcome.stderr + outcome.stdout
    assert "Traceback" not in text and "Warning:" not in text, text[-2000:]
    if outcome.code != 0:
        assert_clean_failure(outcome, (), code=outcome.code, seconds=seconds)
    assert outcome.seconds < seconds, (outcome.seconds, text[-500:])


SCENE = """\
seed = 0
up_axis = "Z"

[[objects]]
name = "box"
mesh = "box.stl"
voxel_size = 0.25
material = "brick"

[[charges]]
position = [0.0, -2.0, 0.25]
mass_kg = {mass}
time_s = {time}

[simulation]
duration = {duration}

[particles]
dust = {dust}

[output]
model = "model.npz"
cache = "sim.npz"
"""


def scene_text(mass: str = "1.0", time: str = "0.0", duration: str = "0.05",
               dust: str = "20000") -> str:
    return SCENE.format(mass=mass, time=time, duration=duration, dust=dust)


@pytest.fixture(scope="module")
def shop(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """box.stl, its 8-voxel model.npz (0.5 m brick cube on the ground) and a SimCache."""
    root = tmp_path_factory.mktemp("budgets")
    trimesh.creation.box(extents=(0.5, 0.5, 0.5)).apply_translation((0, 0, 0.25)).export(
        root / "box.stl")
    made = run_blastvox("voxelize", "box.stl", "-o", "model.npz", "--voxel-size", "0.25",
                        "--material", "brick", "--up-axis", "Z", "-q", cwd=root)
    assert made.code == 0, made.stderr
    made = run_blastvox("simulate", "model.npz", "-o", "sim.npz", *CHARGE, *SHORT, "-q",
                        cwd=root)
    assert made.code == 0, made.stderr
    # the kernels of fracture (the warm-up's fracture models are not the default), of the
    # gravity stress solver (only an unbroken, resting box reaches it: a charge that never
    # goes off), of the rasteriser and of the calculator load (or compile, on a fresh
    # checkout or after an edit) here, untimed
    for args in (("simulate", "model.npz", "-o", "warm.npz", "--charge", "0,-1,0.25:50",
                  "--duration", "0.1", "-q"),
                 ("simulate", "model.npz", "-o", "warm.npz", "--charge", "0,-2,0.25:1@1e3",
                  *SHORT, "-q"),
                 ("preview", "sim.npz", "-o", "warm.png", "--size", "16x16", "-q"),
                 ("blast", "--charge", "1", "--distance", "0,1", "--json")):
        made = run_blastvox(*args, cwd=root)
        assert made.code == 0, made.stderr
    return root


@pytest.fixture
def work(shop: Path, tmp_path: Path) -> Path:
    """A fresh directory with copies of the shop's files (a test may leave nothing in it)."""
    for name in ("box.stl", "model.npz", "sim.npz"):
        (tmp_path / name).write_bytes((shop / name).read_bytes())
    return tmp_path


def refused(work: Path, *args: str, names: tuple[str, ...], code: int = 1,
            words: tuple[str, ...] = (), inputs: tuple[str, ...] = ("model.npz", "sim.npz"),
            allow: tuple[str, ...] = (), seconds: float = QUICK) -> str:
    """Run ``blastvox ARGS`` in ``work`` and check the refusal contract; the error line."""
    with unchanged(work, [work / name for name in inputs], allow=allow):
        outcome = strict(*args, cwd=work, seconds=2 * seconds)
    return assert_clean_failure(outcome, names, code=code, words=words, seconds=seconds)


# --------------------------------------------------------------------------- 1. budgets


SIM = ("simulate", "model.npz", "-o", "out.npz", *CHARGE)
STEP_BUDGETS = {
    "dt 1e-300": (("--dt", "1e-300", *SHORT), ("model.npz", "--dt", "1e-300", "--max-steps")),
    "duration 1e12": (("--duration", "1e12"), ("model.npz", "--duration", "1e+12",
                                               "2.4e+14 steps", "10,000,000", "--max-steps")),
    "fps 1e300": (("--fps", "1e300", *SHORT), ("--fps", "1e+300", "--max-steps")),
    "duration 1e308 at 1e6 fps": (("--duration", "1e308", "--fps", "1e6"),
                                  ("--duration", "--max-steps")),
    "frames": (("--duration", "10000", "--dt", "1"), ("--duration", "--fps", "240,001 frames",
                                                      "--max-frames")),
    "lowered steps": (("--duration", "1", "--max-steps", "100"), ("240 steps", "--max-steps")),
}


@pytest.mark.parametrize("case", STEP_BUDGETS)
def test_simulate_refuses_a_run_over_its_step_or_frame_budget_at_once(work: Path,
                                                                      case: str) -> None:
    args, names = STEP_BUDGETS[case]
    refused(work, *SIM, *args, names=names, words=("over the limit",))


def test_a_raised_budget_lets_the_run_go(work: Path) -> None:
    outcome = strict(*SIM, "--duration", "1", "--dt", "0.01", "--fps", "100", "--max-steps",
                     "100", "--max-frames", "101", "-q", cwd=work)
    assert_clean(outcome, seconds=30)
    assert outcome.code == 0 and (work / "out.npz").is_file()


SCENE_BUDGETS = {
    "duration 1e12": ({"duration": "1e12"}, ("scene.toml", "simulation.duration",
                                              "--max-steps")),
    "particles": ({"dust": "1000000000000"}, ("scene.toml", "particles", "dust",
                                              "--max-particles")),
    "charge time": ({"time": "1e300"}, ("scene.toml", "charges[0].time_s", "1e+300")),
    "charge mass": ({"mass": "1e-300"}, ("scene.toml", "charges[0].mass_kg", "1e-300")),
}


@pytest.mark.parametrize("case", SCENE_BUDGETS)
def test_simulate_names_the_scene_file_and_key(work: Path, case: str) -> None:
    values, names = SCENE_BUDGETS[case]
    (work / "scene.toml").write_text(scene_text(**values))
    refused(work, "simulate", "model.npz", "--scene", "scene.toml", names=names,
            inputs=("model.npz", "sim.npz", "scene.toml"))


def test_a_flag_overrides_the_scene_value_it_would_refuse(work: Path) -> None:
    (work / "scene.toml").write_text(scene_text(duration="1e12"))
    outcome = strict("simulate", "model.npz", "--scene", "scene.toml", "-o", "out.npz",
                     *SHORT, "-q", cwd=work)
    assert_clean(outcome, seconds=30)
    assert outcome.code == 0


def test_run_refuses_the_scene_before_simulating(work: Path) -> None:
    """``blastvox run`` goes through the engine's check (the model stage may run first)."""
    (work / "scene.toml").write_text(scene_text(duration="1e12"))
    (work / "model.npz").unlink()
    (work / "sim.npz").unlink()
    refused(work, "run", "scene.toml", "-q", names=("simulation.duration", "--max-steps"),
            inputs=("scene.toml", "box.stl"), allow=("model.npz",))
    assert not (work / "sim.npz").exists()


def test_the_library_refuses_before_allocating() -> None:
    from blastvox.model import VoxelModel
    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import Budget, ChargeSpec, SimSettings

    started = time.perf_counter()
    charges = (ChargeSpec((0.0, -2.0, 0.25), 1.0),)
    with pytest.raises(BudgetError, match=r"duration 1e\+12 s at dt .* --max-steps"):
        simulate(VoxelModel.__new__(VoxelModel), SimSettings(duration=1e12, charges=charges))
    with pytest.raises(BudgetError, match="--max-frames"):
        simulate(VoxelModel.__new__(VoxelModel), SimSettings(
            duration=1e4, dt=1.0, charges=charges, budget=Budget(max_steps=10**9)))
    with pytest.raises(BlastvoxError, match=r"gravity: must be <= 1000 m/s\^2 \(got 1e\+300\)"):
        simulate(VoxelModel.__new__(VoxelModel), SimSettings(gravity=1e300, charges=charges))
    assert time.perf_counter() - started < QUICK


def _run_gib(work: Path, charges: int = 1) -> float:
    """The run's own memory estimate for work/model.npz, GiB."""
    from blastvox.model import VoxelModel
    from blastvox.simulate.settings import run_memory_bytes

    model = VoxelModel.load(work / "model.npz")
    return run_memory_bytes(model, charges) / 2**30


def test_the_recorded_frames_memory_is_checked_as_pieces_appear(work: Path) -> None:
    """On top of the run's own arrays, 1 piece over 13 frames fits in 5e-6 GiB more, the
    8 pieces the charge makes do not (the run stops at the frame they appear; it may load
    the fracture kernels first)."""
    limit = _run_gib(work) + 5e-6
    line = refused(work, "simulate", "model.npz", "-o", "out.npz", "--charge",
                   "0,-1,0.25:50", "--duration", "0.5", "--max-memory", repr(limit),
                   names=("model.npz", "8 pieces", "13 frames", "--max-memory"), seconds=30)
    assert "GiB" in line and "on top of the run's" in line


def test_a_run_too_large_for_the_memory_budget_is_refused_before_it_starts(
        work: Path) -> None:
    """The run's arrays are estimated from the model's voxels, links and charges before
    anything is built (issue 37: 'a budget estimate before a run that names its
    figure'); under the limit the run goes on, over it the refusal names the figure."""
    need = _run_gib(work)
    line = refused(work, "simulate", "model.npz", "-o", "out.npz", "--charge",
                   "0,-1,0.25:1", "--max-memory", repr(0.5 * need),
                   names=("model.npz", "8 voxels", "links", "--max-memory"), seconds=QUICK)
    assert f"about {need:.3g} GiB" in line, line
    ok = run_blastvox("simulate", "model.npz", "-o", "out.npz", "--charge", "0,-1,0.25:1",
                      "--duration", "0.05", "-q", "--max-memory", repr(1.5 * need), cwd=work)
    assert ok.code == 0, ok.stderr


# --------------------------------------------------------------------------- 2. bounds


BOUNDS = {
    "charge 1e300 kg": (("--charge", "0,-2,0.25:1e300"), ("--charge", "mass", "1e+300")),
    "charge 1e-300 kg": (("--charge", "0,-2,0.25:1e-300"), ("--charge", "mass", "1e-300")),
    "charge at 1e300 m": (("--charge", "1e300,-2,0.25:1"), ("--charge", "X", "1e+300")),
    "charge at 1e300 s": (("--charge", "0,-2,0.25:1@1e300"), ("--charge", "time")),
    "gravity 1e300": (("--gravity", "1e300"), ("--gravity", "1e+300", "1000 m/s^2")),
    "fps 1e-300": (("--fps", "1e-300"), ("--fps", "1e-300", "0.001")),
    "dt 5e-324 in a frameless run": (("--dt", "5e-324", "--duration", "1e-300"), ("--dt",)),
}


@pytest.mark.parametrize("case", BOUNDS)
def test_simulate_refuses_values_that_would_go_non_finite(work: Path, case: str) -> None:
    args, names = BOUNDS[case]
    charge = () if "--charge" in args else CHARGE
    refused(work, "simulate", "model.npz", "-o", "out.npz", *charge, *SHORT, *args,
            names=names)


@pytest.mark.parametrize(("args", "names"), [
    (("--charge", "5e-324", "--distance", "1e308"), ("--charge", "5e-324", ">= 1e-09")),
    (("--charge", "1", "--distance", "1e-320,1e308"), ("--distance", "1e+308", "1e+06 m")),
    (("--charge", "1e300", "--distance", "1"), ("--charge", "1e+300", "<= 1e+09 kg"))])
def test_blast_refuses_values_that_would_go_non_finite(work: Path, args: tuple,
                                                       names: tuple) -> None:
    """They gave a ZeroDivisionError, NaN in the JSON or overflow warnings."""
    refused(work, "blast", *args, "--json", names=names)


def test_blast_plot_of_a_distance_deep_in_the_charge(work: Path) -> None:
    """5e-324 m made the distance axis start at 0 (a traceback from geomspace)."""
    outcome = strict("blast", "--charge", "1", "--distance", "5e-324,1", "--plot", "p.png",
                     "--json", cwd=work)
    assert_clean(outcome, seconds=30)
    assert outcome.code == 0 and (work / "p.png").stat().st_size > 0


# --------------------------------------------------------------------------- 3. seeds


@pytest.mark.parametrize("seed", ["-1", str(2**64), str(10**30)])
def test_simulate_refuses_a_seed_outside_64_bits(work: Path, seed: str) -> None:
    refused(work, *SIM, *SHORT, "--seed", seed, names=("--seed", seed, "must be"))


def test_simulate_takes_the_largest_seed(work: Path) -> None:
    outcome = strict(*SIM, *SHORT, "--seed", str(2**64 - 1), "-q", cwd=work)
    assert_clean(outcome, seconds=30)
    assert outcome.code == 0


# --------------------------------------------------------------------------- 4. pixels


PIXELS = {
    "8192 x 4": (("--size", "8192x8192", "--supersample", "4", "-o", "p.png"),
                 ("--size 8192x8192", "--supersample 4", "1,073,741,824", "--max-pixels")),
    "lowered": (("--size", "64x64", "--max-pixels", "1000", "-o", "p.png"),
                ("--size 64x64", "--max-pixels")),
    "gif frames": (("--size", "64x64", "--max-output-pixels", "5000", "-o", "p.gif"),
                   ("2 frames", "8,192", "--max-output-pixels")),
}


@pytest.mark.parametrize("case", PIXELS)
def test_preview_refuses_a_size_over_its_pixel_budget_before_rendering(work: Path,
                                                                       case: str) -> None:
    args, names = PIXELS[case]
    refused(work, "preview", "sim.npz", *args, names=names, words=("over the limit",))


def test_preview_library_checks_the_budget_on_construction() -> None:
    from blastvox.preview.options import PreviewOptions

    with pytest.raises(BudgetError, match="--max-pixels"):
        PreviewOptions(size=(8192, 8192), supersample=4)
    assert PreviewOptions(size=(8192, 8192), supersample=4, max_pixels=2**30).supersample == 4


def test_an_mp4_streams_and_has_no_output_budget(work: Path) -> None:
    outcome = strict("preview", "sim.npz", "-o", "p.mp4", "--size", "32x32",
                     "--max-output-pixels", "1", "-q", cwd=work)
    assert_clean(outcome, seconds=30)
    assert outcome.code == 0


# --------------------------------------------------------------------------- 5. blast --plot


def test_blast_refuses_more_distances_than_its_limit_at_once(work: Path) -> None:
    """20,000 distances took 19 minutes (573 s of CPU) and 2.8 GB with --plot."""
    many = ",".join(f"{1 + 0.01 * i:g}" for i in range(20_000))
    refused(work, "blast", "--charge", "1", "--distance", many, "--plot", "p.png",
            names=("--distance", "20,000", "1,000"), words=("over the limit",))


def test_blast_plot_draws_at_most_twelve_curves_and_says_so() -> None:
    from blastvox.preview.plots import MAX_CURVES, blast_figure, curve_distances

    distances = [1.0 + 0.5 * i for i in range(50)]
    picked = curve_distances(distances)
    assert len(picked) == MAX_CURVES == 12
    assert picked[0] == 1.0 and picked[-1] == distances[-1]
    assert curve_distances([3.0, 1.0, 3.0]) == [3.0, 1.0]
    started = time.perf_counter()
    fig = blast_figure(1.0, "TNT", distances)
    axes = fig.axes[0]
    assert len([line for line in axes.get_lines() if line.get_label().startswith("R =")]) == 12
    assert "12 of the 50 distances" in axes.get_title()
    assert time.perf_counter() - started < QUICK


# --------------------------------------------------------------------------- 6, 7. flags


FLOATS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, -0.0, 0.0, 5e-324, 1e-300,
                     2.2250738585072014e-308, 1e300, 1e-9, 1e6]),
    st.floats(1e-12, 1e12))


def text_of(value: float) -> str:
    return repr(float(value))


@HYPOTHESIS
@given(flag=st.sampled_from(["--dt", "--fps", "--duration", "--gravity"]), value=FLOATS)
@example(flag="--dt", value=1e-300)
@example(flag="--duration", value=1e12)
@example(flag="--fps", value=5e-324)
def test_simulate_numeric_flags(work: Path, flag: str, value: float) -> None:
    with unchanged(work, [work / "model.npz"], allow=("out.npz",)):
        outcome = strict(*SIM, *SHORT, *TINY, flag, text_of(value), "-q", cwd=work,
                         seconds=2 * QUICK)
    assert_clean(outcome)
    if outcome.code:
        assert flag in outcome.stderr or "--max-" in outcome.stderr, outcome.stderr
        assert not (work / "out.npz").exists()
    (work / "out.npz").unlink(missing_ok=True)


@HYPOTHESIS
@given(x=FLOATS, kg=FLOATS, t=FLOATS)
@example(x=1e300, kg=1.0, t=0.0)
@example(x=0.0, kg=1e9, t=0.0)
@example(x=-1e6, kg=1e-9, t=1e9)
def test_simulate_charge_values(work: Path, x: float, kg: float, t: float) -> None:
    charge = f"{text_of(x)},-2,0.25:{text_of(kg)}@{text_of(t)}"
    with unchanged(work, [work / "model.npz"], allow=("out.npz",)):
        outcome = strict("simulate", "model.npz", "-o", "out.npz", "--charge", charge, *SHORT,
                         *TINY, "-q", cwd=work, seconds=2 * QUICK)
    assert_clean(outcome)
    if outcome.code:
        assert "--charge" in outcome.stderr
    (work / "out.npz").unlink(missing_ok=True)


SIZES = st.one_of(
    st.tuples(st.integers(0, 20_000), st.integers(0, 20_000)).map(lambda s: f"{s[0]}x{s[1]}"),
    st.tuples(st.integers(16, 64), st.integers(16, 64)).map(lambda s: f"{s[0]}x{s[1]}"),
    st.sampled_from(["99999999999999999999x16", "16x" + "9" * 5000, "x", "0x0", "-16x16",
                     "16.5x16", "1e3x16", "nanxnan"]),
    st.text(max_size=12))


@HYPOTHESIS
@given(size=SIZES, fps=st.one_of(st.none(), FLOATS), suffix=st.sampled_from([".png", ".gif"]))
@example(size="8192x8192", fps=None, suffix=".png")
@example(size="64x64", fps=1e-300, suffix=".gif")
@example(size="64x64", fps=1e300, suffix=".gif")
def test_preview_size_and_fps(work: Path, size: str, fps: float | None, suffix: str) -> None:
    fps_args = () if fps is None else ("--fps", text_of(fps))
    out = f"p{suffix}"
    with unchanged(work, [work / "sim.npz"], allow=(out,)):
        outcome = strict("preview", "sim.npz", "-o", out, f"--size={size}", *fps_args,
                         "--max-pixels", "20000", "--max-output-pixels", "20000", "-q",
                         cwd=work, seconds=2 * QUICK)
    assert_clean(outcome)
    if outcome.code == 1:
        assert any(f in outcome.stderr for f in ("--size", "--fps", "--max-")), outcome.stderr
    (work / out).unlink(missing_ok=True)


@HYPOTHESIS
@given(kg=FLOATS, distances=st.lists(FLOATS, min_size=1, max_size=4))
@example(kg=5e-324, distances=[1e308])
@example(kg=1e9, distances=[0.0, 5e-324, 1e6])
@example(kg=1e-9, distances=[1e6, -0.0])
def test_blast_mass_and_distances(work: Path, kg: float, distances: list[float]) -> None:
    outcome = strict("blast", "--charge", text_of(kg), "--distance",
                     ",".join(map(text_of, distances)), "--json", cwd=work,
                     seconds=2 * QUICK)
    assert_clean(outcome)
    if outcome.code:
        assert "--charge" in outcome.stderr or "--distance" in outcome.stderr
    else:
        import json

        rows = json.loads(outcome.stdout)
        assert len(rows) == len(distances)
        assert all(np.isfinite(v) for row in rows for v in row.values()), rows


def test_run_takes_the_memory_budget_too(work: Path) -> None:
    """`blastvox run` had no --max-memory, so a scene whose run is over the budget could
    not be raised from it: it takes the flag, and refuses with the figure below it."""
    (work / "scene.toml").write_text(scene_text())
    need = _run_gib(work)
    line = refused(work, "run", "scene.toml", "-q", "--max-memory", repr(0.5 * need),
                   names=("voxels", "links", "--max-memory"),
                   inputs=("scene.toml", "box.stl", "sim.npz"), allow=("model.npz",),
                   seconds=30)
    assert f"about {need:.3g} GiB" in line, line
    ok = run_blastvox("run", "scene.toml", "-q", "--max-memory", repr(2 * need), cwd=work)
    assert ok.code == 0, ok.stderr
