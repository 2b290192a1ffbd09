"""Issue 18 part A: one validator per file contract.

Crafted VoxelModel and SimCache files, each wrong in one way, must be refused on
load with one :class:`ContractError` line naming the file and the array or meta
key (never a traceback, a segfault, or NaN exported in silence); zip bombs must be
refused or skipped without being decompressed. The files are made from a small
valid model (a conform ball, 81 voxels) and a 0.2 s simulation of it, once per
module.
"""

from __future__ import annotations

import io
import json
import math
import os
import subprocess
import sys
import time
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from bad_input import Outcome, assert_clean_failure, run_blastvox, unchanged
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from blastvox.cache import MODEL_PREFIX, SimCache
from blastvox.errors import ContractError
from blastvox.io import npz
from blastvox.materials import MaterialLibrary, material_table
from blastvox.model import MATERIAL_ARRAYS, VoxelModel

Arrays = dict[str, np.ndarray]


# ----------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(model.npz, sim.npz): a conform wooden ball and 0.2 s of a 5 kg charge beside it
    (close enough to crush wood's face to dust: 21 MPa)."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("contract")
    trimesh.creation.icosphere(subdivisions=2, radius=0.6).export(tmp / "ball.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "ball.stl", voxel_size=(0.25,) * 3,
                                    material="wood", shape="conform")],
                     VoxelizeSettings(up_axis="Z"))
    cache = simulate(model, SimSettings(
        duration=0.2, camera=((0.0, -10.0, 1.0), (0.0, 0.0, 0.5), 35.0),
        charges=(ChargeSpec((0.0, -0.9, 0.3), 5.0),)))
    model.save(tmp / "model.npz")
    cache.save(tmp / "sim.npz")
    return tmp / "model.npz", tmp / "sim.npz"


@pytest.fixture(scope="module")
def model_members(files) -> Arrays:
    return _members(files[0])


@pytest.fixture(scope="module")
def cache_members(files) -> Arrays:
    return _members(files[1])


def _members(path: Path) -> Arrays:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _meta(arrays: Arrays) -> dict:
    return json.loads(arrays["meta"].tobytes().decode())


def _set_meta(arrays: Arrays, edit: Callable[[dict], None]) -> None:
    meta = _meta(arrays)
    edit(meta)
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)


def _write(members: Arrays, path: Path) -> Path:
    np.savez(path, **members)  # stored, not deflated: quick
    return path


def _crafted(members: Arrays, tmp_path: Path, mutate: Callable[[Arrays], None],
             name: str = "crafted.npz") -> Path:
    arrays = {k: v.copy() for k, v in members.items()}
    mutate(arrays)
    return _write(arrays, tmp_path / name)


def _refused(load: Callable[[Path], object], path: Path, *words: str) -> str:
    with pytest.raises(ContractError) as error:
        load(path)
    message = str(error.value)
    assert "\n" not in message and message.startswith(f"{path}: "), message
    for word in words:
        assert word in message, (word, message)
    return message


# ----------------------------------------------------------------------------- mutations


def _set(name: str, index, value) -> Callable[[Arrays], None]:
    def mutate(a: Arrays) -> None:
        a[name][index] = value
    return mutate


def _replace(name: str, value: Callable[[np.ndarray], np.ndarray]) -> Callable[[Arrays], None]:
    def mutate(a: Arrays) -> None:
        a[name] = value(a[name])
    return mutate


def _drop(name: str) -> Callable[[Arrays], None]:
    return lambda a: a.pop(name)


def _meta_edit(edit: Callable[[dict], None]) -> Callable[[Arrays], None]:
    return lambda a: _set_meta(a, edit)


def _meta_set(key: str, value) -> Callable[[Arrays], None]:
    return _meta_edit(lambda m: m.__setitem__(key, value))


def _asymmetric(inertia: np.ndarray) -> np.ndarray:
    inertia[0, 0, 1] += 1.0
    return inertia


def _loose_foundation(a: Arrays) -> None:
    a["voxel_foundation_yield"][np.flatnonzero(~a["voxel_foundation"])[0]] = 5.0


def _far_vertex(a: Arrays) -> None:  # 0.25 m voxels, 9e5 m away: 3.6e6 voxel sizes
    a["vertices"][0] = (9e5, 0.0, 0.0)


#: (case id, mutation, words the one-line message must hold); the model arrays
MODEL_CASES: list[tuple[str, Callable[[Arrays], None], tuple[str, ...]]] = [
    # the tester's cases: a segfault, a read past the end, 7.45 GiB asked for
    ("vertex-1e7", _set("voxel_vertices", (0, 0), 10**7),
     ("'voxel_vertices' refers to vertex 10000000 of",)),
    ("vertex-negative", _set("voxel_vertices", (3, 5), -1), ("'voxel_vertices'", "negative")),
    ("object-negative", _set("voxel_object", 0, -1), ("'voxel_object'", "negative object")),
    ("object-past-end", _set("voxel_object", 4, 1), ("'voxel_object' refers to object 1 of 1",)),
    ("material-99", _set("voxel_material", 2, 99), ("'voxel_material' refers to material 99",)),
    ("mass-zero", _set("voxel_mass", 1, 0.0), ("'voxel_mass'", "> 0", "0.0 at [1]")),
    ("mass-negative", _set("voxel_mass", 1, -2.0), ("'voxel_mass'", "-2.0")),
    ("mass-nan", _set("voxel_mass", 1, np.nan), ("'voxel_mass'", "nan")),
    # finite and > 0, but 1e308 kg overflowed the simulator (density in a divide)
    ("mass-absurd", _set("voxel_mass", 1, 1e308), ("'voxel_mass'", "1e+308 kg at [1]",
                                                   "100000 kg/m^3")),
    ("volume-zero", _set("voxel_volume", 0, 0.0), ("'voxel_volume'",)),
    # the solid's box (contacts and the ground use it): named by its voxel
    ("solid-box-inverted", _set("voxel_solid_box", (2, 0, 1), 1e3),
     ("'voxel_solid_box' holds the box", "at [2]", "lo <= hi")),
    ("solid-box-nan", _set("voxel_solid_box", (3, 1, 2), np.nan), ("'voxel_solid_box'", "at [3]")),
    ("solid-box-far", _set("voxel_solid_box", (4, 1, 0), 1e12), ("'voxel_solid_box'", "at [4]")),
    ("link-yield-short", _replace("link_yield", lambda x: x[:-1]), ("'link_yield' has shape",
                                                                   "one per link")),
    ("link-yield-nan", _set("link_yield", 0, np.nan), ("'link_yield'", "nan")),
    ("link-yield-negative", _set("link_yield", 0, -1.0), ("'link_yield'",)),
    ("conform-offsets-huge", _set("conform_offsets", -1, 2**33), ("'conform_offsets' ends at",)),
    ("conform-offsets-start", _set("conform_offsets", 0, 1), ("'conform_offsets' starts at 1",)),
    ("conform-offsets-drop", _set("conform_offsets", 5, 0), ("'conform_offsets' decreases",)),
    ("conform-offsets-length", _replace("conform_offsets", lambda x: x[:-1]),
     ("'conform_offsets' has shape",)),
    ("conform-tag-7", _set("conform_tag", 0, 7), ("'conform_tag'", "0..6")),
    ("conform-voxel-negative", _set("conform_voxels", 1, -7), ("'conform_voxels'", "negative")),
    ("conform-voxel-dup", lambda a: a["conform_voxels"].__setitem__(1, a["conform_voxels"][0]),
     ("'conform_voxels' lists voxel",)),
    ("conform-voxel-past-end", _set("conform_voxels", 0, 10**6), ("'conform_voxels' refers",)),
    ("conform-triangle-inf", _set("conform_triangles", (0, 1, 2), np.inf),
     ("'conform_triangles'", "inf")),
    ("boundary-128", _set("voxel_boundary", 0, 128), ("'voxel_boundary'", "128")),
    ("link-face-2", _set("link_face", 0, 2), ("'link_face' holds 2",)),
    ("link-voxels-past-end", _set("link_voxels", (1, 1), 5000), ("'link_voxels' refers to voxel",)),
    ("link-voxels-backwards", lambda a: a["link_voxels"].__setitem__(0, a["link_voxels"][0][::-1]),
     ("'link_voxels'", "a < voxel b")),
    ("link-area-zero", _set("link_area", 3, 0.0), ("'link_area'",)),
    ("link-direction-long", _set("link_direction", (0, 0), 3.0), ("'link_direction'", "unit")),
    ("link-midpoint-nan", _set("link_midpoint", (0, 0), np.nan), ("'link_midpoint'",)),
    ("vertices-nan", _set("vertices", (0, 2), np.nan), ("'vertices'", "nan")),
    ("vertices-1e8", _set("vertices", (0, 2), 1e8), ("'vertices'", "+-1e+07 m")),
    ("vertices-far", _far_vertex, ("'vertices' spans", "median voxel size")),
    ("centroid-inf", _set("voxel_centroid", (2, 0), -np.inf), ("'voxel_centroid'",)),
    ("inertia-asymmetric", _replace("voxel_inertia", _asymmetric), ("'voxel_inertia'",
                                                                    "symmetric")),
    ("inertia-zero", _set("voxel_inertia", (0, 1, 1), 0.0), ("'voxel_inertia'", "[0, 1, 1]")),
    ("inertia-nan", _set("voxel_inertia", (0, 2, 1), np.nan), ("'voxel_inertia'",)),
    ("foundation-yield-loose", _loose_foundation, ("'voxel_foundation_yield'", "not a foundation")),
    ("voxel-yield-nan", _set("voxel_yield", 0, np.nan), ("'voxel_yield'",)),
    ("combustibility-negative", _set("voxel_combustibility", 0, -1.0),
     ("'voxel_combustibility'",)),
    ("ijk-negative", _set("voxel_ijk", (0, 0), -1), ("'voxel_ijk'",)),
    ("dtype-int64", _replace("voxel_vertices", lambda x: x.astype(np.int64)),
     ("'voxel_vertices'", "dtype int64", "int32")),
    ("dtype-big-endian", _replace("voxel_mass", lambda x: x.astype(">f8")), ("'voxel_mass'",)),
    ("shape-inertia", _replace("voxel_inertia", lambda x: x.reshape(-1, 9)), ("'voxel_inertia'",)),
    ("shape-rows", _replace("voxel_yield", lambda x: x[:-2]), ("'voxel_yield'", "one per voxel")),
    ("missing", _drop("voxel_centroid"), ("missing array 'voxel_centroid'",)),
    ("material-missing", _drop("material_restitution"), ("missing array 'material_restitution'",)),
    ("material-density-zero", _set("material_density", 0, 0.0), ("'material_density'",)),
    ("material-restitution-2", _set("material_restitution", 0, 2.0),
     ("'material_restitution'", "<= 1")),
    ("material-color", _set("material_color", (0, 1), 1.5), ("'material_color'",)),
    ("material-var-inf", _set("material_link_yield_var", 0, np.inf),
     ("'material_link_yield_var'",)),
    ("material-rows", _replace("material_density", lambda x: np.append(x, 1.0)),
     ("'material_density'", "one per name in meta materials")),
    ("material-impulse-nan", _set("material_link_impulse", 0, np.nan),
     ("'material_link_impulse' holds a value that is not a finite number >= 0",)),
    ("meta-version-99", _meta_set("schema_version", 99), ("version 99 is newer",)),
    ("meta-version-string", _meta_set("schema_version", "1"), ("invalid schema_version '1'",)),
    ("meta-version-bool", _meta_set("schema_version", True), ("invalid schema_version True",)),
    ("meta-schema", _meta_set("schema", "blastvox.SimCache"), ("found 'blastvox.SimCache'",)),
    ("meta-up-axis", _meta_set("up_axis", "Q"), ("up_axis is 'Q'",)),
    # an X-up model simulated, then crashed every export (up axes are Y or Z)
    ("meta-up-axis-x", _meta_set("up_axis", "X"), ("up_axis is 'X'", "Y, Z")),
    ("meta-objects", _meta_set("objects", {"name": "x"}), ("meta objects",)),
    ("meta-object-name", _meta_set("objects", [{"source": "x"}]), ("meta objects",)),
    ("meta-materials", _meta_set("materials", ["wood", 3]), ("meta materials",)),
    ("meta-ground-nan", _meta_set("ground_height", math.nan), ("meta ground_height is nan",)),
    ("meta-ground-text", _meta_set("ground_height", "low"), ("meta ground_height",)),
    ("meta-not-json", lambda a: a.__setitem__("meta", np.frombuffer(b"{", np.uint8)),
     ("corrupt metadata",)),
    ("meta-deep-json", lambda a: a.__setitem__("meta", np.frombuffer(b"[" * 100000, np.uint8)),
     ("corrupt metadata",)),
    ("meta-float", lambda a: a.__setitem__("meta", np.zeros(4)), ("corrupt metadata",)),
    ("pickle", lambda a: a.__setitem__("voxel_mass", np.array([{}], dtype=object)),
     ("'voxel_mass' holds pickled objects",)),
]


def _cache_model_version(a: Arrays) -> None:
    _set_meta(a, lambda m: m["model"].__setitem__("schema_version", 99))


def _owns_nothing(a: Arrays) -> None:
    a["voxel_piece"][:] = 0


def _camera_nowhere(m: dict) -> None:
    m["camera"]["look_at"] = m["camera"]["position"]


#: the SimCache arrays and meta, and its embedded model
CACHE_CASES: list[tuple[str, Callable[[Arrays], None], tuple[str, ...]]] = [
    ("model-version-99", _cache_model_version,
     ("embedded model: blastvox.VoxelModel version 99 is newer",)),
    ("model-schema", _meta_edit(lambda m: m["model"].__setitem__("schema", "x")),
     ("meta model.schema is 'x'",)),
    ("model-meta-missing", _meta_edit(lambda m: m.pop("model")), ("meta model is missing",)),
    ("model-up-axis", _meta_edit(lambda m: m["model"].__setitem__("up_axis", 1)),
     ("meta model.up_axis is 1",)),
    ("model-vertex-1e7", _set("model.voxel_vertices", (0, 0), 10**7),
     ("'model.voxel_vertices' refers to vertex 10000000",)),
    ("model-object-negative", _set("model.voxel_object", 0, -1), ("'model.voxel_object'",)),
    ("model-material-99", _set("model.voxel_material", 0, 99), ("'model.voxel_material'",)),
    ("model-missing", _drop("model.link_area"), ("missing array 'model.link_area'",)),
    ("piece-7-of-P", _set("voxel_piece", 5, 1000), ("'voxel_piece' refers to piece 1000 of",)),
    ("piece-negative", _set("voxel_piece", 5, -1), ("'voxel_piece'", "negative piece")),
    ("piece-owns-nothing", _owns_nothing, ("'voxel_piece' gives piece 1 no voxel",)),
    ("frame-time-nan", _set("frame_time", 2, np.nan), ("'frame_time'", "nan")),
    ("frame-time-decreasing", _set("frame_time", 2, 0.0), ("'frame_time' decreases at [2]",)),
    ("frame-time-start", _set("frame_time", 0, -1.0), ("'frame_time' starts at -1.0",)),
    ("piece-mass-zero", _set("piece_mass", 0, 0.0), ("'piece_mass'",)),
    ("piece-position-nan", _set("piece_position", (1, 0, 2), np.nan), ("'piece_position'",
                                                                       "[1, 0, 2]")),
    ("piece-position-inf", _set("piece_position", (1, 0, 2), np.inf), ("'piece_position'",)),
    ("piece-orientation-zero", _set("piece_orientation", (1, 3), 0.0),
     ("'piece_orientation'", "unit quaternion", "[1, 3]")),
    ("piece-pivot-far", _set("piece_pivot", (0, 0), 1e9), ("'piece_pivot'",)),
    ("end-frame-past", _replace("piece_end_frame", lambda x: x + 100), ("'piece_end_frame'",)),
    ("end-frame-negative", _set("piece_end_frame", 0, -1), ("'piece_end_frame'",)),
    ("destroyed-frame-past", _set("voxel_destroyed_frame", 0, 99),
     ("'voxel_destroyed_frame' refers to frame 99 of 5",)),
    ("destroyed-frame-minus-2", _set("voxel_destroyed_frame", 0, -2),
     ("'voxel_destroyed_frame'", "negative frame index other than -1")),
    ("ignite-frame-past", _set("voxel_ignite_frame", 0, 2**30), ("'voxel_ignite_frame'",)),
    ("damage-frame-past", _set("damage_frame", 0, 5), ("'damage_frame' refers to frame 5 of 5",)),
    ("damage-voxel-past", _set("damage_voxel", 0, 117), ("'damage_voxel' refers to voxel 117",)),
    ("damage-short", _replace("damage_value", lambda x: x[:-1]),
     ("'damage_value' has shape", "one per damage event")),
    ("break-link-past", _set("link_break_link", 0, 10**5), ("'link_break_link' refers to link",)),
    ("break-time-nan", _set("link_break_time", 0, np.nan), ("'link_break_time'",)),
    ("break-time-negative", _set("link_break_time", 0, -1.0), ("'link_break_time'",)),
    ("dust-voxel-negative", _set("dust_voxel", 0, -3), ("'dust_voxel'",)),
    ("dust-mass-zero", _set("dust_mass", 0, 0.0), ("'dust_mass'",)),
    ("dust-position-inf", _set("dust_position", (0, 0), np.inf), ("'dust_position'",)),
    ("dust-velocity-nan", _set("dust_velocity", (0, 1), np.nan), ("'dust_velocity'",)),
    ("dust-short", _replace("dust_time", lambda x: x[:3]), ("'dust_time' has shape",)),
    ("charge-tnt-zero", _set("charge_tnt_kg", 0, 0.0), ("'charge_tnt_kg'",)),
    ("charge-time-nan", _set("charge_time", 0, np.nan), ("'charge_time'",)),
    ("charge-position-far", _set("charge_position", (0, 0), 1e8), ("'charge_position'",)),
    ("shock-radius-negative", _set("shock_radius", (1, 0), -1.0), ("'shock_radius'",)),
    ("shock-opacity-2", _set("shock_opacity", (1, 0), 2.0), ("'shock_opacity'", "<= 1")),
    ("shock-shape", _replace("shock_radius", lambda x: x[:, 0]), ("'shock_radius' has shape",)),
    ("camera-offset-nan", _set("camera_offset", (0, 0), np.nan), ("'camera_offset'",)),
    ("particle-system-9", _set("particle_system", 0, 9),
     ("'particle_system' refers to particle system 9 of 4",)),
    ("particle-size-zero", _set("particle_size", 0, 0.0), ("'particle_size'",)),
    ("particle-birth-nan", _set("particle_birth", 0, np.nan), ("'particle_birth'",)),
    ("particle-velocity-inf", _set("particle_velocity", (0, 0), np.inf), ("'particle_velocity'",)),
    ("dtype-float64-positions", _replace("piece_position", lambda x: x.astype(np.float64)),
     ("'piece_position'", "float32")),
    ("position-origin-far", _set("position_origin", 0, 1e8), ("'position_origin'",)),
    ("position-origin-nan", _set("position_origin", 1, np.nan), ("'position_origin'",)),
    ("missing", _drop("dust_time"), ("missing array 'dust_time'",)),
    ("meta-version-99", _meta_set("schema_version", 99), ("blastvox.SimCache version 99",)),
    ("meta-fps-zero", _meta_set("fps", 0), ("meta fps is 0",)),
    ("meta-fps-text", _meta_set("fps", "24"), ("meta fps is '24'",)),
    ("meta-dt-nan", _meta_set("dt", math.nan), ("meta dt is nan",)),
    ("meta-gravity", _meta_set("gravity_vector", [0.0, -9.81]), ("meta gravity_vector",)),
    ("meta-up-axis", _meta_set("up_axis", "X"), ("meta up_axis is 'X'",)),
    ("meta-settings", _meta_set("settings", "fast"), ("meta settings",)),
    ("meta-camera-nowhere", _meta_edit(_camera_nowhere), ("meta camera.look_at",)),
    ("meta-camera-position", _meta_edit(lambda m: m["camera"].__setitem__("position", None)),
     ("meta camera.position is None",)),
    ("meta-camera-focal", _meta_edit(lambda m: m["camera"].__setitem__("focal_length_mm", -35)),
     ("meta camera.focal_length_mm",)),
    ("meta-particles-missing", _meta_edit(lambda m: m.pop("particle_systems")),
     ("meta particle_systems is missing",)),
    ("meta-particles-drag", _meta_edit(
        lambda m: m["particle_systems"][1].__setitem__("drag_per_s", math.inf)),
     ("meta particle_systems[1].drag_per_s is inf",)),
]


# ----------------------------------------------------------------------------- the cases


def test_the_untouched_files_load(files):
    model, sim = VoxelModel.load(files[0]), SimCache.load(files[1])
    assert model.voxel_count == sim.model.voxel_count > 50 and len(model.conform_voxels)
    for key in ("dust_voxel", "link_break_link", "damage_frame", "particle_system"):
        assert len(sim.arrays[key]), key  # the crafted cases below need events of each kind
    assert sim.meta["camera"] is not None


@pytest.mark.parametrize(("mutate", "words"), [c[1:] for c in MODEL_CASES],
                         ids=[c[0] for c in MODEL_CASES])
def test_a_crafted_model_is_refused(model_members, tmp_path, mutate, words):
    _refused(VoxelModel.load, _crafted(model_members, tmp_path, mutate), *words)


@pytest.mark.parametrize(("mutate", "words"), [c[1:] for c in CACHE_CASES],
                         ids=[c[0] for c in CACHE_CASES])
def test_a_crafted_cache_is_refused(cache_members, tmp_path, mutate, words):
    _refused(SimCache.load, _crafted(cache_members, tmp_path, mutate), *words)


def test_documented_infinities_load(model_members, tmp_path):
    """+inf yields and combustibility mean unbreakable and never burns: they load."""
    def unbreakable(a: Arrays) -> None:
        for key in ("voxel_yield", "link_yield", "voxel_combustibility",
                    "material_link_yield_mean", "material_combustibility"):
            a[key][:] = np.inf

    model = VoxelModel.load(_crafted(model_members, tmp_path, unbreakable))
    assert np.isinf(model.link_yield).all()


def test_optional_material_arrays_may_be_absent(model_members, tmp_path):
    def older(a: Arrays) -> None:
        for key in ("material_link_impulse", "material_voxel_impulse", "material_pi_shape",
                    "material_description"):
            a.pop(key)

    assert VoxelModel.load(_crafted(model_members, tmp_path, older)).voxel_count


def test_the_material_table_is_the_materials_module_s():
    assert set(MATERIAL_ARRAYS) == set(material_table(MaterialLibrary.builtin(), ["brick"]))


def test_a_cache_names_the_embedded_model(files, cache_members, tmp_path):
    """A bad embedded model is refused with the ``model.`` prefix; a model file given
    as a cache (and a cache as a model) is refused too."""
    path = _crafted(cache_members, tmp_path, _set(MODEL_PREFIX + "voxel_object", 3, 2**31 - 1))
    _refused(SimCache.load, path, "'model.voxel_object' refers to object 2147483647 of 1")
    _refused(SimCache.load, files[0], "expected a blastvox.SimCache file")
    _refused(VoxelModel.load, files[1], "expected a blastvox.VoxelModel file")


# ----------------------------------------------------------------------------- the archive


def test_unknown_members_are_ignored(model_members, tmp_path):
    """An unknown member is not read (even a broken one), and not returned."""
    arrays = dict(model_members, extra=np.arange(3), **{"model.vertices": np.zeros(2)})
    path = _write(arrays, tmp_path / "extra.npz")
    with zipfile.ZipFile(path, "a") as zf:
        zf.writestr("broken.npy", b"not an npy file")
        zf.writestr("readme.txt", b"hello")
    model = VoxelModel.load(path)
    assert "extra" not in model.arrays and "model.vertices" not in model.arrays


def test_fortran_order_members_load(model_members, tmp_path):
    arrays = dict(model_members, voxel_inertia=np.asfortranarray(model_members["voxel_inertia"]))
    model = VoxelModel.load(_write(arrays, tmp_path / "fortran.npz"))
    np.testing.assert_array_equal(model.voxel_inertia, model_members["voxel_inertia"])
    assert model.voxel_inertia.flags.writeable


def _npy_header(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        out, {"descr": descr, "fortran_order": False, "shape": shape})
    return out.getvalue()


def _replace_member(source: Path, dest: Path, name: str, payload: bytes) -> Path:
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(dest, "w") as zout:
        for info in zin.infolist():
            if info.filename != f"{name}.npy":
                zout.writestr(info, zin.read(info))
        zout.writestr(f"{name}.npy", payload)
    return dest


def test_a_header_declaring_a_huge_shape_is_refused_before_reading(files, tmp_path):
    path = _replace_member(files[0], tmp_path / "huge.npz", "vertices",
                           _npy_header((10**12, 3)) + bytes(72))
    started = time.perf_counter()
    _refused(VoxelModel.load, path, "member 'vertices' declares shape (1000000000000, 3)")
    assert time.perf_counter() - started < 1.0


@pytest.mark.parametrize(("payload", "words"), [
    (b"\x93NUMPY\x01\x00" + b"\xff" * 30, ("member 'voxel_mass' has no valid .npy header",)),
    (_npy_header((2,), "|O") + bytes(16), ("'voxel_mass' holds pickled objects",)),
    (_npy_header((2,), "<c16") + bytes(32), ("'voxel_mass' has dtype complex128",)),
    (_npy_header((2,)) + bytes(8), ("declares shape (2,)", "holds 8 bytes")),
    (_npy_header((10**12,), "<U0"), ("'voxel_mass' has dtype <U0",)),  # 0 bytes, 3.6 TiB
])
def test_a_malformed_member_is_refused(files, tmp_path, payload, words):
    path = _replace_member(files[0], tmp_path / "bad.npz", "voxel_mass", payload)
    _refused(VoxelModel.load, path, *words)


def test_a_member_twice_is_refused(files, tmp_path):
    path = tmp_path / "twice.npz"
    path.write_bytes(files[0].read_bytes())
    with pytest.warns(UserWarning, match="Duplicate name"), zipfile.ZipFile(path, "a") as zf:
        zf.writestr("voxel_mass.npy", _npy_header((1,)) + bytes(8))
    _refused(VoxelModel.load, path, "member 'voxel_mass' appears twice")


def test_corrupt_and_truncated_archives_are_refused(files, tmp_path):
    data = bytearray(files[0].read_bytes())
    with zipfile.ZipFile(files[0]) as zf:
        info = zf.getinfo("vertices.npy")
    start = info.header_offset + 30 + len(info.filename) + len(info.extra)
    data[start + info.compress_size // 2] ^= 0xFF  # inside the deflate stream
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(bytes(data))
    _refused(VoxelModel.load, corrupt, "not a readable .npz VoxelModel")
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(files[0].read_bytes()[:5000])
    _refused(VoxelModel.load, truncated)


def test_other_compression_methods_are_refused(model_members, tmp_path):
    path = tmp_path / "bz2.npz"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_BZIP2) as zf:
        for key, value in model_members.items():
            buffer = io.BytesIO()
            np.lib.format.write_array(buffer, value, allow_pickle=False)
            zf.writestr(f"{key}.npy", buffer.getvalue())
    _refused(VoxelModel.load, path, "compression method 12")


# zip bombs: real deflate streams of zeros, built block by block (compressing gigabytes
# would take minutes): a full flush makes a block of 1 MiB of zeros self-contained, so
# it can be repeated; the CRC of the zeros is combined in GF(2) as zlib does.

def _gf2_times(matrix: list[int], vector: int) -> int:
    total, i = 0, 0
    while vector:
        if vector & 1:
            total ^= matrix[i]
        vector >>= 1
        i += 1
    return total


def _crc32_combine(crc1: int, crc2: int, len2: int) -> int:
    """zlib's crc32_combine: the CRC of A + B from CRC(A), CRC(B) and len(B)."""
    odd = [0xEDB88320] + [1 << n for n in range(31)]
    even = [_gf2_times(odd, odd[n]) for n in range(32)]
    odd = [_gf2_times(even, even[n]) for n in range(32)]
    while len2:
        even = [_gf2_times(odd, odd[n]) for n in range(32)]
        if len2 & 1:
            crc1 = _gf2_times(even, crc1)
        len2 >>= 1
        if not len2:
            break
        odd = [_gf2_times(even, even[n]) for n in range(32)]
        if len2 & 1:
            crc1 = _gf2_times(odd, crc1)
        len2 >>= 1
    return crc1 ^ crc2


def _add_zero_bomb(zf: zipfile.ZipFile, name: str, header: bytes, zeros: int) -> None:
    """Add member ``name``: ``header`` then ``zeros`` zero bytes (a multiple of 1 MiB),
    deflated, in a few kB per GiB."""
    mib = 2**20
    assert zeros % mib == 0
    head = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = zlib.compressobj(9, zlib.DEFLATED, -15)
    block_bytes = block.compress(bytes(mib)) + block.flush(zlib.Z_FULL_FLUSH)
    stream = (head.compress(header) + head.flush(zlib.Z_FULL_FLUSH)
              + block_bytes * (zeros // mib) + zlib.compressobj(9, zlib.DEFLATED, -15).flush())
    crc_block, crc_zeros, n = zlib.crc32(bytes(mib)), 0, 0
    for bit in bin(zeros // mib)[2:]:  # CRC of k blocks by doubling
        crc_zeros, n = _crc32_combine(crc_zeros, crc_zeros, n * mib), 2 * n
        if bit == "1":
            crc_zeros, n = _crc32_combine(crc_zeros, crc_block, mib), n + 1
    info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
    zf.writestr(info, stream)  # stored as-is; the directory then says what it is
    info.compress_type = zipfile.ZIP_DEFLATED
    info.file_size = len(header) + zeros
    info.CRC = _crc32_combine(zlib.crc32(header), crc_zeros, zeros)


def test_the_bomb_builder_makes_real_deflate_members(tmp_path):
    path = tmp_path / "small.zip"
    with zipfile.ZipFile(path, "w") as zf:
        _add_zero_bomb(zf, "z", _npy_header((3 * 2**20,), "|u1"), 3 * 2**20)
    with np.load(path) as z:
        assert z["z"].shape == (3 * 2**20,) and not z["z"].any()


def test_an_unknown_bomb_is_never_decompressed(files, tmp_path, monkeypatch):
    """The tester's 3 MB file that became 3 GB: a 3 GiB member of zeros no loader
    knows. It is skipped without a byte of it being decompressed."""
    path = tmp_path / "bomb.npz"
    path.write_bytes(files[0].read_bytes())
    with zipfile.ZipFile(path, "a") as zf:
        _add_zero_bomb(zf, "junk", _npy_header((3 * 2**30,), "|u1"), 3 * 2**30)
    assert path.stat().st_size < 8 * 2**20
    opened: list[str] = []
    real_open = zipfile.ZipFile.open
    monkeypatch.setattr(zipfile.ZipFile, "open", lambda self, name, *args, **kwargs: (
        opened.append(getattr(name, "filename", name)) or real_open(self, name, *args, **kwargs)))
    started = time.perf_counter()
    model = VoxelModel.load(path)
    seconds = time.perf_counter() - started
    assert "junk" not in model.arrays and "junk.npy" not in opened
    assert seconds < 2.0, seconds


def test_a_known_bomb_is_refused_before_decompressing(files, tmp_path, monkeypatch):
    """A known member declaring 3 GiB of zeros in a 3 MB file: refused from the zip
    directory (ratio ~1000:1), and by the byte cap when the ratio check is lifted."""
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(files[0]) as zin, zipfile.ZipFile(path, "w") as zout:
        for info in zin.infolist():
            if info.filename != "voxel_combustibility.npy":
                zout.writestr(info, zin.read(info))
        _add_zero_bomb(zout, "voxel_combustibility", _npy_header((3 * 2**27,)), 3 * 2**30)
    started = time.perf_counter()
    _refused(VoxelModel.load, path, "GiB", "decompression bomb", npz.MAX_BYTES_ENV)
    monkeypatch.setenv(npz.MAX_BYTES_ENV, "2G")
    _refused(VoxelModel.load, path, "more than the 2.0 GiB allowed", npz.MAX_BYTES_ENV)
    assert time.perf_counter() - started < 2.0


def test_the_byte_cap_is_set_by_the_environment(files, monkeypatch):
    monkeypatch.setenv(npz.MAX_BYTES_ENV, "1K")
    _refused(VoxelModel.load, files[0], "more than the 1.0 KiB allowed", npz.MAX_BYTES_ENV)
    monkeypatch.setenv(npz.MAX_BYTES_ENV, str(2**30))
    assert VoxelModel.load(files[0]).voxel_count
    monkeypatch.setenv(npz.MAX_BYTES_ENV, "lots")
    with pytest.raises(ContractError, match=f"{npz.MAX_BYTES_ENV}='lots'"):
        VoxelModel.load(files[0])
    monkeypatch.delenv(npz.MAX_BYTES_ENV)
    assert npz.max_npz_bytes() == (npz.MAX_NPZ_BYTES, False)


# ----------------------------------------------------------------------------- fuzzing

_NASTY = st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0.0, 1e7, 1e30, -1e30,
                          2**31 - 1, -(2**31), 255, 7, -2, 1.5])


def _corrupt(members: Arrays, data: st.DataObject, prefix: str = "") -> tuple[Arrays, str]:
    names = sorted(k for k in members if k != "meta" and members[k].size
                   and members[k].dtype.kind in "biuf" and k.startswith(prefix))
    name = data.draw(st.sampled_from(names), label="array")
    arr = members[name].copy()
    flat = data.draw(st.integers(0, arr.size - 1), label="element")
    value = data.draw(_NASTY, label="value")
    with np.errstate(invalid="ignore", over="ignore"):
        if arr.dtype.kind == "f":
            arr.reshape(-1)[flat] = value
        elif arr.dtype.kind == "b":
            arr.reshape(-1)[flat] = not arr.reshape(-1)[flat]
        else:
            info = np.iinfo(arr.dtype)
            number = value if math.isfinite(value) else info.max
            arr.reshape(-1)[flat] = int(min(max(int(number), info.min), info.max))
    return dict(members, **{name: arr}), name


@settings(max_examples=50, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_one_corrupt_element_loads_or_is_refused(model_members, tmp_path, data):
    """Any one element of any model array set to a nasty value: a clean load (and the
    simulator's static model builds) or one ContractError line naming the array."""
    from blastvox.simulate.model import build_model

    arrays, name = _corrupt(model_members, data)
    path = _write(arrays, tmp_path / "fuzz.npz")
    try:
        model = VoxelModel.load(path)
    except ContractError as error:
        assert "\n" not in str(error) and f"'{name}'" in str(error), str(error)
        return
    build_model(model)


@settings(max_examples=30, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_one_corrupt_element_of_a_cache(cache_members, tmp_path, data):
    arrays, name = _corrupt(cache_members, data)
    path = _write(arrays, tmp_path / "fuzz.npz")
    try:
        cache = SimCache.load(path)
    except ContractError as error:
        assert "\n" not in str(error) and f"'{name}'" in str(error), str(error)
        return
    cache.summary()


# ----------------------------------------------------------------------------- the CLI


def _run_all(commands: list[list[str]], cwd: Path) -> list[Outcome]:
    """Run ``python -m blastvox`` commands in parallel (interpreter start-ups dominate)."""
    started = time.perf_counter()
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    procs = [subprocess.Popen([sys.executable, "-m", "blastvox", *c], cwd=cwd, env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for c in commands]
    outcomes = []
    for proc in procs:
        out, err = proc.communicate(timeout=300)
        outcomes.append(Outcome(proc.returncode, out, err, time.perf_counter() - started))
    return outcomes


def test_the_cli_refuses_crafted_files_in_one_line(model_members, cache_members, tmp_path):
    """simulate/info/export on crafted files: exit 1, one line naming the file and the
    array, no traceback, no output. The first two segfaulted (exit 139)."""
    bad = {
        "vertex.npz": (model_members, _set("voxel_vertices", (0, 0), 10**7), "'voxel_vertices'"),
        "object.npz": (model_members, _set("voxel_object", 0, -1), "'voxel_object'"),
        "material.npz": (model_members, _set("voxel_material", 0, 99), "'voxel_material'"),
        "sim99.npz": (cache_members, _cache_model_version, "version 99"),
        "offsets.npz": (model_members, _set("conform_offsets", -1, 2**33), "'conform_offsets'"),
        "simnan.npz": (cache_members, _set("piece_position", (1, 0, 0), np.nan),
                       "'piece_position'"),
    }
    for name, (members, mutate, _) in bad.items():
        _crafted(members, tmp_path, mutate, name)
    simulate = [["simulate", name, "--charge", "0,0,-5:1", "-o", "out.npz"] for name in bad]
    commands = [*simulate[:3], ["export", "sim99.npz", "-o", "shot.glb"]]
    with unchanged(tmp_path, [tmp_path / n for n in bad]):
        outcomes = _run_all(commands, tmp_path)  # real processes: a segfault shows as -11
        # the rest in-process, through the same entry point (no interpreter start-up)
        outcomes += [run_blastvox(*simulate[4], cwd=tmp_path),
                     run_blastvox("info", "simnan.npz", cwd=tmp_path)]
    for (name, (_, _, word)), outcome in zip(bad.items(), outcomes, strict=True):
        assert_clean_failure(outcome, [name, word])
    assert not (tmp_path / "out.npz").exists() and not (tmp_path / "shot.glb").exists()


def test_inputs_that_are_not_blastvox_files_are_named_for_what_they_are(tmp_path):
    """info, diff and export say what a wrong input is: a directory or a device is not
    "no such file"; info names both kinds it reads; no doubled words."""
    (tmp_path / "adir.npz").mkdir()
    np.savez(tmp_path / "rand.npz", a=np.zeros(3))
    np.savez(tmp_path / "schemaless.npz",
             meta=np.frombuffer(json.dumps({"kind": "SimCache"}).encode(), dtype=np.uint8))
    cases = {
        ("info", "adir.npz"): ["adir.npz", "is a directory"],
        ("info", "/dev/null"): ["/dev/null", "is a character device"],
        ("info", "rand.npz"): ["rand.npz", "not a blastvox VoxelModel or SimCache"],
        ("info", "schemaless.npz"): ["schemaless.npz", "VoxelModel or blastvox.SimCache",
                                     "meta naming no schema"],
        ("diff", "adir.npz", "rand.npz"): ["adir.npz", "is a directory"],
        ("diff", "rand.npz", "rand.npz"): ["rand.npz", "not a blastvox file ("],
        ("export", "adir.npz", "-o", "x.usdc"): ["adir.npz", "is a directory, not a SimCache"],
    }
    for args, needles in cases.items():
        outcome = run_blastvox(*args, cwd=tmp_path)
        line = assert_clean_failure(outcome, needles[:1], code=outcome.code)
        assert outcome.code in (1, 2), outcome.code
        for needle in needles[1:]:
            assert needle in line, (args, line)
        assert "blastvox blastvox" not in line
