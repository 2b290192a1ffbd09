"""Issue 18 part B: ``voxelize`` and scene input that must be refused cleanly (or work).

Each defect the tester measured has its cases here; every refusal meets the
contract of ``tests/bad_input.py``: exit 1 (2 for usage errors), one line
``blastvox: error: <file>: <problem>`` naming the file and the flag or scene
key, no traceback, inputs unchanged, no output or temporary file left.

1. the voxel budget cannot be bypassed by overflow (a tiny voxel size, a huge
   resolution), from flags, a scene and ``blastvox run``;
2. NaN, inf and huge-but-finite numbers in every voxelize flag, scene key and
   material field are refused against a documented bound (hypothesis fuzzes the
   numeric flags: success or a clean refusal, never a traceback);
3. seeds outside 0 .. 2**64 - 1;
4. a Latin-1 (non-UTF-8) OBJ loads;
5. meshio's ``sys.exit`` and prints on bad volume meshes become one line;
6. a non-UTF-8 file name works;
7. unreadable inputs (missing, a directory, a device, a FIFO, no permission)
   fail at once with exit 1 naming the file, and nothing blocks;
8. a scene's build records mesh paths relative to the scene: the same build in
   two directories gives byte-identical models;
9. an unknown explosive is refused when the scene loads.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
from pathlib import Path

import numpy as np
import pytest
import trimesh
from bad_input import assert_clean_failure, run_blastvox, unchanged
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parent.parent
HOUSE = ROOT / "examples" / "house"


@pytest.fixture
def cube(tmp_path: Path) -> Path:
    """A closed 1 m cube standing on z = 0, as OBJ."""
    mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    mesh.apply_translation((0.0, 0.0, 0.5))
    path = tmp_path / "cube.obj"
    mesh.export(path)
    return path


def _scene(tmp_path: Path, objects: str = 'voxel_size = 0.25', top: str = "",
           charges: str = "", name: str = "scene.toml") -> Path:
    text = (f'{top}\n[[objects]]\nmesh = "cube.obj"\n{objects}\n{charges}\n'
            f'[output]\nmodel = "out/model.npz"\ncache = "out/sim.npz"\n')
    path = tmp_path / name
    path.write_text(text)
    return path


def _refused(tmp_path: Path, args: tuple, names: list[str], inputs: list[Path],
             code: int = 1, words: tuple[str, ...] = (), seconds: float = 30.0) -> str:
    with unchanged(tmp_path, inputs):
        outcome = run_blastvox(*args, cwd=tmp_path)
    line = assert_clean_failure(outcome, names, code=code, words=words, seconds=seconds)
    assert outcome.stdout == "", outcome.stdout
    return line


# ------------------------------------------------------------------ 1. the voxel budget

@pytest.mark.parametrize(("flag", "value"), [
    ("--resolution", "1000000000"),
    ("--resolution", str(2**62)),
    ("--voxel-size", "1e-300"),
    ("--voxel-size", "5e-324"),           # the smallest denormal
    ("--voxel-size", "1e-300,1,1"),
    ("--voxel-size", "0.001"),            # a plain 1e9-voxel request
])
def test_budget_is_not_bypassed_by_flags(tmp_path: Path, cube: Path, flag: str,
                                         value: str) -> None:
    line = _refused(tmp_path, ("voxelize", "cube.obj", "-o", "m.npz", flag, value, "-q"),
                    ["cube.obj", flag, "--max-voxels", "4,000,000"], [cube],
                    words=("voxels", "budget"), seconds=10)
    assert "-" not in line.split("about")[-1].split("voxels")[0]  # never a wrapped count


@pytest.mark.parametrize(("key", "value"), [("voxel_size", "1e-300"),
                                            ("resolution", "1000000000")])
@pytest.mark.parametrize("command", ["voxelize", "run"])
def test_budget_is_not_bypassed_by_a_scene(tmp_path: Path, cube: Path, key: str, value: str,
                                           command: str) -> None:
    scene = _scene(tmp_path, f"{key} = {value}")
    args = ("voxelize", "--scene", "scene.toml", "-q") if command == "voxelize" else (
        "run", "scene.toml", "-q")
    _refused(tmp_path, args, ["scene.toml", f"objects[0].{key}", "--max-voxels"],
             [cube, scene], words=("budget",), seconds=10)


def test_the_budget_counts_every_object(tmp_path: Path, cube: Path) -> None:
    shutil.copy(cube, tmp_path / "cube2.obj")
    _refused(tmp_path, ("voxelize", "cube.obj", "cube2.obj", "-o", "m.npz", "--voxel-size",
                        "0.1", "--max-voxels", "1500", "-q"),
             ["cube2.obj", "--voxel-size", "1,500", "--max-voxels"], [cube],
             words=("left of the budget",))


# ------------------------------------------------------------------ 2. numbers

@pytest.mark.parametrize(("flag", "value", "words"), [
    ("--ground", "nan", ("finite",)),
    ("--ground", "inf", ("finite",)),
    ("--ground=-inf", None, ("finite",)),
    ("--ground", "1e300", ("<= 1e+06 m",)),
    ("--ground", "2e6", ("<= 1e+06 m",)),
    ("--jitter", "nan", ("finite",)),
    ("--jitter", "inf", ("finite",)),
    ("--jitter", "1e300", ("< 0.5",)),
    ("--jitter=-0.1", None, (">= 0",)),
    ("--voxel-size", "nan", ("finite",)),
    ("--voxel-size", "inf", ("finite",)),
    ("--voxel-size", "1e300", ("<= 1e+06 m",)),
    ("--voxel-size", "-0.0", ("> 0",)),
    ("--voxel-size", "0.1,nan,0.1", ("finite",)),
    ("--max-voxels", str(10**20), ("<= 100,000,000",)),
    ("--max-voxels", "0", (">= 1",)),
    ("--resolution", "0", (">= 1",)),
])
def test_numeric_flags(tmp_path: Path, cube: Path, flag: str, value: str | None,
                       words: tuple[str, ...]) -> None:
    given_flag = [flag] if value is None else [flag, value]
    _refused(tmp_path, ("voxelize", "cube.obj", "-o", "m.npz", *given_flag, "-q"),
             ["cube.obj", flag.split("=")[0]], [cube], words=words, seconds=10)


@pytest.mark.parametrize(("objects", "top", "key", "words"), [
    ("voxel_size = nan", "", "objects[0].voxel_size", ("finite",)),
    ("voxel_size = [0.1, inf, 0.1]", "", "objects[0].voxel_size", ("finite",)),
    ("voxel_size = 1e300", "", "objects[0].voxel_size", ("<= 1e+06 m",)),
    ("voxel_size = 0.25\njitter = nan", "", "objects[0].jitter", ()),
    ("voxel_size = 0.25\njitter = 1e300", "", "objects[0].jitter", ("< 0.5",)),
    ("voxel_size = 0.25\ntransform = { translate = [0, 0, 1e300] }", "",
     "objects[0].transform.translate", ("<= 1e+06 m",)),
    ("voxel_size = 0.25\ntransform = { scale = 1e300 }", "",
     "objects[0].transform.scale", ("<= 1e+06",)),
    ("voxel_size = 0.25\ntransform = { scale = [1, nan, 1] }", "",
     "objects[0].transform.scale", ("finite",)),
    ("voxel_size = 0.25\ntransform = { rotate_deg = [0, 1e300, 0] }", "",
     "objects[0].transform.rotate_deg", ("<= 1e+06 degrees",)),
    ("voxel_size = 0.25\n[[objects.rules]]\nsphere = { center = [0, 0, 0], radius = 1e300 }"
     "\nstrength_scale = 2", "", "objects[0].rules[0].sphere.radius", ("<= 1e+06",)),
    ("voxel_size = 0.25\n[[objects.rules]]\nbox = { min = [-1e300, 0, 0], max = [1, 1, 1] }"
     "\nstrength_scale = 2", "", "objects[0].rules[0].box.min", (">= -1e+06 m",)),
    ("voxel_size = 0.25\n[[objects.rules]]\nhalfspace = { point = [0, 0, 0], normal = "
     "[0, 0, 1e300] }\nstrength_scale = 2", "", "objects[0].rules[0].halfspace.normal",
     ("<= 1e+06",)),
    ("voxel_size = 0.25\n[[objects.rules]]\nhalfspace = { point = [0, 0, 0], normal = "
     "[0, 0, 1] }\nstrength_scale = 1e300", "", "objects[0].rules[0].strength_scale",
     ("<= 1e+06",)),
    ("voxel_size = 0.25", "ground = nan", "ground", ("finite",)),
    ("voxel_size = 0.25", "ground = 1e300", "ground", ("<= 1e+06 m",)),
    ("voxel_size = 0.25", "seed = -1", "seed", (">= 0",)),
    ("voxel_size = 0.25", "[camera]\nposition = [0, 0, 1e300]\nlook_at = [0, 0, 0]",
     "camera.position", ("<= 1e+06 m",)),
    ("voxel_size = 0.25", "[materials.m]\nbase = 'brick'\ndensity = 1e300",
     "materials.m.density", ("<= 100000",)),
    ("voxel_size = 0.25", "[materials.m]\nbase = 'brick'\nlink_yield_mean = nan",
     "materials.m.link_yield_mean", ("nan",)),
    ("voxel_size = 0.25", "[materials.m]\nbase = 'brick'\nvoxel_yield_var = 1e300",
     "materials.m.voxel_yield_var", ("<= 1e+12",)),
    ("voxel_size = 0.25", "[materials.m]\nbase = 'brick'\nlink_impulse = inf",
     "materials.m.link_impulse", ("finite",)),
    ("voxel_size = 0.25", "[materials.m]\nbase = 'brick'\nfoundation_yield = 1e13",
     "materials.m.foundation_yield", ("<= 1e+12",)),
])
def test_numeric_scene_keys(tmp_path: Path, cube: Path, objects: str, top: str, key: str,
                            words: tuple[str, ...]) -> None:
    # tables ([camera], [materials.m]) must come after the top-level keys and objects
    scene = tmp_path / "scene.toml"
    head, _, tables = top.partition("[") if top.startswith("[") else (top, "", "")
    scene.write_text(f'{head}\n[[objects]]\nmesh = "cube.obj"\n{objects}\n'
                     + (f"[{tables}\n" if tables else ""))
    _refused(tmp_path, ("voxelize", "--scene", "scene.toml", "-o", "m.npz", "-q"),
             ["scene.toml", key], [cube, scene], words=words, seconds=10)


@pytest.mark.parametrize(("field", "value", "words"), [
    ("density", "1e300", ("<= 100000",)),
    ("restitution", "1.5", ("[0, 1]",)),
    ("restitution", "inf", ("finite",)),
    ("link_yield_var", "nan", ("finite",)),
    ("pi_shape", "1e300", ("<= 1e+06",)),
])
def test_numeric_material_fields(tmp_path: Path, cube: Path, field: str, value: str,
                                 words: tuple[str, ...]) -> None:
    library = tmp_path / "lib.toml"
    library.write_text(f'[oak]\nbase = "wood"\n{field} = {value}\n')
    _refused(tmp_path, ("voxelize", "cube.obj", "-o", "m.npz", "--materials", "lib.toml",
                        "--material", "oak", "-q"),
             ["lib.toml", f"oak.{field}"], [cube, library], words=words, seconds=10)


@pytest.mark.parametrize(("coordinate", "transform"), [
    (1e300, ""), (2e6, ""), (2.0, "scale = 1e6"), (1.0, "translate = [0, 0, 999999.5]")])
def test_mesh_coordinates_are_bounded(tmp_path: Path, coordinate: float,
                                      transform: str) -> None:
    mesh = tmp_path / "far.obj"
    c = coordinate
    mesh.write_text(f"v 0 0 0\nv {c} 0 0\nv 0 {c} 0\nv 0 0 {c}\n"
                    "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    if transform:
        scene = tmp_path / "scene.toml"
        scene.write_text(f'[[objects]]\nmesh = "far.obj"\nresolution = 4\n'
                         f"transform = {{ {transform} }}\n")
        _refused(tmp_path, ("voxelize", "--scene", "scene.toml", "-o", "m.npz", "-q"),
                 ["scene.toml", "objects[0].transform", "far.obj", "1e+06 m"], [mesh, scene],
                 seconds=10)
    else:
        _refused(tmp_path, ("voxelize", "far.obj", "-o", "m.npz", "-q"),
                 ["far.obj", "1e+06 m"], [mesh], words=("coordinates",), seconds=10)


def test_a_voxel_below_a_micrometre_is_refused(tmp_path: Path) -> None:
    mesh = trimesh.creation.box(extents=(1e-5, 1e-5, 1e-5))
    mesh.export(tmp_path / "dust.stl")
    _refused(tmp_path, ("voxelize", "dust.stl", "-o", "m.npz", "-q"),
             ["dust.stl", "--resolution 32", "1e-06 m"], [tmp_path / "dust.stl"],
             words=("smallest voxel size",), seconds=10)


def _fuzz_one(tmp_path: Path, args: list[str], flag: str) -> None:
    out = tmp_path / "fuzz.npz"
    outcome = run_blastvox("voxelize", "cube.obj", "-o", out.name, "--max-voxels", "2000",
                           *args, "-q", cwd=tmp_path)
    assert "Traceback" not in outcome.stderr, outcome.stderr
    if outcome.code == 0:
        assert out.is_file() and outcome.stderr == ""
        out.unlink()
    else:
        line = assert_clean_failure(outcome, ["cube.obj"], seconds=20)
        assert not out.exists() and not list(tmp_path.glob("*.partial*")), line


_FLOAT_TEXT = st.floats().map(repr) | st.sampled_from(
    ["nan", "inf", "-inf", "1e308", "-0.0", "5e-324", "2.2250738585072014e-308", "1e-300",
     "0.25", "0.3", "1e6", "1e6000"])


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=_FLOAT_TEXT, flag=st.sampled_from(["--voxel-size", "--ground", "--jitter"]))
@example(text="0.3", flag="--voxel-size")
@example(text="-0.0", flag="--ground")
@example(text="0.49999999999999994", flag="--jitter")
def test_fuzz_float_flags(tmp_path: Path, cube: Path, text: str, flag: str) -> None:
    args = [f"{flag}={text}"]
    if flag != "--voxel-size":
        args += ["--voxel-size", "0.25"]
    _fuzz_one(tmp_path, args, flag)


@settings(max_examples=15, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(value=st.integers(-2**70, 2**70) | st.integers(0, 40))
@example(value=2**63)
@example(value=1)
def test_fuzz_resolution(tmp_path: Path, cube: Path, value: int) -> None:
    _fuzz_one(tmp_path, [f"--resolution={value}"], "--resolution")


# ------------------------------------------------------------------ 3. seeds

@pytest.mark.parametrize("seed", ["-1", str(2**64), str(10**30)])
def test_seed_out_of_range(tmp_path: Path, cube: Path, seed: str) -> None:
    _refused(tmp_path, ("voxelize", "cube.obj", "-o", "m.npz", f"--seed={seed}", "-q"),
             ["cube.obj", "--seed"], [cube], seconds=10)


def test_largest_seed_works(tmp_path: Path, cube: Path) -> None:
    outcome = run_blastvox("voxelize", "cube.obj", "-o", "m.npz", "--voxel-size", "0.25",
                           "--jitter", "0.3", f"--seed={2**64 - 1}", "-q", cwd=tmp_path)
    assert outcome.code == 0, outcome.stderr


# ------------------------------------------------------------------ 4. text encodings

def test_latin1_obj_loads(tmp_path: Path, cube: Path) -> None:
    latin = tmp_path / "caf\u00e9.obj"
    latin.write_bytes(b"# caf\xe9 cr\xe8me br\xfbl\xe9e\no caf\xe9\n" + cube.read_bytes())
    outcome = run_blastvox("voxelize", latin.name, "-o", "m.npz", "--voxel-size", "0.25",
                           "-q", cwd=tmp_path)
    assert outcome.code == 0, outcome.stderr
    from blastvox.model import VoxelModel

    assert VoxelModel.load(tmp_path / "m.npz").summary()["voxel_count"] == 64


# ------------------------------------------------------------------ 5. meshio

@pytest.mark.parametrize(("name", "data"), [
    ("empty.vtu", b""),
    ("blank.vtu", b" "),
    ("truncated.vtu", b'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid"'),
    ("garbage.msh", b"\x00\x01garbage\xff" * 100),
    ("truncated.msh", b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n10\n1 0 0 0\n"),
    ("truncated4.msh", b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 10 1 10\n"),
    ("bad.vtk", b"# vtk DataFile Version 2.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\n"),
    ("dangling.msh", b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n"
                     b"3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 0 1 2 3 99\n"
                     b"$EndElements\n"),
])
def test_bad_volume_meshes(tmp_path: Path, name: str, data: bytes) -> None:
    path = tmp_path / name
    path.write_bytes(data)
    _refused(tmp_path, ("voxelize", name, "-o", "m.npz", "-q"), [name], [path], seconds=10)


# ------------------------------------------------------------------ 6. file names

def test_non_utf8_file_name(tmp_path: Path, cube: Path) -> None:
    name = os.fsdecode(b"\xff-cube.obj")  # a surrogate escape on Linux
    (tmp_path / name).write_bytes(cube.read_bytes())
    outcome = run_blastvox("voxelize", name, "-o", "m.npz", "--voxel-size", "0.25", "-q",
                           cwd=tmp_path)
    assert outcome.code == 0, outcome.stderr
    with np.load(tmp_path / "m.npz") as data:
        meta = json.loads(bytes(data["meta"]).decode("utf-8"))
    # compared as ascii(): a failure report holding a lone surrogate would crash
    # pytest-xdist's transport (an INTERNALERROR that ends the whole run)
    assert ascii(meta["objects"][0]["source"]) == ascii("\\xff-cube.obj")
    assert ascii(meta["objects"][0]["name"]) == ascii("\\xff-cube")


def test_non_utf8_file_name_in_an_error(tmp_path: Path) -> None:
    name = os.fsdecode(b"\xfe-missing.obj")
    _refused(tmp_path, ("voxelize", name, "-o", "m.npz", "-q"), ["\\xfe-missing.obj"], [],
             words=("no such file",))


# ------------------------------------------------------------------ 7. unreadable inputs

def _fifo(tmp_path: Path, name: str) -> Path:
    path = tmp_path / name
    os.mkfifo(path)
    return path


@pytest.mark.parametrize(("make", "words"), [
    (lambda d: d / "missing.obj", ("no such file",)),
    (lambda d: (d / "dir.obj").mkdir() or d / "dir.obj", ("directory",)),
    (lambda d: _fifo(d, "fifo.obj"), ("FIFO",)),
    (lambda d: Path("/dev/zero"), ("device",)),
    (lambda d: Path("/dev/urandom"), ("device",)),
    (lambda d: (d / "empty.obj").write_bytes(b"") and None or d / "empty.obj", ("empty",)),
    (lambda d: d / "cube.obj" / "x.obj", ("cannot read",)),
])
def test_unreadable_mesh(tmp_path: Path, cube: Path, make, words: tuple[str, ...]) -> None:
    path = make(tmp_path)
    shown = str(path.relative_to(tmp_path)) if path.is_relative_to(tmp_path) else str(path)
    _refused(tmp_path, ("voxelize", shown, "-o", "m.npz", "-q"), [shown], [cube],
             words=words, seconds=5)


def test_unreadable_second_mesh_fails_before_any_work(tmp_path: Path, cube: Path) -> None:
    _fifo(tmp_path, "fifo.obj")
    _refused(tmp_path, ("voxelize", "cube.obj", "fifo.obj", "-o", "m.npz", "-q"),
             ["fifo.obj"], [cube], words=("FIFO",), seconds=5)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_mesh_without_permission(tmp_path: Path, cube: Path) -> None:
    cube.chmod(0)
    try:
        _refused(tmp_path, ("voxelize", "cube.obj", "-o", "m.npz", "-q"), ["cube.obj"], [],
                 words=("permission",), seconds=5)
    finally:
        cube.chmod(stat.S_IRUSR | stat.S_IWUSR)


def test_mesh_refused_by_the_os(tmp_path: Path, cube: Path,
                                monkeypatch: pytest.MonkeyPatch) -> None:
    """EACCES as a non-root user sees it (the test may run as root)."""
    import blastvox.voxelize.mesh_io as mesh_io

    def refuse(path, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(mesh_io, "open", refuse, raising=False)
    _refused(tmp_path, ("voxelize", "cube.obj", "-o", "m.npz", "-q"), ["cube.obj"], [cube],
             words=("permission denied",), seconds=5)


@pytest.mark.parametrize("option", ["--scene", "--materials"])
@pytest.mark.parametrize("kind", ["fifo", "dir", "/dev/zero", "missing"])
def test_unreadable_toml(tmp_path: Path, cube: Path, option: str, kind: str) -> None:
    if kind == "fifo":
        name = _fifo(tmp_path, "x.toml").name
    elif kind == "dir":
        (tmp_path / "x.toml").mkdir()
        name = "x.toml"
    else:
        name = "missing.toml" if kind == "missing" else kind
    args = (("voxelize", "--scene", name, "-o", "m.npz", "-q") if option == "--scene" else
            ("voxelize", "cube.obj", "--materials", name, "-o", "m.npz", "-q"))
    _refused(tmp_path, args, [name], [cube], seconds=5)


def test_unreadable_scene_for_run(tmp_path: Path) -> None:
    _fifo(tmp_path, "scene.toml")
    _refused(tmp_path, ("run", "scene.toml", "-q"), ["scene.toml"], [], words=("FIFO",),
             seconds=5)


# ------------------------------------------------------------------ 8. recorded paths

def _house_copy(where: Path) -> Path:
    """examples/house copied to where/examples/house, its meshes beside its scene."""
    target = where / "examples" / "house"
    shutil.copytree(HOUSE, target)
    return target


@pytest.mark.parametrize("command", ["voxelize", "run"])
def test_a_build_elsewhere_is_byte_identical(tmp_path: Path, command: str) -> None:
    first = _house_copy(tmp_path / "a")
    second = _house_copy(tmp_path / "deeper" / "checkout" / "b")
    models = []
    for house, cwd in ((first, tmp_path / "a"), (second, second)):
        scene = house / "scene.toml"
        if command == "run":  # voxelize only: a scene without charges stops after it
            text = scene.read_text()
            scene.write_text(text[:text.index("[[charges]]")] + text[text.index("[simulation]"):])
            outcome = run_blastvox("run", scene.relative_to(cwd), "-q", cwd=cwd)
            assert outcome.code == 1 and "charges" in outcome.stderr, outcome.stderr
        else:
            outcome = run_blastvox("voxelize", "--scene", scene.relative_to(cwd), "-q", cwd=cwd)
            assert outcome.code == 0, outcome.stderr
        models.append(house.parent.parent / "out" / "house" / "model.npz")
    assert models[0].read_bytes() == models[1].read_bytes()
    with np.load(models[0]) as data:
        meta = json.loads(bytes(data["meta"]).decode("utf-8"))
    assert meta["objects"][0]["source"] == "house.obj"
    assert str(tmp_path) not in json.dumps(meta)


def test_a_mesh_argument_is_recorded_as_given(tmp_path: Path, cube: Path) -> None:
    (tmp_path / "sub").mkdir()
    outcome = run_blastvox("voxelize", "../cube.obj", "-o", "m.npz", "--voxel-size", "0.25",
                           "-q", cwd=tmp_path / "sub")
    assert outcome.code == 0, outcome.stderr
    with np.load(tmp_path / "sub" / "m.npz") as data:
        meta = json.loads(bytes(data["meta"]).decode("utf-8"))
    assert meta["objects"][0]["source"] == "../cube.obj"
    assert meta["settings"]["objects"][0]["mesh"] == "cube.obj"


# ------------------------------------------------------------------ 9. explosives

def test_unknown_explosive_is_refused_when_the_scene_loads(tmp_path: Path, cube: Path) -> None:
    scene = _scene(tmp_path, charges='[[charges]]\nposition = [0, 0, 0]\nmass_kg = 1.0\n'
                   '[[charges]]\nposition = [0, 0, 0]\nmass_kg = 1.0\nexplosive = "semtexx"\n')
    for args in (("voxelize", "--scene", "scene.toml", "-q"), ("run", "scene.toml", "-q")):
        _refused(tmp_path, args, ["scene.toml", "charges[1].explosive", "'semtexx'",
                                  "known: anfo, c4"], [cube, scene], seconds=5)


def test_explosive_aliases_still_load(tmp_path: Path) -> None:
    from blastvox.scene import scene_from_dict

    scene = scene_from_dict({"objects": [{"mesh": "a.obj"}], "charges": [
        {"position": [0, 0, 0], "mass_kg": 1, "explosive": name}
        for name in ("TNT", "C-4", "composition b", "Semtex")]}, "scene.toml", tmp_path)
    assert [c.explosive for c in scene.charges] == ["TNT", "C-4", "composition b", "Semtex"]


def test_one_mesh_given_twice_is_refused_and_same_stems_get_distinct_names(
        cube: Path, tmp_path: Path) -> None:
    """Two copies of one solid overlap and push each other apart from the first step;
    two files of one stem (a/cube.obj, b/cube.obj) are two objects, named apart."""
    with unchanged(tmp_path, [cube]):
        outcome = run_blastvox("voxelize", cube, "cube.obj", "--voxel-size", "0.25", "-q",
                               "-o", "m.npz", cwd=tmp_path)
    assert_clean_failure(outcome, ["cube.obj"], words=["given twice"])
    other = tmp_path / "b" / "cube.obj"
    other.parent.mkdir()
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).apply_translation((3.0, 0.0, 0.5)).export(
        other)
    outcome = run_blastvox("voxelize", cube, other, "--voxel-size", "0.25", "-q", "-o",
                           "m.npz", cwd=tmp_path)
    assert outcome.code == 0, outcome.stderr
    from blastvox.model import VoxelModel

    names = [o["name"] for o in VoxelModel.load(tmp_path / "m.npz").meta["objects"]]
    assert names == ["cube", "cube_2"]


def test_a_conform_refusal_names_the_setting_that_asked_for_it(tmp_path: Path) -> None:
    """Suzanne is open: conform voxels need a closed manifold. From a scene the line
    names its key, from the command line the flag."""
    shutil.copy(ROOT / "tests" / "data" / "suzanne.ply", tmp_path / "suzanne.ply")
    (tmp_path / "scene.toml").write_text(
        '[[objects]]\nmesh = "suzanne.ply"\nresolution = 20\nshape = "conform"\n'
        '[output]\nmodel = "m.npz"\ncache = "s.npz"\n')
    with unchanged(tmp_path, [tmp_path / "suzanne.ply", tmp_path / "scene.toml"]):
        outcome = run_blastvox("voxelize", "--scene", "scene.toml", "-q", cwd=tmp_path)
    line = assert_clean_failure(outcome, ["suzanne.ply", 'objects[0].shape = "conform"'],
                                words=["closed manifold", 'use shape = "cube"'])
    assert "--shape" not in line
    with unchanged(tmp_path, [tmp_path / "suzanne.ply"], allow=["scene.toml"]):
        outcome = run_blastvox("voxelize", "suzanne.ply", "--resolution", "20", "--shape",
                               "conform", "-q", "-o", "m.npz", cwd=tmp_path)
    assert_clean_failure(outcome, ["suzanne.ply", "--shape conform"], words=["--shape cube"])


def test_a_ply_whose_face_names_a_missing_vertex_is_one_line(tmp_path):
    """Issue 36: a PLY (or glTF) face index past the vertex list was an IndexError
    traceback from deep in the voxelizer; now one line naming the file and the index."""
    header = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
              "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
              "end_header\n")
    body = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 99\n"
    (tmp_path / "bad.ply").write_text(header + body)
    outcome = run_blastvox("voxelize", "bad.ply", "-o", "m.npz", "--resolution", "8",
                           cwd=tmp_path)
    assert_clean_failure(outcome, ["bad.ply", "99"], words=["4 vertices"])
    assert not (tmp_path / "m.npz").exists()


@pytest.mark.parametrize("depth, words", [(40, ["32 levels"]), (6000, ["nested more"])])
def test_a_scene_nested_too_deep_is_one_line(tmp_path, depth, words):
    """A scene TOML nested 5,000+ deep was a RecursionError traceback (tomllib parses
    recursively); 40 deep would recurse in the stages after it. One line each."""
    (tmp_path / "deep.toml").write_text("a = " + "[" * depth + "]" * depth + "\n")
    outcome = run_blastvox("run", "deep.toml", cwd=tmp_path)
    assert_clean_failure(outcome, ["deep.toml"], words=words)


@pytest.mark.parametrize("count", [0, 1000])
def test_a_binary_stl_whose_header_count_lies_says_so(tmp_path, count):
    """Issue 36: a binary STL whose header's triangle count lies was called empty
    ("contains no triangles": it holds 12); the line now says both counts."""
    trimesh.creation.box().export(tmp_path / "box.stl")
    data = bytearray((tmp_path / "box.stl").read_bytes())
    data[80:84] = count.to_bytes(4, "little")
    (tmp_path / "lie.stl").write_bytes(bytes(data))
    outcome = run_blastvox("voxelize", "lie.stl", "-o", "m.npz", "--resolution", "8",
                           cwd=tmp_path)
    assert_clean_failure(outcome, ["lie.stl", f"{count:,} triangles", "holds 12"])
