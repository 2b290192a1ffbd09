"""Tests for blastvox.scene: the scene-file schema, its errors and path resolution."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from blastvox.errors import SceneError
from blastvox.materials import MaterialLibrary
from blastvox.scene import Box, Halfspace, Scene, Sphere, load_scene, scene_from_dict

FULL = """\
seed = 7
up_axis = "Z"
ground = 0.25
materials_file = "libs/extra.toml"

[materials.weak_brick]
base = "brick"
link_yield_mean = 20000.0

[materials.never_burns]
base = "wood"
combustibility = inf

[[objects]]
name = "house"
mesh = "meshes/house.glb"
voxel_size = [0.25, 0.25, 0.5]
shape = "conform"
jitter = 0.1
material = "Concrete"
material_map = { "Glass Pane" = "glass", Wood = "oak" }
transform = { translate = [1, 2, 3], rotate_deg = [0, 90, 0], scale = 2 }

[[objects.rules]]
box = { min = [0, 0, 0], max = [1, 1, 1] }
material = "weak_brick"

[[objects.rules]]
halfspace = { point = [0, 0, 0], normal = [0, 0, 1] }
strength_scale = 0.5

[[objects]]
mesh = "tower.obj"
resolution = 40
[[objects.rules]]
sphere = { center = [0, 0, 5], radius = 2 }
material = "never_burns"
strength_scale = 2.0

[[charges]]
position = [0, 1, 0]
mass_kg = 1
explosive = "c4"

[[charges]]
position = [5, 1, 0]
mass_kg = 0.5
time_s = 1.5

[simulation]
dt = 0.002
fps = 30
duration = 3.0
fracture = "damage"
gravity = 0.0
linear_drag = 0.1
angular_drag = 0.2
weakening = 0.25

[effects]
fire = false
camera_shake = false

[camera]
position = [10, 2, 0]
look_at = [0, 1, 0]
focal_length_mm = 50

[output]
model = "out/model.npz"
cache = "../cache/sim.npz"
export = "/abs/shot.usdc"
"""

LIB = '[oak]\nbase = "wood"\nlink_yield_mean = 15000.0\n'


@pytest.fixture
def scene_file(tmp_path: Path) -> Path:
    (tmp_path / "libs").mkdir()
    (tmp_path / "libs" / "extra.toml").write_text(LIB)
    path = tmp_path / "scene.toml"
    path.write_text(FULL)
    return path


def minimal(**extra: Any) -> dict[str, Any]:
    return {"objects": [{"mesh": "a.obj"}], **extra}


def error_of(data: Any, source: str = "scene.toml") -> str:
    with pytest.raises(SceneError) as info:
        scene_from_dict(data, source, Path("/base"))
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{source}: ")
    return message


def test_full_scene_loads(scene_file: Path) -> None:
    scene = load_scene(scene_file)
    root = scene_file.parent
    assert scene.seed == 7 and scene.up_axis == "Z" and scene.ground == 0.25
    house, tower = scene.objects
    assert house.name == "house" and tower.name == "tower"
    assert house.mesh == root / "meshes" / "house.glb"
    assert house.voxel_size == (0.25, 0.25, 0.5) and house.resolution is None
    assert tower.voxel_size is None and tower.resolution == 40
    assert house.shape == "conform" and house.jitter == 0.1
    assert house.material == "concrete"
    assert house.material_map == {"Glass Pane": "glass", "Wood": "oak"}
    assert house.transform.scale == (2.0, 2.0, 2.0)
    assert house.transform.rotate_deg == (0.0, 90.0, 0.0)
    assert isinstance(house.rules[0].region, Box) and house.rules[0].material == "weak_brick"
    assert isinstance(house.rules[1].region, Halfspace) and house.rules[1].material is None
    assert isinstance(tower.rules[0].region, Sphere)
    assert scene.charges[0].explosive == "c4" and scene.charges[1].explosive == "TNT"
    assert scene.charges[1].time_s == 1.5 and scene.charges[0].mass_kg == 1.0
    sim = scene.simulation
    assert (sim.dt, sim.fps, sim.duration, sim.fracture) == (0.002, 30.0, 3.0, "damage")
    assert (sim.gravity, sim.linear_drag, sim.angular_drag, sim.weakening) == (0.0, 0.1, 0.2, 0.25)
    assert not scene.effects.fire and not scene.effects.camera_shake and scene.effects.dust
    assert scene.camera is not None and scene.camera.focal_length_mm == 50.0
    assert scene.materials_file == root / "libs" / "extra.toml"
    assert scene.output.model == root / "out" / "model.npz"
    assert scene.output.cache == root.parent / "cache" / "sim.npz"
    assert scene.output.export == Path("/abs/shot.usdc")


def test_full_scene_round_trips_through_to_dict(scene_file: Path) -> None:
    scene = load_scene(scene_file)
    data = scene.to_dict()
    text = json.dumps(data)  # JSON-serialisable (inf as Infinity)
    assert Scene.model_validate(json.loads(text)) == scene
    assert scene_from_dict(data, "again", Path("/elsewhere")) == scene  # paths already absolute
    assert math.isinf(data["materials"]["never_burns"]["combustibility"])


def test_scene_is_frozen(scene_file: Path) -> None:
    scene = load_scene(scene_file)
    with pytest.raises(ValueError):
        scene.seed = 3  # type: ignore[misc]


def test_material_library_layers(scene_file: Path) -> None:
    lib = load_scene(scene_file).material_library()
    builtin = MaterialLibrary.builtin()
    assert lib["oak"].link_yield_mean == 15000.0  # from materials_file
    assert lib["oak"].density == builtin["wood"].density
    weak = lib["weak_brick"]
    assert weak.link_yield_mean == 20000.0
    assert weak.voxel_yield_mean == builtin["brick"].voxel_yield_mean
    assert weak.density == builtin["brick"].density and weak.color == builtin["brick"].color
    assert math.isinf(lib["never_burns"].combustibility)
    assert math.isfinite(builtin["wood"].combustibility)
    for name in builtin:
        assert lib[name] == builtin[name]


def test_inline_material_can_build_on_materials_file(tmp_path: Path) -> None:
    (tmp_path / "lib.toml").write_text(LIB)
    inline = {"old_oak": {"base": "oak", "density": 700}}
    data = minimal(materials_file="lib.toml", materials=inline)
    data["objects"][0]["material"] = "OLD_OAK"
    scene = scene_from_dict(data, "s.toml", tmp_path)
    assert scene.objects[0].material == "old_oak"
    assert scene.material_library()["old_oak"].link_yield_mean == 15000.0


def test_defaults() -> None:
    scene = Scene.model_validate(minimal())
    obj = scene.objects[0]
    assert obj.name == "a" and obj.resolution == 32 and obj.voxel_size is None
    assert obj.shape == "cube" and obj.jitter == 0.0 and obj.material == "concrete"
    assert obj.transform.scale == (1.0, 1.0, 1.0) and obj.rules == [] and obj.material_map == {}
    assert obj.mesh == Path("a.obj")  # no base_dir: left as given
    assert scene.seed == 0 and scene.up_axis == "Y" and scene.ground == "auto"
    assert scene.charges == [] and scene.camera is None and scene.output.model is None
    assert scene.simulation.dt == 1.0 / 240.0 and scene.simulation.fracture == "pressure-impulse"
    assert scene.simulation.weakening == 0.5 and scene.simulation.gravity == 9.81
    assert all(dict(scene.effects).values())
    assert scene.material_library() == MaterialLibrary.builtin()


def test_relative_paths_resolve_against_base_dir(tmp_path: Path) -> None:
    sub = tmp_path / "shots" / "a"
    scene = scene_from_dict(minimal(output={"export": "../b/x.usda"}), "s.toml", sub)
    assert scene.objects[0].mesh == sub / "a.obj"
    assert scene.output.export == tmp_path / "shots" / "b" / "x.usda"
    assert scene.objects[0].mesh.is_absolute()


@pytest.mark.parametrize("ground", ["auto", "none", "NONE", 0, -1.5])
def test_ground_forms(ground: Any) -> None:
    value = Scene.model_validate(minimal(ground=ground)).ground
    assert value == (ground.lower() if isinstance(ground, str) else float(ground))


@pytest.mark.parametrize(("data", "key", "what"), [
    ({"objects": [{"mesh": "a.obj", "voxel_size": -1}]}, "objects[0].voxel_size", "must be > 0"),
    ({"objects": [{"mesh": "a.obj", "voxel_size": [1, 0, 1]}]}, "objects[0].voxel_size",
     "must be > 0"),
    ({"objects": [{"mesh": "a.obj", "voxel_size": [1, 2]}]}, "objects[0].voxel_size",
     "list of 3 numbers"),
    ({"objects": [{"mesh": "a.obj", "voxel_size": math.inf}]}, "objects[0].voxel_size", "finite"),
    ({"objects": [{"mesh": "a.obj", "voxel_size": 1, "resolution": 8}]}, "objects[0].resolution",
     "not both"),
    ({"objects": [{"mesh": "a.obj", "resolution": 0}]}, "objects[0].resolution", "must be >= 1"),
    ({"objects": [{"mesh": "a.obj", "resolution": 2.5}]}, "objects[0].resolution",
     "must be an integer"),
    (minimal(simulation={"fracture": "foo"}), "simulation.fracture",
     "must be one of 'pressure-impulse', 'yield', 'damage' (got 'foo')"),
    (minimal(simulation={"fractur": "yield"}), "simulation.fractur",
     "unknown key (did you mean 'fracture'?)"),
    (minimal(simulaton={}), "simulaton", "unknown key (did you mean 'simulation'?)"),
    (minimal(simulation={"dt": 0}), "simulation.dt", "must be > 0"),
    (minimal(simulation={"dt": "1/240"}), "simulation.dt", "must be a number"),
    (minimal(simulation={"duration": math.nan}), "simulation.duration", "must be finite"),
    (minimal(simulation={"weakening": 1.5}), "simulation.weakening", "must be <= 1"),
    (minimal(simulation={"gravity": -9.81}), "simulation.gravity", "must be >= 0"),
    (minimal(seed=-1), "seed", "must be >= 0"),
    (minimal(seed=True), "seed", "must be an integer"),
    (minimal(up_axis="X"), "up_axis", "must be one of 'Y', 'Z'"),
    (minimal(ground="floor"), "ground", "must be 'auto', 'none' or a finite height"),
    ({"objects": []}, "objects", "at least 1"),
    ({}, "objects", "required key is missing"),
    ({"objects": [{"name": "x"}]}, "objects[0].mesh", "required key is missing"),
    ({"objects": [{"mesh": "a.obj"}, {"mesh": "b/a.stl"}]}, "objects[1].name",
     "duplicate object name 'a'"),
    ({"objects": [{"mesh": "a.obj", "jitter": 0.5}]}, "objects[0].jitter", "must be < 0.5"),
    ({"objects": [{"mesh": "a.obj", "shape": "blob"}]}, "objects[0].shape", "'cube', 'conform'"),
    ({"objects": [{"mesh": "a.obj", "transform": {"scale": [1, 0, 1]}}]},
     "objects[0].transform.scale", "must be > 0"),
    ({"objects": [{"mesh": "a.obj", "transform": {"rotate": [0, 0, 0]}}]},
     "objects[0].transform.rotate", "unknown key (did you mean 'rotate_deg'?)"),
    ({"objects": [{"mesh": "a.obj", "material": "adamantium"}]}, "objects[0].material",
     "unknown material 'adamantium' (known: brick, concrete"),
    ({"objects": [{"mesh": "a.obj", "material_map": {"Glass": "crystal"}}]},
     "objects[0].material_map.Glass", "unknown material 'crystal'"),
    ({"objects": [{"mesh": "a.obj", "rules": [
        {"box": {"min": [0, 0, 0], "max": [1, 1, 1]}, "material": "unobtainium"}]}]},
     "objects[0].rules[0].material", "unknown material 'unobtainium'"),
    ({"objects": [{"mesh": "a.obj", "rules": [{"material": "glass"}]}]},
     "objects[0].rules[0]", "exactly one of box, sphere, halfspace"),
    ({"objects": [{"mesh": "a.obj", "rules": [
        {"box": {"min": [0, 0, 0], "max": [1, 1, 1]},
         "sphere": {"center": [0, 0, 0], "radius": 1}, "material": "glass"}]}]},
     "objects[0].rules[0]", "exactly one of box, sphere, halfspace"),
    ({"objects": [{"mesh": "a.obj", "rules": [{"sphere": {"center": [0, 0, 0], "radius": 1}}]}]},
     "objects[0].rules[0]", "needs material, strength_scale or chunk_size"),
    ({"objects": [{"mesh": "a.obj", "rules": [
        {"sphere": {"center": [0, 0, 0], "radius": 0}, "material": "glass"}]}]},
     "objects[0].rules[0].sphere.radius", "must be > 0"),
    ({"objects": [{"mesh": "a.obj", "rules": [
        {"box": {"min": [0, 0, 0], "max": [1, -1, 1]}, "material": "glass"}]}]},
     "objects[0].rules[0].box.max", "must be >= min"),
    ({"objects": [{"mesh": "a.obj", "rules": [
        {"halfspace": {"point": [0, 0, 0], "normal": [0, 0, 0]}, "strength_scale": 2}]}]},
     "objects[0].rules[0].halfspace.normal", "zero vector"),
    ({"objects": [{"mesh": "a.obj", "rules": [
        {"halfspace": {"point": [0, 0, 0], "normal": [0, 1, 0]}, "strength_scale": -2}]}]},
     "objects[0].rules[0].strength_scale", "must be > 0"),
    (minimal(charges=[{"position": [0, 0, 0]}]), "charges[0].mass_kg", "required key is missing"),
    (minimal(charges=[{"position": [0, 0, 0], "mass_kg": 0}]), "charges[0].mass_kg", "> 0"),
    (minimal(charges=[{"position": [0, 0], "mass_kg": 1}]), "charges[0].position",
     "list of 3 finite numbers"),
    (minimal(charges=[{"position": [0, 0, 0], "mass_kg": 1, "time_s": -1}]), "charges[0].time_s",
     "must be >= 0"),
    (minimal(effects={"fire": "yes"}), "effects.fire", "must be true or false"),
    (minimal(effects={"smoke": True}), "effects.smoke", "unknown key"),
    (minimal(camera={"position": [1, 2, 3], "look_at": [1, 2, 3]}), "camera.look_at",
     "must differ from position"),
    (minimal(camera={"position": [1, 2, 3]}), "camera.look_at", "required key is missing"),
    # 1e308 mm gave the .glb a yfov of 0, which the Khronos validator rejects
    (minimal(camera={"position": [1, 2, 3], "look_at": [0, 0, 0], "focal_length_mm": 1e308}),
     "camera.focal_length_mm", "must be <= 10000"),
    (minimal(camera={"position": [1, 2, 3], "look_at": [0, 0, 0], "focal_length_mm": 0.5}),
     "camera.focal_length_mm", "must be >= 1"),
    (minimal(simulation={"contact_substeps": 0}), "simulation.contact_substeps", "must be >= 1"),
    (minimal(output={"cache": ""}), "output.cache", "non-empty path"),
    (minimal(materials={"m": {"base": "brick", "density": -1}}), "materials.m.density",
     "must be > 0"),
    (minimal(materials={"m": {"base": "brick", "yield": 1}}), "materials.m.yield", "unknown key"),
    (minimal(materials={"m": {"density": 1}}), "materials.m", "new material is missing"),
    (minimal(materials={"m": 3}), "materials.m", "must be a table"),
    (minimal(materials_file="nope.toml"), "materials_file", "nope.toml: file not found"),
    (minimal(simulation=3), "simulation", "must be a table"),
])
def test_bad_input_names_file_and_key(data: dict, key: str, what: str) -> None:
    message = error_of(data)
    assert message.startswith(f"scene.toml: {key}: "), message
    assert what in message, message


def test_several_errors_are_counted() -> None:
    message = error_of(minimal(seed=-1, simulation={"dt": 0, "fps": 0}))
    assert message.endswith("(+2 more)"), message


def test_not_a_table() -> None:
    assert "must be a table" in error_of([1, 2])


def test_bad_materials_file_names_both_files(tmp_path: Path) -> None:
    (tmp_path / "lib.toml").write_text("[oak]\nbase = 'wood'\nrestitution = 2\n")
    with pytest.raises(SceneError) as info:
        scene_from_dict(minimal(materials_file="lib.toml"), "scene.toml", tmp_path)
    assert str(info.value) == (f"scene.toml: materials_file: {tmp_path / 'lib.toml'}: "
                               "oak.restitution: must be in [0, 1] (got 2.0)")


def test_load_scene_file_errors(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match=r"missing\.toml: file not found$"):
        load_scene(tmp_path / "missing.toml")
    path = tmp_path / "scene.toml"
    path.write_text('seed = 1\n\n[simulation\ndt = 0.1\n')
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert str(info.value).startswith(f"{path}: TOML syntax error at line 3")
    assert "\n" not in str(info.value)
    path.write_text('[[objects]]\nmesh = "a.obj"\nvoxel_size = 0\n')
    with pytest.raises(SceneError, match=r"scene\.toml: objects\[0\]\.voxel_size: must be > 0"):
        load_scene(path)


def test_regions_contain() -> None:
    pts = np.array([[0.5, 0.5, 0.5], [1.0, 1.0, 1.0], [1.5, 0.5, 0.5], [0.0, -2.0, 0.0]])
    box = Box.model_validate({"min": [0, 0, 0], "max": [1, 1, 1]})
    assert box.contains(pts).tolist() == [True, True, False, False]
    sphere = Sphere.model_validate({"center": [0, 0, 0], "radius": 1.0})
    assert sphere.contains(pts).tolist() == [True, False, False, False]
    half = Halfspace.model_validate({"point": [0, 0, 0], "normal": [0, 2, 0]})
    assert half.contains(pts).tolist() == [True, True, True, False]


@given(st.one_of(st.floats(min_value=1e-6, max_value=1e3),
                 st.lists(st.floats(min_value=1e-6, max_value=1e3), min_size=3, max_size=3)))
def test_voxel_size_accepts_positive_scalars_and_triples(size: float | list[float]) -> None:
    obj = Scene.model_validate({"objects": [{"mesh": "a.obj", "voxel_size": size}]}).objects[0]
    expected = tuple(size) if isinstance(size, list) else (size,) * 3
    assert obj.voxel_size == expected


@given(st.floats(max_value=0.0) | st.just(math.nan))
def test_voxel_size_rejects_non_positive(size: float) -> None:
    message = error_of({"objects": [{"mesh": "a.obj", "voxel_size": size}]})
    assert message.startswith("scene.toml: objects[0].voxel_size: ")


@pytest.mark.parametrize("scene", sorted(
    str(p.relative_to(Path(__file__).resolve().parents[1]))
    for p in (Path(__file__).resolve().parents[1] / "examples").glob("*/scene.toml")))
def test_every_example_scene_loads(scene: str) -> None:
    """The bundled examples are valid scenes whose meshes exist (a renamed key or mesh
    would otherwise surface only when someone runs `make -C examples`)."""
    from blastvox.scene import load_scene

    spec = load_scene(Path(__file__).resolve().parents[1] / scene)
    assert spec.objects and all(Path(o.mesh).is_file() for o in spec.objects)
    assert spec.output.model is not None and spec.output.cache is not None
