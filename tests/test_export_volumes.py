"""Particle volumes: blastvox's own OpenVDB writer read back by the real OpenVDB (bpy's
``openvdb`` module, OpenVDB 12, in ``.venv-blender``), the splat's mass conservation,
and the USD export's Volume prims, files, determinism and atomicity.

The synthetic cache is test_export_usd's (three pieces, 4 dust particles born at
frame 6 of 10), with fireball particles added: 30 particles born at frames 1 to 3
that live 1.2 s (to the end of the shot).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdShade, UsdVol  # noqa: E402
from test_export_usd import F, synthetic  # noqa: E402, F401  (the fixture)

from blastvox.cache import SimCache  # noqa: E402
from blastvox.errors import BlastvoxError  # noqa: E402
from blastvox.export.api import ExportOptions, export  # noqa: E402
from blastvox.export.usd_validate import validate_usd  # noqa: E402
from blastvox.export.vdb import FloatGrid, vdb_bytes, write_vdb  # noqa: E402
from blastvox.export.volumes import (  # noqa: E402
    KERNEL_TAU,
    VOLUME_LOOKS,
    cross_section,
    frame_grids,
    splat,
    system_voxel,
)

ROOT = Path(__file__).resolve().parents[1]
BLENDER_PYTHON = ROOT / ".venv-blender" / "bin" / "python"
VDB_CHECK = ROOT / "tools" / "blender" / "vdb_check.py"
needs_blender = pytest.mark.skipif(
    not BLENDER_PYTHON.exists(),
    reason=f"no Blender venv ({BLENDER_PYTHON.relative_to(ROOT)}): run `make blender-venv`")


def _openvdb_read(*paths: Path) -> dict:
    """What OpenVDB itself reads from ``paths`` (tools/blender/vdb_check.py)."""
    result = subprocess.run([str(BLENDER_PYTHON), str(VDB_CHECK), *map(str, paths)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def fiery(synthetic) -> SimCache:  # noqa: F811 (the imported fixture)
    """The synthetic cache with 30 fireball particles (system 3) born at frames 1..3."""
    rng = np.random.default_rng(3)
    arrays = dict(synthetic.arrays)
    n = 30
    births = np.repeat([0.1, 0.2, 0.3], 10)
    add = {"particle_system": np.full(n, 3, np.uint8), "particle_birth": births,
           "particle_position": rng.normal(size=(n, 3)) * 0.5 + [0.0, 0.0, 1.0],
           "particle_velocity": rng.normal(size=(n, 3)) * 2.0,
           "particle_size": np.full(n, 0.8, np.float32)}
    for key, value in add.items():
        arrays[key] = np.concatenate([arrays[key], value.astype(arrays[key].dtype)])
    return SimCache(arrays=arrays, model=synthetic.model, meta=synthetic.meta)


# ----------------------------------------------------------------------------- the writer

def _random_grid(seed: int, count: int, spread: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    ijk = np.unique(rng.integers(-spread, spread, size=(count, 3)), axis=0).astype(np.int32)
    dense = np.stack(np.meshgrid(*[np.arange(-4, 12)] * 3, indexing="ij"), -1).reshape(-1, 3)
    ijk = np.unique(np.concatenate([ijk, dense + 5000]), axis=0).astype(np.int32)  # full leaves
    values = rng.random(len(ijk)).astype(np.float32) + np.float32(1e-3)
    return ijk, values


@needs_blender
@pytest.mark.parametrize("zipped", [False, True])
def test_openvdb_reads_our_grids_exactly(tmp_path, zipped):
    """Voxels in many leaves and in every octant (negative indices, several root
    children), a dense block of whole leaves, two grids in one file, a zero value
    dropped: OpenVDB reads back the names, classes, voxel size, transform, active
    count, bounding box and every value bit for bit."""
    ijk, values = _random_grid(1, 3000, 5000)
    values[7] = 0.0  # not active
    temperature = values * np.float32(1500.0)
    path = tmp_path / "grids.vdb"
    write_vdb(path, [FloatGrid("density", ijk, values, 0.25, (1.0, -2.0, 0.5)),
                     FloatGrid("temperature", ijk[:500], temperature[:500], 0.25,
                               (1.0, -2.0, 0.5), grid_class="unknown")], zipped=zipped)
    got = _openvdb_read(path)[str(path)]
    assert [g["name"] for g in got] == ["density", "temperature"]
    keep = values > 0
    for grid, (want_ijk, want) in zip(got, [(ijk[keep], values[keep]),
                                            (ijk[:500][keep[:500]],
                                             temperature[:500][keep[:500]])], strict=True):
        assert grid["type"] == "float"
        assert grid["voxel_size"] == [0.25] * 3
        assert grid["origin"] == [1.0, -2.0, 0.5]
        assert grid["active"] == len(want) == grid["metadata"]["file_voxel_count"]
        order = np.lexsort(want_ijk.T[::-1])
        assert np.array_equal(np.array(grid["ijk"]), want_ijk[order])
        assert np.array_equal(np.array(grid["values"], dtype=np.float32), want[order])
        assert grid["bbox"] == [want_ijk.min(axis=0).tolist(), want_ijk.max(axis=0).tolist()]
    assert got[0]["class"] == "fog volume" and got[1]["class"] == "unknown"
    assert got[0]["metadata"]["file_compression"] == (
        "zip + active values" if zipped else "active values")


@needs_blender
def test_openvdb_reads_an_empty_grid(tmp_path):
    path = tmp_path / "empty.vdb"
    write_vdb(path, [FloatGrid("density", np.zeros((0, 3), np.int32), np.zeros(0), 0.1)])
    (grid,) = _openvdb_read(path)[str(path)]
    assert grid["name"] == "density" and grid["active"] == 0


def test_same_grids_same_bytes_and_bad_grids_refused():
    ijk, values = _random_grid(2, 500, 300)
    a = vdb_bytes([FloatGrid("density", ijk, values, 0.1)])
    shuffled = np.random.default_rng(0).permutation(len(ijk))
    assert vdb_bytes([FloatGrid("density", ijk[shuffled], values[shuffled], 0.1)]) == a
    assert vdb_bytes([FloatGrid("density", ijk, values * 2, 0.1)]) != a
    with pytest.raises(ValueError, match="listed twice"):
        vdb_bytes([FloatGrid("density", np.concatenate([ijk, ijk[:1]]),
                             np.concatenate([values, values[:1]]), 0.1)])
    with pytest.raises(ValueError, match="distinct"):
        vdb_bytes([FloatGrid("a", ijk, values, 0.1), FloatGrid("a", ijk, values, 0.1)])
    with pytest.raises(ValueError, match="voxel size"):
        vdb_bytes([FloatGrid("a", ijk, values, 0.0)])


def test_tree_order_is_the_twelve_key_depth_first_order():
    """The writer's voxel order (two packed keys) is the depth-first order of the tree's
    twelve keys (root origin x, y, z, then each node's offset), out to the ends of int32."""
    from blastvox.export.vdb import _grid_tree

    ijk, values = _random_grid(3, 3000, 4000)
    ends = np.array([[-2**31, 0, 2**31 - 1], [2**31 - 1, -2**31, 0], [-1, -1, -1],
                     [-4096, 4095, 4096]], dtype=np.int64)
    ijk = np.concatenate([ijk, ends.astype(np.int32)])
    values = np.concatenate([values, np.ones(len(ends), dtype=np.float32)])
    _, _, got, _ = _grid_tree(FloatGrid("density", ijk, values, 0.1), False)
    a = ijk.astype(np.int64)[values > 0]
    keys = np.concatenate([a >> 12, (a >> 7) & 31, (a >> 3) & 15, a & 7], axis=1)
    assert np.array_equal(got, a[np.lexsort(keys.T[::-1])])


# ----------------------------------------------------------------------------- the splat

def test_splat_conserves_mass_at_any_cell_size():
    """The grid's integral (sum of density x cell volume) is the particles' summed
    cross-section at every cell size, from cells far smaller than a particle to cells
    larger than one (a particle then lands whole in its nearest cell), and the cloud's
    centre of mass stays where the particles are (to a fraction of a cell)."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(400, 3)) * [2.0, 1.0, 0.5] + [3.0, -1.0, 2.0]
    size = rng.uniform(0.1, 0.6, 400)
    amount = cross_section(size, 0.5)
    for h in (0.03, 0.1, 0.25, 1.0):
        ijk, density, _ = splat(x, size, amount, h)
        assert (density > 0).all()
        mass = density.astype(np.float64) * h**3
        assert mass.sum() == pytest.approx(amount.sum(), rel=1e-5), h
        centre = (ijk * h * mass[:, None]).sum(axis=0) / mass.sum()
        assert np.allclose(centre, (x * amount[:, None]).sum(axis=0) / amount.sum(),
                           atol=0.25 * h), h


def test_splat_far_from_the_origin_is_the_same_cloud_shifted():
    """A cloud 200 km from the origin (a scene placed in map coordinates) splats into
    the cells of the same cloud near the origin, moved by a whole number of cells: not
    an error because the packed cell keys reach only 2^20 cells (105 km at 0.1 m) each
    way; the indices stay exact int32 cells of the far position."""
    rng = np.random.default_rng(7)
    h = 0.1
    near = rng.normal(size=(200, 3)) * 0.5
    size = rng.uniform(0.1, 0.4, 200)
    amount = cross_section(size, 2.0)
    shift = np.array([2_000_000, 500, -1_500_000])
    ijk0, d0, _ = splat(near, size, amount, h)
    ijk1, d1, _ = splat(near + shift * h, size, amount, h)
    assert np.array_equal(ijk1, ijk0 + shift)
    assert np.allclose(d1, d0, rtol=1e-4)
    with pytest.raises(ValueError, match="spread over"):
        splat(np.array([[-1.2e5, 0, 0], [1.2e5, 0, 0]]), size[:2], amount[:2], h)


def test_an_isolated_particle_has_its_optical_depth():
    """A ray through a lone particle's centre sees the system's tau (the kernel's
    constant), within the sampling error of the cells."""
    size = np.array([0.4])
    for h in (0.01, 0.02):
        ijk, density, _ = splat(np.zeros((1, 3)), size, cross_section(size, 0.7), h)
        column = density[(ijk[:, 0] == 0) & (ijk[:, 1] == 0)].sum() * h
        assert column == pytest.approx(0.7, rel=0.03)
    assert KERNEL_TAU == pytest.approx(1.4324, rel=1e-4)


def test_fire_has_a_temperature_grid_that_cools_with_age():
    x = np.zeros((2, 3))
    young = frame_grids("fireball", x, np.array([1.0, 1.0]), np.array([0.0, 0.0]), 0.2)
    old = frame_grids("fireball", x, np.array([1.0, 1.0]), np.array([1.0, 1.0]), 0.2)
    assert [g.name for g in young] == ["density", "temperature"]
    assert np.allclose(young[1].values, 2200.0) and np.allclose(old[1].values, 700.0)
    assert [g.name for g in frame_grids("dust", x, np.array([0.1, 0.1]), np.zeros(2), 0.2)
            ] == ["density"]
    assert system_voxel(np.full(5, 2.95), 0.1) == pytest.approx(0.738)
    assert system_voxel(np.full(5, 0.15), 0.1) == 0.1


# ----------------------------------------------------------------------------- USD

def _volume_files(stage: Usd.Stage, system: str, fields: tuple[str, ...]) -> dict[int, Path]:
    volume = UsdVol.Volume(stage.GetPrimAtPath(f"/Shot/Particles/{system}"))
    assert volume, system
    paths = volume.GetFieldPaths()
    assert sorted(paths) == sorted(fields)
    out = {}
    for field in fields:
        asset = UsdVol.OpenVDBAsset(stage.GetPrimAtPath(paths[field]))
        assert asset.GetFieldNameAttr().Get() == field
        attr = asset.GetFilePathAttr()
        for t in attr.GetTimeSamples():
            value = attr.Get(t)
            assert value.path == f"./shot_volumes/{system}.{int(t):04d}.vdb"
            out[int(t)] = Path(value.resolvedPath)
    return out


def test_usd_volumes_per_frame(fiery, tmp_path):
    """Each system with particles is a Volume whose fields read one file per frame from
    its first live particle to its last (relative paths into shot_volumes/, which
    exist), invisible before; the files hold the grids of that frame."""
    out = tmp_path / "shot.usda"
    export(fiery, out)
    stage = Usd.Stage.Open(str(out))
    dust = _volume_files(stage, "dust", ("density",))
    assert sorted(dust) == list(range(6, F))  # born at frame 6, alive to the end
    fire = _volume_files(stage, "fireball", ("density", "temperature"))
    assert sorted(fire) == list(range(1, F))
    assert all(p.is_file() for p in [*dust.values(), *fire.values()])
    assert sorted(p.name for p in (tmp_path / "shot_volumes").iterdir()) == sorted(
        p.name for p in [*dust.values(), *fire.values()])
    volume = UsdVol.Volume(stage.GetPrimAtPath("/Shot/Particles/dust"))
    assert volume.ComputeVisibility(5) == "invisible"
    assert volume.ComputeVisibility(6) == "inherited"
    lo, hi = np.array(volume.GetExtentAttr().Get(8))
    assert (hi > lo).all()
    material, _ = UsdShade.MaterialBindingAPI(volume.GetPrim()).ComputeBoundMaterial()
    assert material.GetPath() == "/Shot/Materials/particle_dust"
    assert not stage.GetPrimAtPath("/Shot/Particles/dust/Prototypes")  # no spheres
    assert validate_usd(out) == []


@needs_blender
def test_usd_volume_files_read_by_openvdb(fiery, tmp_path):
    """The fireball's frame 3 read by OpenVDB: density and temperature on the same
    voxels, the voxel size the system's, the grid's integral the live particles'
    summed cross-section."""
    out = tmp_path / "shot.usdc"
    export(fiery, out)
    path = tmp_path / "shot_volumes" / "fireball.0003.vdb"
    density, temperature = _openvdb_read(path)[str(path)]
    assert (density["name"], temperature["name"]) == ("density", "temperature")
    h = system_voxel(np.full(30, 0.8), ExportOptions().volume_voxel_m)
    assert density["voxel_size"] == pytest.approx([h] * 3)
    assert density["ijk"] == temperature["ijk"] and density["active"] > 100
    assert np.sum(density["values"]) * h**3 == pytest.approx(
        30 * cross_section(np.array([0.8]), VOLUME_LOOKS["fireball"].tau)[0],
        rel=1e-4)  # all 30 born by frame 3
    assert 700.0 <= min(temperature["values"]) <= max(temperature["values"]) <= 2200.0


def _glow_parts(stage, system: str) -> list:
    """The UsdPreviewSurface of each prototype of ``system``'s glow (its rim, its hot
    core), checking that every binding on the way targets a real prim."""
    from pxr import UsdGeom

    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath(f"/Shot/Particles/{system}_glow"))
    assert instancer, system
    shaders = []
    for k, path in enumerate(instancer.GetPrototypesRel().GetTargets()):
        assert path.name == ("rim", "hot")[k]
        mesh = stage.GetPrimAtPath(path)
        assert mesh.GetTypeName() == "Mesh"
        (target,) = UsdShade.MaterialBindingAPI(mesh).GetDirectBindingRel().GetTargets()
        material = UsdShade.Material(stage.GetPrimAtPath(target))
        assert material, target  # a real Material prim
        shader = material.ComputeSurfaceSource()[0]
        assert shader.GetIdAttr().Get() == "UsdPreviewSurface"
        shaders.append(shader)
    assert len(shaders) == 2
    return shaders


@pytest.mark.parametrize("name", ["shot.usda", "pack.usdz"])
def test_fireball_glows_beside_its_volume(fiery, tmp_path, name):
    """Blender's USD importer gives a Volume no material, so fire and the fireball also
    get Particles/<system>_glow: an instancer of emissive balls (a rim and a hotter
    core, each bound to a real Material whose UsdPreviewSurface emits, translucent),
    fewer blobs than particles, each blob's id its group's from frame to frame,
    shrinking as they cool to nothing; beside the Volume (.usda) or the spheres (.usdz,
    where the fireball's spheres are its smoke, none at birth, growing as it cools),
    still valid USD."""
    from pxr import UsdGeom

    out = tmp_path / name
    export(fiery, out)
    stage = Usd.Stage.Open(str(out))
    parts = _glow_parts(stage, "fireball")
    emit = [np.array(s.GetInput("emissiveColor").Get()) for s in parts]
    assert all((e > 0).all() for e in emit)
    assert emit[0].sum() < emit[1].sum()  # a hot core, a cooler rim
    assert all(0 < s.GetInput("opacity").Get() < 0.5 for s in parts)
    body = stage.GetPrimAtPath("/Shot/Particles/fireball")
    assert body.GetTypeName() == ("Volume" if name.endswith("usda") else "PointInstancer")
    material, _ = UsdShade.MaterialBindingAPI(body).ComputeBoundMaterial() \
        if body.IsA(UsdVol.Volume) else (None, None)
    assert material is None or stage.GetPrimAtPath(material.GetPath())
    glow = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Shot/Particles/fireball_glow"))
    assert glow.ComputeVisibility(0) == "invisible"  # born at frame 1
    assert glow.ComputeVisibility(1) == "inherited"
    ids = [np.asarray(glow.GetIdsAttr().Get(f)) for f in range(F)]
    assert 1 <= len(ids[1]) < 10  # 10 particles, pooled: a rim and a core per blob
    protos = [np.asarray(glow.GetProtoIndicesAttr().Get(f)) for f in range(F)]
    assert all(((p == ids[f] % 2) | (ids[f] < 0)).all() for f, p in enumerate(protos))
    sizes = [np.asarray(glow.GetScalesAttr().Get(f))[:, 0] for f in range(F)]
    assert all(len(v) == len(ids[f]) == len(glow.GetPositionsAttr().Get(f)) == len(
        glow.GetVelocitiesAttr().Get(f)) for f, v in enumerate(sizes))
    assert sizes[1].max() <= 2.4 * 0.8 * 1.5  # the glow of a few close particles
    assert sizes[-1].max() == 0.0  # a 1 kg fireball glows 0.26 s: cooled to nothing
    if body.IsA(UsdGeom.PointInstancer):
        smoke = UsdGeom.PointInstancer(body)
        assert np.asarray(smoke.GetScalesAttr().Get(1)).max() < 0.1 * 0.8  # just born
        assert np.asarray(smoke.GetScalesAttr().Get(F - 1)).max() > 0.5 * 0.8
        assert len(smoke.GetIdsAttr().Get(F - 1)) <= 30 // 4 + 1  # one in four
    assert validate_usd(out) == []


def test_glow_groups_and_blobs():
    """Particles born together in one place are one group for life, those born far or
    late another; a group's blob is as wide as its members' glow when they coincide,
    centred on them; a particle's glow shrinks as it cools, to nothing at its duration
    (the fireball's: the measured one, 0.258 W^0.349 s)."""
    from blastvox.export.glow import (
        DRAPER_K,
        fireball_diameter,
        fireball_duration,
        glow_blobs,
        glow_groups,
        glow_share,
    )
    from blastvox.export.usd_glow import glow_duration
    from blastvox.particles import SYSTEMS

    birth = np.array([0.0, 0.0, 0.1, 0.0, 0.5])
    x0 = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0, 0], [9.0, 0, 0], [0.0, 0, 0]])
    assert glow_groups(birth, x0, window=0.25, reach=1.0).tolist() == [0, 0, 0, 1, 2]
    group = np.zeros(200, dtype=np.int64)
    x, v = np.zeros((200, 3)), np.ones((200, 3))
    ids, centre, diameter, core, velocity = glow_blobs(
        group, x, v, np.full(200, 6.0), np.full(200, 3.0), np.array([1200.0]))
    assert ids.tolist() == [0] and centre.tolist() == [[0.0, 0.0, 0.0]]
    assert diameter.tolist() == [6.0] and core.tolist() == [3.0]
    assert velocity.tolist() == [[1.0, 1.0, 1.0]]
    group[100:], x[100:] = 1, [50.0, 0.0, 0.0]
    ids, centre, diameter, _, _ = glow_blobs(group, x, v, np.full(200, 2.0),
                                             np.zeros(200), np.array([400.0, 400.0]))
    assert ids.tolist() == [0, 1] and centre[:, 0].tolist() == [0.0, 50.0]
    assert diameter.tolist() == [2.0, 2.0]
    assert [len(a) for a in glow_blobs(group, x, v, np.zeros(200), np.zeros(200),
                                       np.ones(2))] == [0, 0, 0, 0, 0]
    assert fireball_duration(50.0) == pytest.approx(1.01, abs=0.01)
    assert fireball_diameter(50.0) == pytest.approx(13.5, abs=0.1)
    spec = SYSTEMS["fireball"]
    duration = glow_duration("fireball", spec, np.array([spec.size * 50 ** (1 / 3)]))
    assert duration == pytest.approx(fireball_duration(50.0))
    share = glow_share(np.array([-0.1, 0.0, 0.5, 1.0, 2.0]), np.full(5, 1.0), 2200.0)
    assert share[[0, 1, 3, 4]].tolist() == [0.0, 1.0, 0.0, 0.0] and 0.3 < share[2] < 0.6
    core = glow_share(np.array([0.0, 0.49, 0.51]), np.ones(3), 2200.0, floor_k=1500.0)
    assert core[0] == 1.0 and core[1] > 0 and core[2] == 0.0  # 1500 K at 0.4993 s
    assert glow_share(np.array([0.05]), np.ones(1), 1600.0, rise=0.2)[0] < 0.5
    assert DRAPER_K == 798.0


def test_glow_is_coherent_from_frame_to_frame():
    """Two 50 kg fireballs (the simulator's burst: 200 particles each, 0.3 s apart, 20 m
    apart) and a fire of flames born every frame: from frame to frame at 24 fps a blob
    keeps its id, its centre moves less than the particles can (22 m/s: 0.92 m), its
    width changes by less than 20 % of its largest (a fire blob, whose flames grow in
    over 0.2 s, 35 %), a fire blob is small when it appears and every blob is small
    when it goes; no blob pops."""
    from blastvox.export.glow import glow_blobs, glow_groups, glow_share
    from blastvox.export.usd_effects import _velocity
    from blastvox.export.usd_glow import GLOW_LOOKS, glow_duration
    from blastvox.export.volumes import VOLUME_LOOKS
    from blastvox.particles import SYSTEM_NAMES, SYSTEMS, all_positions_at

    rng = np.random.default_rng(5)
    g = np.array([0.0, -9.81, 0.0])
    bursts = {}
    scale = 50.0 ** (1 / 3)
    direction = rng.normal(size=(400, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    bursts["fireball"] = (np.repeat([0.0, 0.3], 200),
                          0.15 * scale * direction + np.repeat([[0, 1, 0], [20, 1, 0]], 200, 0),
                          direction * (6 * scale * rng.uniform(0.6, 1.0, 400))[:, None],
                          np.full(400, SYSTEMS["fireball"].size * scale))
    bursts["fire"] = (np.repeat(np.arange(24) / 24, 10), rng.uniform(0, 2, (240, 3)),
                      rng.normal(0, 0.3, (240, 3)) + [0, 0.5, 0], np.full(240, 0.25))
    for name, (birth, x0, v0, size) in bursts.items():
        spec, look = SYSTEMS[name], GLOW_LOOKS[name]
        full = look["core"] * size
        duration = glow_duration(name, spec, size)
        group = glow_groups(birth, x0, look["window"], look["reach"] * float(np.median(size)))
        totals = np.bincount(group, full)
        system = np.full(len(birth), SYSTEM_NAMES.index(name), dtype=np.uint8)
        frames = []
        for f in range(48):
            t = f / 24
            alive, x = all_positions_at(birth, x0, v0, system, t, g)
            age = t - birth[alive]
            glow = full[alive] * glow_share(age, duration[alive], VOLUME_LOOKS[name].hot_k,
                                            look["rise"])
            ids, centre, diameter, _, _ = glow_blobs(
                group[alive], x[alive], _velocity(spec, v0[alive], age, g), glow, glow,
                totals)
            frames.append(dict(zip(ids.tolist(), zip(centre, diameter, strict=True),
                                   strict=True)))
        largest = {}
        for blobs in frames:
            for k, (_, d) in blobs.items():
                largest[k] = max(largest.get(k, 0.0), d)
        assert len(largest) < len(birth) / 4  # pooled
        steps = []
        for before, after in zip(frames, frames[1:], strict=False):
            for k in before.keys() & after.keys():
                assert np.linalg.norm(after[k][0] - before[k][0]) < 0.92, (name, k)
                steps.append(abs(after[k][1] - before[k][1]) / largest[k])
            for k in before.keys() - after.keys():  # gone: it faded out first
                assert before[k][1] < 0.2 * largest[k], (name, k)
            if name == "fire":
                for k in after.keys() - before.keys():  # new: it fades in
                    assert after[k][1] < 0.5 * largest[k], (name, k)
        assert max(steps) < (0.35 if name == "fire" else 0.2), (name, max(steps))


def test_spheres_on_request_and_in_usdz(fiery, tmp_path):
    export(fiery, tmp_path / "shot.usda", ExportOptions(particles="spheres"))
    stage = Usd.Stage.Open(str(tmp_path / "shot.usda"))
    assert stage.GetPrimAtPath("/Shot/Particles/dust").GetTypeName() == "PointInstancer"
    assert not (tmp_path / "shot_volumes").exists()
    export(fiery, tmp_path / "pack.usdz")  # auto: spheres
    assert not (tmp_path / "pack_volumes").exists()
    with pytest.raises(BlastvoxError, match="cannot carry"):
        export(fiery, tmp_path / "pack.usdz", ExportOptions(particles="volumes"))
    with pytest.raises(BlastvoxError, match="volume-voxel"):
        export(fiery, tmp_path / "x.usdc", ExportOptions(volume_voxel_m=0.0))


def test_cells_too_small_for_the_shot_are_one_error(fiery, tmp_path, monkeypatch):
    """A cell size that would make a frame's splat too large (here a limit of 1,000
    cells) is one BlastvoxError naming the volumes folder, the system and the frame, and
    writes nothing."""
    from blastvox.export import volumes

    monkeypatch.setattr(volumes, "MAX_SPLAT_CELLS", 1000)
    with pytest.raises(BlastvoxError, match=r"shot_volumes: fireball particles at frame 1: "
                                            r".* use a larger --volume-voxel"):
        export(fiery, tmp_path / "shot.usdc")
    assert list(tmp_path.iterdir()) == []


def test_volumes_same_bytes_twice(fiery, tmp_path):
    a, b = tmp_path / "a" / "shot.usdc", tmp_path / "b" / "shot.usdc"
    for out in (a, b):
        out.parent.mkdir()
        export(fiery, out)
    export(fiery, a)  # again, in place
    files = sorted(p.relative_to(a.parent) for p in a.parent.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(b.parent) for p in b.parent.rglob("*") if p.is_file())
    assert any(f.suffix == ".vdb" for f in files)
    for f in files:
        assert (a.parent / f).read_bytes() == (b.parent / f).read_bytes(), f


def test_failed_export_leaves_no_volumes(fiery, tmp_path, monkeypatch):
    """A failure after some volume files are written (here the 5th) leaves no volumes
    folder, no partial file, and a previous export exactly as it was."""
    from blastvox.export import vdb

    real = vdb.write_vdb
    calls = []

    def failing(path, grids, zipped=None):
        calls.append(path)
        if len(calls) == 5:
            raise KeyboardInterrupt
        return real(path, grids, zipped)

    out = tmp_path / "shot.usdc"
    monkeypatch.setattr(vdb, "write_vdb", failing)
    with pytest.raises(KeyboardInterrupt):
        export(fiery, out)
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setattr(vdb, "write_vdb", real)
    export(fiery, out)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    calls.clear()
    monkeypatch.setattr(vdb, "write_vdb", failing)
    with pytest.raises(KeyboardInterrupt):
        export(fiery, out, ExportOptions(volume_voxel_m=0.2))
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".partial")]


def test_cli_run_writes_volumes(tmp_path):
    """`blastvox run` on the house example (copied, its volumes at 0.4 m cells and its
    first 0.5 s to stay fast): the .usda's dust and fireball read their .vdb files."""
    scene_dir = tmp_path / "house"
    shutil.copytree(ROOT / "examples" / "house", scene_dir)
    scene = scene_dir / "scene.toml"
    text = scene.read_text().replace("../../out/house/", "out/")
    text = re.sub(r"\nvolume_voxel_m = .*", "", text)  # the example's own cell size
    text = text.replace("duration = 3.0", "duration = 0.5")  # dust and fireball by then
    text = text.replace('export = ["out/shot.usda", "out/shot.glb"]',
                        'export = "out/shot.usda"\nvolume_voxel_m = 0.4')
    assert "volume_voxel_m = 0.4" in text and "duration = 0.5" in text
    scene.write_text(text)
    result = subprocess.run([sys.executable, "-m", "blastvox", "run", str(scene), "-q"],
                            capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    stage = Usd.Stage.Open(str(scene_dir / "out" / "shot.usda"))
    files = _volume_files(stage, "dust", ("density",))
    assert files and all(p.is_file() for p in files.values())
    assert _volume_files(stage, "fireball", ("density", "temperature"))
    path = next(iter(files.values()))
    assert _openvdb_voxel(path) == pytest.approx(0.4)  # the scene's cell size


def _openvdb_voxel(path: Path) -> float:
    """The cell size a .vdb file's transform holds (read with our own layout: the
    UniformScaleTranslateMap's voxel size follows its translation)."""
    import struct

    data = path.read_bytes()
    at = data.index(b"UniformScaleTranslateMap") + len(b"UniformScaleTranslateMap")
    return struct.unpack_from("<3d", data, at + 24 + 24)[0]


# ----------------------------------------------------------------------------- glTF

def test_glb_particles_on_request(fiery, tmp_path):
    """--particles spheres gives a .glb a node per particle (at most the budget per
    system): the system's sphere, translated along the closed form (Y up) at every
    frame, scaled to its radius while it lives and to 0 before; none by default. The
    Khronos validator (where installed) reports no errors or warnings."""
    from test_export_gltf import accessor, read_glb

    from blastvox.export.gltf_particles import GLTF_PARTICLE_BUDGET
    from blastvox.export.gltf_validate import validate_gltf, validator_available
    from blastvox.export.usd_specs import model_gravity
    from blastvox.geometry.frames import frame_change
    from blastvox.particles import all_positions_at

    plain = tmp_path / "plain.glb"
    export(fiery, plain)
    doc, _ = read_glb(plain.read_bytes())
    assert not [n for n in doc["nodes"] if "system" in n.get("extras", {})]
    out = tmp_path / "shot.glb"
    export(fiery, out, ExportOptions(particles="spheres"))
    doc, blob = read_glb(out.read_bytes())
    particles = {i: n for i, n in enumerate(doc["nodes"]) if "system" in n.get("extras", {})}
    q = len(fiery.particle_birth)
    assert sorted(n["extras"]["particle"] for n in particles.values()) == list(range(q))
    assert q <= 2 * GLTF_PARTICLE_BUDGET
    root = doc["nodes"][doc["scenes"][0]["nodes"][0]]
    assert set(particles) <= set(root["children"])
    change = frame_change("Z", "Y")
    channels = doc["animations"][0]["channels"]
    samplers = doc["animations"][0]["samplers"]
    for i, node in particles.items():
        p = node["extras"]["particle"]
        got = {c["target"]["path"]: samplers[c["sampler"]] for c in channels
               if c["target"]["node"] == i}
        assert got["scale"]["interpolation"] == "STEP"
        scale = accessor(doc, blob, got["scale"]["output"])
        trans = accessor(doc, blob, got["translation"]["output"])
        for f in (0, F - 1):
            alive, x = all_positions_at(fiery.particle_birth[p:p + 1],
                                        fiery.particle_position[p:p + 1] @ change.T,
                                        fiery.particle_velocity[p:p + 1] @ change.T,
                                        fiery.particle_system[p:p + 1],
                                        float(fiery.frame_time[f]),
                                        change @ model_gravity(fiery))
            radius = fiery.particle_size[p] / 2 if alive[0] else 0.0
            assert np.allclose(scale[f], radius, atol=1e-6), (p, f)
            assert np.allclose(trans[f], x[0], atol=1e-4), (p, f)
    if validator_available() is None:
        issues = validate_gltf(out)["issues"]
        assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues
