"""Exports that never destroy the last good output (issue 36, item 4).

A USD export is written into a private folder beside its output and moved into
place, its textures folder first, only when everything is written: a re-export that
fails (a file-size limit standing in for a full disk, an error, Ctrl-C) leaves the
previous export and its textures byte for byte, and no ``.partial`` file or
textures folder behind; USD's errors are one line (a full disk printed 9,963 lines
of C++ errors). Temporaries are named after their writer's host and process, so a
killed writer's are cleaned by the next write and a live one's (another wedge in
the same folder) never are. A wedge records each finished shot's files (size and
SHA-256) and runs a shot whose files changed again.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import trimesh
from bad_input import assert_clean_failure, listing, run_blastvox, snapshot, unchanged

from blastvox.io import atomic

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def shot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """sim.npz of a small wall (fractured: it has a damage texture)."""
    root = tmp_path_factory.mktemp("shot")
    trimesh.creation.box(extents=(2.0, 0.5, 2.0)).export(root / "wall.stl")
    for args in (("voxelize", "wall.stl", "-o", "model.npz", "--voxel-size", "0.25",
                  "--up-axis", "Z", "-q"),
                 ("simulate", "model.npz", "-o", "sim.npz", "--charge", "0,-1.5,0.5:2",
                  "--duration", "0.2", "-q")):
        assert run_blastvox(*args, cwd=root).code == 0
    return root


@pytest.fixture()
def exported(shot: Path, tmp_path: Path) -> Path:
    """A folder with sim.npz and a good export of it: shot.usdc and shot_textures/."""
    (tmp_path / "sim.npz").write_bytes((shot / "sim.npz").read_bytes())
    assert run_blastvox("export", "sim.npz", "-o", "shot.usdc", "-q", cwd=tmp_path).code == 0
    assert list((tmp_path / "shot_textures").glob("*.png"))
    return tmp_path


def _files(folder: Path) -> dict[Path, str]:
    return snapshot(p for p in folder.rglob("*") if p.is_file())


def _limited(cwd: Path, limit: int, *args: str) -> subprocess.CompletedProcess:
    """``blastvox ARGS`` in a child that may write no file larger than ``limit`` bytes
    (EFBIG where the disk would be full: a full disk cannot be made without root)."""
    def limit_writes() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return subprocess.run([sys.executable, "-m", "blastvox", *args], cwd=cwd, text=True,
                          capture_output=True, timeout=60, preexec_fn=limit_writes,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})


@pytest.mark.parametrize("output", ["shot.usdc", "shot.usda"])
def test_a_re_export_onto_a_full_disk_keeps_the_last_good_one(exported: Path,
                                                             output: str) -> None:
    """The limit lets the textures be written and stops the USD file: before, the new
    textures had replaced the old ones and were then deleted (the folder left empty),
    and a .usda printed 9,963 lines of USD's C++ errors. Particles as spheres: the
    volume files would meet the limit first (see the next test but one)."""
    largest = max(p.stat().st_size for p in (exported / "shot_textures").iterdir())
    limit = largest + 4096
    assert limit < (exported / "shot.usdc").stat().st_size
    if output == "shot.usda":  # a good .usda first, to be kept
        assert run_blastvox("export", "sim.npz", "-o", output, "-q", cwd=exported).code == 0
    before, names = _files(exported), listing(exported)
    done = _limited(exported, limit, "export", "sim.npz", "-o", output, "-q",
                    "--particles", "spheres")
    assert done.returncode == 1, done.stderr[-2000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert lines[0].startswith(f"blastvox: error: {output}: cannot write"), lines
    assert "File too large" in lines[0]
    assert _files(exported) == before and listing(exported) == names


def test_a_texture_that_cannot_be_written_names_its_place(exported: Path) -> None:
    before, names = _files(exported), listing(exported)
    done = _limited(exported, 1000, "export", "sim.npz", "-o", "shot.usdc", "-q",
                    "--particles", "spheres")
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        "blastvox: error: shot_textures/damage_concrete.png: cannot write (File too large)"]
    assert _files(exported) == before and listing(exported) == names


def test_a_volume_file_that_cannot_be_written_names_its_place(exported: Path) -> None:
    """The particle volumes (written first) meet the limit: one line naming the .vdb
    file where it was to go; the previous export, its volumes included, is whole."""
    assert list((exported / "shot_volumes").glob("*.vdb"))
    before, names = _files(exported), listing(exported)
    done = _limited(exported, 1000, "export", "sim.npz", "-o", "shot.usdc", "-q")
    assert done.returncode == 1
    (line,) = done.stderr.strip().splitlines()
    assert re.fullmatch(r"blastvox: error: shot_volumes/dust\.\d{4}\.vdb: cannot write "
                        r"\(File too large\)", line), line
    assert _files(exported) == before and listing(exported) == names


@pytest.mark.parametrize("failure", [KeyboardInterrupt, RuntimeError])
def test_a_failure_after_the_textures_keeps_the_old_ones(exported: Path, failure,
                                                        monkeypatch) -> None:
    """Whatever stops the export once its new textures are written (here: the USD file's
    write), the previous export is whole and nothing is left behind."""
    import blastvox.export.usd as usd

    def fail(layer, path):
        raise failure("stopped")

    monkeypatch.setattr(usd, "_export_layer", fail)
    with unchanged(exported, list(exported.rglob("*.*"))):
        with pytest.raises(failure):
            from blastvox.cache import SimCache
            from blastvox.export.api import export

            export(SimCache.load(exported / "sim.npz"), exported / "shot.usdc")


def test_a_new_export_replaces_the_textures_and_keeps_other_files(exported: Path) -> None:
    """The textures folder is swapped in whole; a file in it the export does not write
    (another export's, with the same stem) is kept."""
    (exported / "shot_textures" / "mine.png").write_bytes(b"keep me")
    damage = exported / "shot_textures" / "damage_concrete.png"
    good = damage.read_bytes()
    damage.write_bytes(b"stale")
    assert run_blastvox("export", "sim.npz", "-o", "shot.usdc", "-q", cwd=exported).code == 0
    assert damage.read_bytes() == good
    assert (exported / "shot_textures" / "mine.png").read_bytes() == b"keep me"
    assert not [p for p in listing(exported) if p.endswith(".partial")]


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_killed_writer_s_temporaries_are_cleaned_a_live_one_s_never(exported: Path) -> None:
    """A SIGKILLed export leaves .<name>.<host>-<pid>.<random>.partial (a file or the
    staging folder); the next export of that name removes it once the process is gone,
    and leaves a running writer's alone (two wedges into one folder deleted each
    other's files mid-write)."""
    tag = atomic.writer_tag().rsplit("-", 1)[0]
    dead = exported / f".shot.usdc.{tag}-{_dead_pid()}.abcd1234.partial"
    dead.mkdir()
    (dead / "shot.usdc").write_bytes(b"half")
    dead_file = exported / f".shot.usdc.{tag}-{_dead_pid()}.efgh5678.partial"
    dead_file.write_bytes(b"half")
    with subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]) as live:
        try:
            alive = exported / f".shot.usdc.{tag}-{live.pid}.ijkl9012.partial"
            alive.write_bytes(b"being written")
            other = exported / f".sim.npz.{tag}-{_dead_pid()}.mnop3456.partial"
            other.write_bytes(b"another output's")
            assert run_blastvox("export", "sim.npz", "-o", "shot.usdc", "-q",
                                cwd=exported).code == 0
            assert not dead.exists() and not dead_file.exists()
            assert alive.read_bytes() == b"being written"
            assert other.exists()  # only the output being written cleans its own
        finally:
            live.kill()


def test_the_swap_without_an_atomic_exchange(exported: Path, monkeypatch) -> None:
    """Where renameat2 cannot exchange, the old folder is moved aside first, and put back
    if the export fails after it."""
    monkeypatch.setattr(atomic, "exchange", lambda a, b: False)
    final, new = exported / "shot_textures", exported / "new"
    new.mkdir()
    (new / "damage_concrete.png").write_bytes(b"new")
    old = (final / "damage_concrete.png").read_bytes()
    with pytest.raises(RuntimeError), atomic.swapped_in(new, final):
        assert (final / "damage_concrete.png").read_bytes() == b"new"
        raise RuntimeError
    assert (final / "damage_concrete.png").read_bytes() == old
    with atomic.swapped_in(new, final):
        pass
    assert (final / "damage_concrete.png").read_bytes() == b"new"


# --- a wedge checks the files of a finished shot ---------------------------------

SCENE = """\
up_axis = "Z"

[[objects]]
mesh = "wall.stl"
voxel_size = 0.25

[[charges]]
position = [0.0, -1.5, 0.5]
mass_kg = 2.0

[simulation]
duration = 0.1

[output]
model = "out/model.npz"
cache = "out/sim.npz"
export = "out/shot.usda"
"""


def test_a_wedge_runs_a_corrupted_finished_shot_again(shot: Path, tmp_path: Path) -> None:
    """A finished shot's sim.npz changed in place (same size, same time) was called up to
    date; its result now records each file's size and SHA-256, checked first."""
    from blastvox.wedge.plan import plan_wedge
    from blastvox.wedge.shot import cached_result, run_shot

    (tmp_path / "wall.stl").write_bytes((shot / "wall.stl").read_bytes())
    (tmp_path / "scene.toml").write_text(SCENE)
    spec = plan_wedge(tmp_path / "scene.toml", ["seed=0"], out=tmp_path / "w",
                      preview=False).shots[0]
    assert run_shot(spec)["status"] == "ran"
    directory = Path(spec.directory)
    recorded = json.loads((directory / "result.json").read_text())["files"]
    assert {"model.npz", "sim.npz", "shot.usda"} <= set(recorded)
    assert any(name.startswith("shot_textures/") for name in recorded)
    assert cached_result(spec) is not None and "files" not in cached_result(spec)
    good = {p: p.read_bytes() for p in directory.rglob("*") if p.is_file()
            and p.name not in ("result.json", "log.txt")}
    sim = directory / "sim.npz"
    data = bytearray(sim.read_bytes())
    data[len(data) // 2] ^= 0xFF
    times = (sim.stat().st_atime_ns, sim.stat().st_mtime_ns)
    sim.write_bytes(bytes(data))
    os.utime(sim, ns=times)
    assert cached_result(spec) is None
    assert run_shot(spec)["status"] == "ran"
    assert hashlib.sha256(sim.read_bytes()).hexdigest() == recorded["sim.npz"]["sha256"]
    assert {p: p.read_bytes() for p in good} == good
    texture = next(directory.glob("shot_textures/*.png"))
    texture.write_bytes(b"not a png")
    assert cached_result(spec) is None
    run_shot(spec)
    assert texture.read_bytes() == good[texture] and cached_result(spec) is not None


def test_a_wedge_shot_leaves_a_live_writer_s_temporary_alone(shot: Path, tmp_path: Path
                                                              ) -> None:
    from blastvox.wedge.plan import plan_wedge
    from blastvox.wedge.shot import run_shot

    (tmp_path / "wall.stl").write_bytes((shot / "wall.stl").read_bytes())
    (tmp_path / "scene.toml").write_text(SCENE)
    spec = plan_wedge(tmp_path / "scene.toml", ["seed=0"], out=tmp_path / "w",
                      preview=False).shots[0]
    directory = Path(spec.directory)
    directory.mkdir(parents=True)
    tag = atomic.writer_tag().rsplit("-", 1)[0]
    dead = directory / f".sim.npz.{tag}-{_dead_pid()}.abcd1234.partial"
    dead.write_bytes(b"killed")
    with subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]) as live:
        try:
            alive = directory / f".result.json.{tag}-{live.pid}.abcd1234.partial"
            alive.write_bytes(b"another wedge's")
            assert run_shot(spec)["status"] == "ran"
            assert not dead.exists() and alive.exists()
        finally:
            live.kill()


def test_an_export_error_from_usd_is_one_line(exported: Path, monkeypatch) -> None:
    """A Tf.ErrorException (every C++ error of the write in one message) is one line."""
    from pxr import Tf

    import blastvox.export.usd as usd

    def fail(layer, path):
        Tf.RaiseRuntimeError("Error occurred writing file: No space left on device")

    monkeypatch.setattr(usd, "_export_layer", fail)
    with unchanged(exported, list(exported.rglob("*.*"))):
        outcome = run_blastvox("export", "sim.npz", "-o", "shot.usdc", "-q", cwd=exported)
    assert_clean_failure(outcome, ["shot.usdc", "No space left on device"])
