"""USD export: files are read back with pxr and checked against the SimCache.

Two caches: a small synthetic one (three pieces of a two-material box with
known motion, a piece that vanishes into dust at frame 6, damage steps and a
shock front), so every expectation is exact; and a real simulation of a brick
wall, for the integration checks (validation, transforms, the CLI).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom, UsdShade  # noqa: E402

from blastvox.cache import SimCache  # noqa: E402
from blastvox.errors import OutputError  # noqa: E402
from blastvox.export.api import ExportOptions, export  # noqa: E402
from blastvox.export.pieces import (  # noqa: E402
    animation,
    frame_change,
    piece_meshes,
    piece_objects,
)
from blastvox.export.usd import write_usd  # noqa: E402
from blastvox.export.usd_specs import piece_prim_paths  # noqa: E402
from blastvox.export.usd_validate import validate_usd  # noqa: E402
from blastvox.geometry import quaternion  # noqa: E402

F, FPS = 10, 10.0
VANISH_PIECE, VANISH_FRAME = 2, 6
GRAVITY = 9.81
#: the synthetic cache's pieces under their objects (piece 1 spans both: its first voxel's)
PIECE = ["/Shot/left/piece_00000", "/Shot/left/piece_00001", "/Shot/right/piece_00002"]


# ----------------------------------------------------------------------------- caches

@pytest.fixture(scope="module")
def synthetic(tmp_path_factory) -> SimCache:
    import trimesh

    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("synthetic")
    requests = []
    for name, x, material in (("left", -0.25, "brick"), ("right", 0.25, "wood")):
        box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
        box.apply_translation((x, 0.0, 0.25))
        box.export(tmp / f"{name}.stl")
        requests.append(ObjectRequest(mesh=tmp / f"{name}.stl", name=name,
                                      voxel_size=(0.25,) * 3, material=material))
    model = voxelize(requests, VoxelizeSettings(up_axis="Z", ground=None))
    a = model.arrays
    n = model.voxel_count
    slab = np.clip(np.floor((a["voxel_centroid"][:, 0] + 0.5) / 0.25), 0, 3).astype(int)
    piece = np.array([0, 1, 1, 2])[slab].astype(np.int32)  # piece 1 spans both materials
    p_count = 3
    mass = np.bincount(piece, weights=a["voxel_mass"], minlength=p_count)
    pivot = np.stack([np.bincount(piece, weights=a["voxel_mass"] * a["voxel_centroid"][:, i],
                                  minlength=p_count) for i in range(3)], axis=1) / mass[:, None]
    t = np.arange(F) / FPS
    velocity = np.array([[-2.0, 1.0, 3.0], [0.0, 0.0, 0.0], [3.0, -1.0, 4.0]])
    g = np.array([0.0, 0.0, -GRAVITY])
    moving = np.array([1.0, 0.0, 1.0])[:, None]  # piece 1 stays at rest
    position = pivot[None] + (t[:, None, None] * velocity[None]
                              + 0.5 * t[:, None, None] ** 2 * g * moving[None])
    axis = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    spin = np.array([4.0, 0.0, -6.0])
    half = 0.5 * spin[None] * t[:, None]
    orientation = np.concatenate([np.cos(half)[..., None], np.sin(half)[..., None] * axis[None]],
                                 axis=-1)
    end = np.full(p_count, F, dtype=np.int32)
    end[VANISH_PIECE] = VANISH_FRAME
    destroyed = np.where(piece == VANISH_PIECE, VANISH_FRAME, -1).astype(np.int32)
    dust = np.flatnonzero(destroyed >= 0).astype(np.int32)
    t_dust = t[VANISH_FRAME]
    q = orientation[VANISH_FRAME, VANISH_PIECE]
    dust_pos = position[VANISH_FRAME, VANISH_PIECE] + quaternion.rotate(
        q, a["voxel_centroid"][dust] - pivot[VANISH_PIECE])
    dust_vel = np.tile(velocity[VANISH_PIECE] + g * t_dust, (len(dust), 1))
    # damage: a voxel of piece 1 steps to 128 at frame 2 and 255 at frame 5, another to
    # 64 at frame 5; destroyed voxels jump to 255 at their frame
    v1 = np.flatnonzero(piece == 1)
    d_frame = np.array([2, 5, 5] + [VANISH_FRAME] * len(dust), dtype=np.int32)
    d_voxel = np.array([v1[0], v1[0], v1[1], *dust], dtype=np.int32)
    d_value = np.array([128, 255, 64] + [255] * len(dust), dtype=np.uint8)
    radius = np.where(t > 0.15, 340.0 * (t - 0.15), 0.0)
    i4, f8 = np.zeros(0, np.int32), np.zeros(0)
    arrays = {
        "frame_time": t, "voxel_piece": piece, "piece_pivot": pivot, "piece_mass": mass,
        "piece_position": position.astype(np.float32),
        "piece_orientation": orientation.astype(np.float32), "piece_end_frame": end,
        "voxel_destroyed_frame": destroyed, "damage_frame": d_frame, "damage_voxel": d_voxel,
        "damage_value": d_value, "link_break_link": i4, "link_break_time": f8,
        "dust_voxel": dust, "dust_time": np.full(len(dust), t_dust), "dust_mass":
        a["voxel_mass"][dust], "dust_position": dust_pos, "dust_velocity": dust_vel,
        "charge_position": np.array([[0.0, -3.0, 0.25]]), "charge_tnt_kg": np.array([5.0]),
        "charge_time": np.array([0.15]), "shock_radius": radius[:, None],
        # the destroyed voxels' dust as particles of the dust system (index 0)
        "particle_system": np.zeros(len(dust), np.uint8),
        "particle_birth": np.full(len(dust), t_dust), "particle_position": dust_pos,
        "particle_velocity": dust_vel, "particle_size": np.full(len(dust), 0.1, np.float32),
    }
    assert n == 16
    return SimCache(arrays=arrays, model=model,
                    meta={"fps": FPS, "settings": {"gravity": GRAVITY},
                          "gravity_vector": [0.0, 0.0, -GRAVITY]})


@pytest.fixture(scope="module")
def wall(tmp_path_factory) -> tuple[SimCache, Path]:
    """A real simulation: a 2 x 0.5 x 2 m brick wall, 2 kg TNT 2 m in front."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("wall")
    trimesh.creation.box(extents=(2, 0.5, 2)).export(tmp / "wall.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "wall.stl", voxel_size=(0.25,) * 3,
                                    material="brick")], VoxelizeSettings(up_axis="Z"))
    cache = simulate(model, SimSettings(duration=0.5, fps=24,
                                        charges=(ChargeSpec((0, -2.0, 1.0), 40.0),)))
    path = tmp / "wall_sim.npz"
    cache.save(path)
    return SimCache.load(path), path


def _write(cache: SimCache, path: Path, up: str = "Y", layout: str = "xforms",
           shock: bool = False, damage_textures: bool = True,
           particles: str = "auto", damage_samples: bool = False) -> Usd.Stage:
    export(cache, path, ExportOptions(up_axis=up, layout=layout, shock=shock,
                                      damage_textures=damage_textures, particles=particles,
                                      damage_samples=damage_samples))
    stage = Usd.Stage.Open(str(path))
    assert stage is not None
    return stage


# ----------------------------------------------------------------------------- stage

@pytest.mark.parametrize("up", ["Y", "Z"])
def test_stage_metadata(synthetic, tmp_path, up):
    stage = _write(synthetic, tmp_path / "shot.usda", up=up)
    assert UsdGeom.GetStageUpAxis(stage) == up
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == FPS
    assert stage.GetFramesPerSecond() == FPS
    assert stage.GetStartTimeCode() == 0
    assert stage.GetEndTimeCode() == F - 1
    assert stage.GetDefaultPrim().GetPath() == "/Shot"


def test_one_xform_and_mesh_per_piece(synthetic, tmp_path):
    stage = _write(synthetic, tmp_path / "shot.usdc")
    assert [p.GetName() for p in stage.GetPrimAtPath("/Shot").GetChildren()
            if p.IsA(UsdGeom.Xform)][:2] == ["left", "right"]
    pieces = [stage.GetPrimAtPath(path) for path in PIECE]
    assert [p.GetName() for p in pieces] == ["piece_00000", "piece_00001", "piece_00002"]
    meshes = piece_meshes(synthetic, "Y")
    for p, prim in enumerate(pieces):
        assert prim.IsA(UsdGeom.Xform)
        mesh = UsdGeom.Mesh(prim.GetChild(prim.GetName()))
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
        assert len(counts) == meshes.offsets[p + 1] - meshes.offsets[p]
        assert np.all(counts == 3)
        assert len(mesh.GetNormalsAttr().Get()) == 3 * len(counts)
        assert mesh.GetNormalsInterpolation() == UsdGeom.Tokens.faceVarying
        assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
        points = np.asarray(mesh.GetPointsAttr().Get())
        extent = np.asarray(mesh.GetExtentAttr().Get())
        assert np.allclose(extent, [points.min(axis=0), points.max(axis=0)])
        # every triangle of piece_meshes is there (points are shared, so compare corners)
        corners = points[np.asarray(mesh.GetFaceVertexIndicesAttr().Get())].reshape(-1, 3, 3)
        expected = meshes.vertices[meshes.offsets[p]:meshes.offsets[p + 1]]
        assert np.allclose(corners, expected, atol=1e-6)


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_world_transform_matches_cache(synthetic, tmp_path, up):
    stage = _write(synthetic, tmp_path / "shot.usdc", up=up)
    c = frame_change("Z", up)
    for p, f in ((0, F - 1), (2, VANISH_FRAME - 1), (0, 3)):
        prim = stage.GetPrimAtPath(PIECE[p])
        world = UsdGeom.XformCache(Usd.TimeCode(f)).GetLocalToWorldTransform(prim)
        pos = synthetic.piece_position[f, p].astype(np.float64)
        assert np.allclose(np.array(world.ExtractTranslation()), c @ pos, atol=1e-6)
        # a mesh vertex goes where the cache's rigid transform sends it
        mesh = UsdGeom.Mesh(prim.GetChild(prim.GetName()))
        local = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
        got = np.array([world.Transform(pxr.Gf.Vec3d(*x)) for x in local])
        q = synthetic.piece_orientation[f, p].astype(np.float64)
        want = (pos + quaternion.rotate(q, local @ c)) @ c.T  # local = C (x - pivot)
        assert np.allclose(got, want, atol=1e-5)


def test_unchanged_samples_are_pruned(synthetic, tmp_path):
    stage = _write(synthetic, tmp_path / "shot.usda")
    resting = UsdGeom.Xformable(stage.GetPrimAtPath(PIECE[1]))
    # a constant double3 start (the piece's frame-0 translation), then float3 offsets from it
    start, translate = (op.GetAttr() for op in resting.GetOrderedXformOps()[:2])
    assert not start.GetTimeSamples() and start.HasAuthoredValue()
    assert translate.GetTimeSamples() == [0.0]
    assert tuple(translate.Get(0)) == (0.0, 0.0, 0.0)
    moving = UsdGeom.Xformable(stage.GetPrimAtPath(PIECE[0]))
    assert len(moving.GetOrderedXformOps()[1].GetAttr().GetTimeSamples()) == F
    ops = [op.GetOpName() for op in moving.GetOrderedXformOps()]
    assert ops == ["xformOp:translate:start", "xformOp:translate", "xformOp:orient"]
    precision = [op.GetPrecision() for op in moving.GetOrderedXformOps()]
    assert precision == [UsdGeom.XformOp.PrecisionDouble, UsdGeom.XformOp.PrecisionFloat,
                         UsdGeom.XformOp.PrecisionFloat]
    # a vanished piece has no samples after it is gone
    gone = UsdGeom.Xformable(stage.GetPrimAtPath(PIECE[VANISH_PIECE]))
    assert max(gone.GetOrderedXformOps()[1].GetAttr().GetTimeSamples()) == VANISH_FRAME - 1


def test_visibility_switches_at_end_frame(synthetic, tmp_path):
    stage = _write(synthetic, tmp_path / "shot.usdc")
    gone = UsdGeom.Imageable(stage.GetPrimAtPath(PIECE[VANISH_PIECE]))
    for f in range(F):
        want = "invisible" if f >= VANISH_FRAME else "inherited"
        assert gone.ComputeVisibility(Usd.TimeCode(f)) == want
    kept = UsdGeom.Imageable(stage.GetPrimAtPath(PIECE[0]))
    assert not kept.GetVisibilityAttr().HasAuthoredValue()
    assert kept.ComputeVisibility(Usd.TimeCode(F - 1)) == "inherited"


# ----------------------------------------------------------------------------- materials

def _subsets(stage: Usd.Stage, p: int, paths: list[str] = PIECE
             ) -> dict[str, UsdGeom.Subset]:
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{paths[p]}/piece_{p:05d}"))
    assert mesh  # an invalid prim would crash GetGeomSubsets
    return {s.GetPrim().GetName(): s for s in
            UsdGeom.Subset.GetGeomSubsets(mesh, UsdGeom.Tokens.face, "materialBind")}


def _face_materials(stage: Usd.Stage, p: int, paths: list[str] = PIECE) -> list[str]:
    """The material each face of piece p's mesh renders with: its materialBind subset's,
    or the mesh's own binding where it has no subsets."""
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{paths[p]}/piece_{p:05d}"))
    faces = len(mesh.GetFaceVertexCountsAttr().Get())
    subsets = _subsets(stage, p, paths)
    if not subsets:
        bound = UsdShade.MaterialBindingAPI(mesh.GetPrim()).ComputeBoundMaterial()[0]
        return [str(bound.GetPath())] * faces
    out = [""] * faces
    for subset in subsets.values():
        bound = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()[0]
        for i in subset.GetIndicesAttr().Get():
            out[i] = str(bound.GetPath())
    return out


def test_damage_subsets_match_piece_meshes(synthetic, tmp_path):
    """Every face renders with its material's surface or damage material: through a
    GeomSubset (a materialBind partition, elementType the fallback "face") where a piece
    has faces of several, through the mesh's own binding where all its faces share one."""
    stage = _write(synthetic, tmp_path / "shot.usdc")
    meshes = piece_meshes(synthetic, "Y")
    names = synthetic.model.meta["materials"]
    single = 0
    for p in range(synthetic.piece_count):
        t0, t1 = meshes.offsets[p], meshes.offsets[p + 1]
        subsets = _subsets(stage, p)
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{PIECE[p]}/piece_{p:05d}"))
        pairs = list(zip(meshes.material[t0:t1].tolist(), meshes.damage[t0:t1].tolist(),
                         strict=True))
        keys = set(pairs)
        if len(keys) > 1:
            family = UsdGeom.Subset.GetFamilyType(mesh, "materialBind")
            assert family == UsdGeom.Tokens.partition
            valid, reason = UsdGeom.Subset.ValidateFamily(mesh, UsdGeom.Tokens.face,
                                                          "materialBind")
            assert valid, reason
            assert len(subsets) == len(keys)
            for subset in subsets.values():
                assert not subset.GetElementTypeAttr().HasAuthoredValue()
                assert subset.GetElementTypeAttr().Get() == UsdGeom.Tokens.face
        else:
            single += 1
            assert not subsets and not mesh.GetPrim().GetChildren()
        want = [f"/Shot/Materials/{names[m]}{'_damage' if d else ''}" for m, d in pairs]
        assert _face_materials(stage, p) == want
        damage = sum(len(s.GetIndicesAttr().Get()) for n, s in subsets.items()
                     if n.startswith("damage_"))
        assert damage == (int(meshes.damage[t0:t1].sum()) if len(keys) > 1 else 0)
        for name, subset in subsets.items():
            kind, material = name.split("_", 1)
            faces = np.asarray(subset.GetIndicesAttr().Get()) + t0
            assert np.all(meshes.damage[faces] == (kind == "damage"))
            assert {names[m] for m in meshes.material[faces]} == {material}
    # piece 1 spans both materials: a surface and a damage subset of each
    assert set(_subsets(stage, 1)) == {"surface_brick", "damage_brick", "surface_wood",
                                      "damage_wood"}


def test_material_bindings(synthetic, tmp_path):
    stage = _write(synthetic, tmp_path / "shot.usda", damage_textures=False)  # flat colours
    names = synthetic.model.meta["materials"]
    colors = synthetic.model.arrays["material_color"]
    damage_colors = synthetic.model.arrays["material_damage_color"]
    for i, name in enumerate(names):
        for path, color in ((f"/Shot/Materials/{name}", colors[i]),
                            (f"/Shot/Materials/{name}_damage", damage_colors[i])):
            material = UsdShade.Material(stage.GetPrimAtPath(path))
            assert material
            shader = material.ComputeSurfaceSource()[0]
            assert shader.GetIdAttr().Get() == "UsdPreviewSurface"
            assert np.allclose(shader.GetInput("diffuseColor").Get(), color, atol=1e-6)
            assert shader.GetInput("roughness").Get() == pytest.approx(0.8)
    for p in range(synthetic.piece_count):
        mesh = stage.GetPrimAtPath(f"{PIECE[p]}/piece_{p:05d}")
        # bound as a whole (MaterialBindingAPI) only where no subsets bind its faces
        assert mesh.HasAPI(UsdShade.MaterialBindingAPI) == (not _subsets(stage, p))
        for name, subset in _subsets(stage, p).items():
            prim = subset.GetPrim()
            assert prim.HasAPI(UsdShade.MaterialBindingAPI)
            bound = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
            kind, material = name.split("_", 1)
            suffix = "_damage" if kind == "damage" else ""
            assert bound.GetPath() == f"/Shot/Materials/{material}{suffix}"
    # displayColor per face agrees with the bound material
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(PIECE[1] + "/piece_00001"))
    display = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor")
    assert display.GetInterpolation() == UsdGeom.Tokens.uniform
    values = np.asarray(display.Get())
    for name, subset in _subsets(stage, 1).items():
        kind, material = name.split("_", 1)
        i = names.index(material)
        want = damage_colors[i] if kind == "damage" else colors[i]
        assert np.allclose(values[np.asarray(subset.GetIndicesAttr().Get())], want, atol=1e-6)


def test_damage_primvar_is_final_value_and_first_frame_by_default(synthetic, tmp_path):
    """Without --damage-samples the per-face damage is constant (no mesh animation for
    Blender to read per frame): its final value, and the frame each face is first hit."""
    stage = _write(synthetic, tmp_path / "shot.usdc")
    meshes = piece_meshes(synthetic, "Y")
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(PIECE[1] + "/piece_00001"))
    primvars = UsdGeom.PrimvarsAPI(mesh)
    damage, first = primvars.GetPrimvar("damage"), primvars.GetPrimvar("blastvox:damageFrame")
    assert damage.GetAttr().GetTimeSamples() == [] == first.GetAttr().GetTimeSamples()
    assert first.GetInterpolation() == UsdGeom.Tokens.uniform
    face_voxel = meshes.voxel[meshes.offsets[1]:meshes.offsets[2]]
    v1 = np.flatnonzero(synthetic.voxel_piece == 1)
    levels, frames = {v1[0]: 255, v1[1]: 64}, {v1[0]: 2, v1[1]: 5}
    assert np.allclose(np.asarray(damage.Get()),
                       [levels.get(v, 0) / 255.0 for v in face_voxel])
    assert list(first.Get()) == [frames.get(v, -1) for v in face_voxel]
    untouched = UsdGeom.PrimvarsAPI(UsdGeom.Mesh(
        stage.GetPrimAtPath(PIECE[0] + "/piece_00000")))
    assert np.all(np.asarray(untouched.GetPrimvar("damage").Get()) == 0.0)
    assert not untouched.GetPrimvar("blastvox:damageFrame")


def test_damage_primvar_steps_where_events_say(synthetic, tmp_path):
    stage = _write(synthetic, tmp_path / "shot.usdc", damage_samples=True)
    meshes = piece_meshes(synthetic, "Y")
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(PIECE[1] + "/piece_00001"))
    primvar = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("damage")
    assert primvar.GetInterpolation() == UsdGeom.Tokens.uniform
    t0, t1 = meshes.offsets[1], meshes.offsets[2]
    face_voxel = meshes.voxel[t0:t1]
    v1 = np.flatnonzero(synthetic.voxel_piece == 1)
    for f, levels in ((0, {}), (1, {}), (2, {v1[0]: 128}), (4, {v1[0]: 128}),
                      (5, {v1[0]: 255, v1[1]: 64}), (F - 1, {v1[0]: 255, v1[1]: 64})):
        want = np.array([levels.get(v, 0) / 255.0 for v in face_voxel], dtype=np.float32)
        assert np.allclose(np.asarray(primvar.Get(f)), want), f
    # samples only around the changes: frame 1 holds the old values, 2 steps, 4 holds, 5 steps
    assert primvar.GetAttr().GetTimeSamples() == [1.0, 2.0, 4.0, 5.0]
    untouched = UsdGeom.PrimvarsAPI(UsdGeom.Mesh(
        stage.GetPrimAtPath(PIECE[0] + "/piece_00000"))).GetPrimvar("damage")
    assert untouched.GetAttr().GetTimeSamples() == []
    assert np.all(np.asarray(untouched.Get(F - 1)) == 0.0)


# ----------------------------------------------------------------------------- dust, shock

def _shown(points: UsdGeom.PointInstancer, f: int) -> np.ndarray:
    """Which instances draw at frame f: those of the sprite (prototype 0), not of the
    fixed layout's empty ``hidden`` prototype."""
    return np.asarray(points.GetProtoIndicesAttr().Get(f)) == 0


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_dust_points_fly_ballistically(synthetic, tmp_path, up):
    """The synthetic dust lives from VANISH_FRAME to the end: the fixed layout (every
    particle at every frame, the unborn at their birth position and hidden, ids and
    scales once, no velocities: a constant count blurs by its positions)."""
    from blastvox.particles import positions_at

    stage = _write(synthetic, tmp_path / "shot.usdc", up=up, particles="spheres")
    points = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Shot/Particles/dust"))
    assert points
    assert [t.name for t in points.GetPrototypesRel().GetTargets()] == ["sprite", "hidden"]
    assert not stage.GetPrimAtPath("/Shot/Particles/dust/Prototypes/hidden").GetChildren()
    c = frame_change("Z", up)
    g = c @ np.array([0.0, 0.0, -GRAVITY])
    q = len(synthetic.particle_birth)
    assert np.array_equal(points.GetIdsAttr().Get(), np.arange(q))
    assert points.GetIdsAttr().GetNumTimeSamples() == 0
    assert np.allclose(points.GetScalesAttr().Get(), synthetic.particle_size[:, None])
    assert not points.GetVelocitiesAttr().HasAuthoredValue()
    for f in range(F):
        got = np.asarray(points.GetPositionsAttr().Get(f))
        assert len(got) == q
        if f < VANISH_FRAME:  # no particle yet: all hidden, the instancer invisible
            assert not _shown(points, f).any()
            assert points.ComputeVisibility(f) == "invisible"
            assert np.allclose(got, synthetic.particle_position @ c.T, atol=1e-5)  # at birth
            continue
        assert points.ComputeVisibility(f) == "inherited"
        alive, want = positions_at(synthetic.particle_birth, synthetic.particle_position @ c.T,
                                   synthetic.particle_velocity @ c.T, synthetic.particle_system,
                                   float(synthetic.frame_time[f]), g)
        assert np.array_equal(alive, np.arange(q)) and _shown(points, f).all()
        assert np.allclose(got, want, atol=1e-5)


def test_dust_is_dropped_after_its_lifetime(synthetic, tmp_path):
    """Half the dust dies two frames into the shot, the other half is born at its last
    frame: the alive-only layout (the live particles of each frame, with ids, scales
    and velocities) is the smaller; between the two, one instance of scale 0 and the
    instancer invisible."""
    from blastvox.particles import SYSTEMS, positions_at

    life = SYSTEMS["dust"].lifetime
    arrays = dict(synthetic.arrays)
    q = len(arrays["particle_birth"])
    early = np.arange(q) < q // 2
    last = float(synthetic.frame_time[-1])
    arrays["particle_birth"] = np.where(early, 0.05 - life, last)
    cache = SimCache(arrays=arrays, model=synthetic.model, meta=synthetic.meta)
    stage = _write(cache, tmp_path / "shot.usda", particles="spheres")
    points = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Shot/Particles/dust"))
    assert [t.name for t in points.GetPrototypesRel().GetTargets()] == ["sprite"]
    assert np.array_equal(points.GetIdsAttr().Get(0), np.flatnonzero(early))  # just alive
    alive, want = positions_at(cache.particle_birth, cache.particle_position,
                               cache.particle_velocity, cache.particle_system, 0.0,
                               np.array([0.0, 0.0, -GRAVITY]))
    assert np.array_equal(alive, np.flatnonzero(early))
    assert np.allclose(np.asarray(points.GetPositionsAttr().Get(0)),
                       want @ frame_change("Z", "Y").T, atol=1e-5)
    assert len(points.GetVelocitiesAttr().Get(0)) == len(alive)  # the count changes
    assert np.asarray(points.GetScalesAttr().Get(F - 2)).tolist() == [[0.0] * 3]  # none alive
    assert points.ComputeVisibility(F - 2) == "invisible"
    assert np.array_equal(points.GetIdsAttr().Get(F - 1), np.flatnonzero(~early))  # born
    assert points.ComputeVisibility(F - 1) == "inherited"


def test_each_particle_system_takes_the_smaller_layout():
    from blastvox.export.usd_effects import _layout_of

    assert _layout_of(100, [0, 100, 100, 100, 0]) == "fixed"    # all live the whole span
    assert _layout_of(100, [0, 10, 10, 10, 10]) == "alive only"  # short-lived
    assert _layout_of(100, [0, 0, 0]) == "alive only"
    assert _layout_of(100, [50, 50, 0, 0, 0, 0]) == "fixed"     # the span is only 2 frames


def test_no_dust_no_points_prim(synthetic, tmp_path):
    arrays = dict(synthetic.arrays)
    for key in list(arrays):
        if key.startswith(("dust_", "particle_")):
            arrays[key] = arrays[key][:0]
    cache = SimCache(arrays=arrays, model=synthetic.model, meta=synthetic.meta)
    stage = _write(cache, tmp_path / "shot.usda")
    assert not stage.GetPrimAtPath("/Shot/Particles")
    assert validate_usd(tmp_path / "shot.usda") == []


def test_particles_have_their_materials(synthetic, tmp_path):
    from pxr import UsdShade

    stage = _write(synthetic, tmp_path / "shot.usda", particles="spheres")
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Shot/Particles/dust"))
    sprite = instancer.GetPrototypesRel().GetTargets()[0]
    ball = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath(sprite)).GetPointsAttr().Get())
    radii = sorted(set(np.round(np.linalg.norm(ball, axis=1), 4).tolist()))
    assert radii == pytest.approx([0.22, 0.36, 0.5])  # soft: three shells, diameter 1
    material, _ = UsdShade.MaterialBindingAPI(
        stage.GetPrimAtPath(sprite)).ComputeBoundMaterial()
    assert material.GetPath() == "/Shot/Materials/particle_dust"
    shader = material.ComputeSurfaceSource()[0]
    assert shader.GetIdAttr().Get() == "UsdPreviewSurface"
    assert 0 < shader.GetInput("opacity").Get() < 1  # dust is translucent
    assert validate_usd(tmp_path / "shot.usda") == []


def test_no_shock_sphere_unless_asked(synthetic, tmp_path):
    """It grows to hundreds of metres, past the camera: a render saw only its inside."""
    stage = _write(synthetic, tmp_path / "shot.usda")
    assert not stage.GetPrimAtPath("/Shot/Effects")


def test_shock_sphere(synthetic, tmp_path):
    stage = _write(synthetic, tmp_path / "shot.usdc", up="Y", shock=True)
    sphere = UsdGeom.Sphere(stage.GetPrimAtPath("/Shot/Effects/shock_0"))
    assert sphere
    assert sphere.ComputePurpose() == UsdGeom.Tokens.guide  # renders skip it
    centre = UsdGeom.XformCache(Usd.TimeCode(0)).GetLocalToWorldTransform(
        sphere.GetPrim()).ExtractTranslation()
    assert np.allclose(np.array(centre), frame_change("Z", "Y") @ synthetic.charge_position[0])
    radius = synthetic.shock_radius[:, 0]
    opacity = UsdGeom.PrimvarsAPI(sphere).GetPrimvar("displayOpacity")
    previous = 2.0
    for f in range(F):
        assert sphere.GetRadiusAttr().Get(f) == pytest.approx(radius[f])
        visible = sphere.ComputeVisibility(Usd.TimeCode(f))
        assert visible == ("inherited" if 0 < radius[f] < radius.max() else "invisible")
        if radius[f] > 0:
            value = float(opacity.Get(f)[0])
            assert value < previous
            previous = value
    assert float(opacity.Get(F - 1)[0]) == pytest.approx(0.0)


# ----------------------------------------------------------------------------- piece attributes

def test_piece_xforms_carry_index_mass_and_object(synthetic, tmp_path):
    stage = _write(synthetic, tmp_path / "shot.usda")
    names = ["left", "left", "right"]  # piece 1 spans both objects: its first voxel's
    for p in range(synthetic.piece_count):
        # custom userProperties, which Blender imports as custom properties named as
        # the glTF export's node extras; written once (no primvars of the same values)
        prim = stage.GetPrimAtPath(PIECE[p])
        primvars = UsdGeom.PrimvarsAPI(prim)
        assert not any(primvars.HasPrimvar(f"blastvox:{k}") for k in ("piece", "mass",
                                                                       "object", "part"))
        for key, value in (("piece", p), ("mass_kg", synthetic.piece_mass[p]),
                           ("object", names[p])):
            attr = prim.GetAttribute(f"userProperties:{key}")
            assert attr.IsCustom() and attr.Get() == value
    assert validate_usd(tmp_path / "shot.usda") == []


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_xform_velocity_primvars_are_the_motion(synthetic, tmp_path, up):
    """Each piece Xform carries its velocity (m/s) and angular velocity (deg/s) as
    time-sampled primvars; the synthetic pieces fly at v + g t and spin steadily."""
    stage = _write(synthetic, tmp_path / "shot.usda", up=up)
    c = frame_change("Z", up)
    velocity = np.array([[-2.0, 1.0, 3.0], [0.0, 0.0, 0.0], [3.0, -1.0, 4.0]])
    moving = np.array([1.0, 0.0, 1.0])
    spin = np.array([[0.0, 0.0, 4.0], [0.0, 0.0, 0.0], [0.0, -6.0, 0.0]])  # rad/s
    g = np.array([0.0, 0.0, -GRAVITY])
    for p in range(synthetic.piece_count):
        primvars = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(PIECE[p]))
        linear = primvars.GetPrimvar("blastvox:velocity")
        angular = primvars.GetPrimvar("blastvox:angularVelocity")
        for f in range(1, min(F, int(synthetic.piece_end_frame[p])) - 1):
            t = float(synthetic.frame_time[f])
            np.testing.assert_allclose(np.asarray(linear.Get(f)),
                                       (velocity[p] + moving[p] * g * t) @ c.T, atol=2e-3)
            np.testing.assert_allclose(np.asarray(angular.Get(f)),
                                       np.degrees(spin[p] @ c.T), atol=0.05)
    # piece 1 rests: one sample holds its zero velocity for the whole shot
    rest = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(PIECE[1])).GetPrimvar("blastvox:velocity")
    assert rest.GetAttr().GetTimeSamples() == [0.0]


def test_objects_become_xforms_with_valid_unique_names():
    assert piece_prim_paths(["wall", "wall", "Camera", "my roof", "", "my_roof", "9x"]) == [
        "/Shot/wall/piece_00000", "/Shot/wall/piece_00001", "/Shot/Camera_1/piece_00002",
        "/Shot/my_roof/piece_00003", "/Shot/object/piece_00004",
        "/Shot/my_roof_1/piece_00005", "/Shot/_x/piece_00006"]


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_instancer_velocities_are_the_motion(synthetic, tmp_path, up):
    """The synthetic pieces fly at v + g t and spin steadily: central differences give
    both exactly inside the shot; angular velocities are in degrees per second."""
    stage = _write(synthetic, tmp_path / "shot.usdc", up=up, layout="instancer")
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Shot/Pieces"))
    c = frame_change("Z", up)
    velocity = np.array([[-2.0, 1.0, 3.0], [0.0, 0.0, 0.0], [3.0, -1.0, 4.0]])
    moving = np.array([1.0, 0.0, 1.0])[:, None]
    spin = np.array([[0.0, 0.0, 4.0], [0.0, 0.0, 0.0], [0.0, -6.0, 0.0]])  # rad/s
    g = np.array([0.0, 0.0, -GRAVITY])
    for f in range(1, F - 1):
        t = float(synthetic.frame_time[f])
        want = (velocity + moving * g * t) @ c.T
        np.testing.assert_allclose(np.asarray(inst.GetVelocitiesAttr().Get(f)), want,
                                   atol=2e-3)
        np.testing.assert_allclose(np.asarray(inst.GetAngularVelocitiesAttr().Get(f)),
                                   np.degrees(spin @ c.T), atol=0.05)
    assert list(inst.GetIdsAttr().Get()) == list(range(synthetic.piece_count))
    primvars = UsdGeom.PrimvarsAPI(inst)
    assert list(primvars.GetPrimvar("blastvox:mass").Get()) == synthetic.piece_mass.tolist()
    assert primvars.GetPrimvar("blastvox:mass").GetInterpolation() == "vertex"


# ----------------------------------------------------------------------------- instancer

@pytest.mark.parametrize("up", ["Y", "Z"])
def test_instancer_layout(synthetic, tmp_path, up):
    stage = _write(synthetic, tmp_path / "shot.usdc", up=up, layout="instancer")
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Shot/Pieces"))
    assert inst
    p_count = synthetic.piece_count
    targets = inst.GetPrototypesRel().GetTargets()
    assert [t.name for t in targets] == [f"piece_{p:05d}" for p in range(p_count)]
    assert list(inst.GetProtoIndicesAttr().Get()) == list(range(p_count))
    anim = animation(synthetic, up)
    for f in (0, VANISH_FRAME - 1, VANISH_FRAME, F - 1):
        positions = np.asarray(inst.GetPositionsAttr().Get(f))
        assert np.allclose(positions, anim.position[f], atol=1e-5)
        gone = list(inst.GetInvisibleIdsAttr().Get(f) or [])
        assert gone == ([VANISH_PIECE] if f >= VANISH_FRAME else [])
        # instance transforms agree with the xforms layout's
        xforms = inst.ComputeInstanceTransformsAtTime(
            Usd.TimeCode(f), Usd.TimeCode(f), UsdGeom.PointInstancer.IncludeProtoXform,
            UsdGeom.PointInstancer.IgnoreMask)
        assert len(xforms) == p_count
        for p in range(p_count):
            assert np.allclose(np.array(xforms[p].ExtractTranslation()), anim.position[f, p],
                               atol=1e-5)
            # the instance's rotation is the piece's (orientationsf: float precision)
            rotation = np.array(xforms[p].ExtractRotationMatrix()).T  # USD: row vectors
            q = anim.orientation[f, p]
            for axis in np.eye(3):
                assert np.allclose(rotation @ axis, quaternion.rotate(q, axis), atol=1e-5)
    # prototypes carry the same subsets and damage primvar as the xforms layout
    proto = stage.GetPrimAtPath(targets[1])
    assert UsdGeom.Mesh(proto)
    names = {s.GetPrim().GetName() for s in UsdGeom.Subset.GetGeomSubsets(
        UsdGeom.Mesh(proto), UsdGeom.Tokens.face, "materialBind")}
    assert "damage_brick" in names
    assert np.any(np.asarray(UsdGeom.PrimvarsAPI(proto).GetPrimvar("damage").Get()) > 0)


def test_instancer_orientation_matches(synthetic, tmp_path):
    stage = _write(synthetic, tmp_path / "shot.usda", layout="instancer")
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Shot/Pieces"))
    anim = animation(synthetic, "Y")
    f = F - 1
    for attr, tolerance in ((inst.GetOrientationsfAttr(), 1e-6),   # quatf, preferred
                            (inst.GetOrientationsAttr(), 2e-3)):   # quath
        quats = attr.Get(f)
        for p in range(synthetic.piece_count):
            got = np.array([quats[p].GetReal(), *quats[p].GetImaginary()])
            want = anim.orientation[f, p]
            assert min(np.abs(got - want).max(), np.abs(got + want).max()) < tolerance


# ----------------------------------------------------------------------------- files

@pytest.mark.parametrize("suffix", [".usda", ".usdc", ".usd"])
@pytest.mark.parametrize("layout", ["xforms", "instancer"])
def test_deterministic_bytes(synthetic, tmp_path, suffix, layout):
    a, b = tmp_path / "a" / f"shot{suffix}", tmp_path / "b" / f"shot{suffix}"
    a.parent.mkdir()
    b.parent.mkdir()
    export(synthetic, a, ExportOptions(layout=layout))
    export(synthetic, b, ExportOptions(layout=layout))
    assert a.read_bytes() == b.read_bytes()
    export(synthetic, a, ExportOptions(layout=layout))  # overwrite in place
    assert a.read_bytes() == b.read_bytes()
    files = sorted(p.relative_to(a.parent) for p in a.parent.rglob("*"))
    assert files == sorted(p.relative_to(b.parent) for p in b.parent.rglob("*"))
    assert [str(f) for f in files if f.suffix == ".png"]  # its damage textures
    for f in files:
        if (a.parent / f).is_file():
            assert (a.parent / f).read_bytes() == (b.parent / f).read_bytes(), f


def test_formats_follow_the_suffix(synthetic, tmp_path):
    from pxr import Sdf

    for suffix, text in ((".usda", True), (".usdc", False), (".usd", False)):
        path = tmp_path / f"shot{suffix}"
        export(synthetic, path)
        assert path.read_bytes().startswith(b"#usda 1.0") == text
        assert Sdf.Layer.FindOrOpen(str(path))


def test_failed_write_leaves_nothing(synthetic, tmp_path, monkeypatch):
    from blastvox.export import usd

    class Broken:
        def Export(self, name):  # noqa: N802 (pxr's name)
            Path(name).write_bytes(b"half")
            return False

    monkeypatch.setattr(usd._Writer, "build", lambda self: Broken())
    out = tmp_path / "shot.usdc"
    with pytest.raises(OutputError, match="shot.usdc: USD could not write"):
        write_usd(synthetic, out, ExportOptions())
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("layout", ["xforms", "instancer"])
@pytest.mark.parametrize("up", ["Y", "Z"])
def test_validation_passes(synthetic, wall, tmp_path, layout, up):
    for name, cache in (("synthetic", synthetic), ("wall", wall[0])):
        for suffix in (".usda", ".usdc"):
            path = tmp_path / f"{name}{suffix}"
            export(cache, path, ExportOptions(up_axis=up, layout=layout))
            assert validate_usd(path) == [], (name, suffix)


def test_validator_reports_errors(synthetic, tmp_path):
    path = tmp_path / "shot.usda"
    export(synthetic, path)
    text = path.read_text().replace('    upAxis = "Y"\n', "")
    text = text.replace('prepend apiSchemas = ["MaterialBindingAPI"]', "")
    broken = tmp_path / "broken.usda"
    broken.write_text(text)
    errors = validate_usd(broken)
    assert any("MissingUpAxisMetadata" in e for e in errors)
    assert any("MissingMaterialBindingAPI" in e for e in errors)


# ----------------------------------------------------------------------------- real cache

def test_real_simulation(wall, tmp_path):
    cache, _ = wall
    stage = _write(cache, tmp_path / "wall.usdc", up="Y")
    paths = piece_prim_paths(piece_objects(cache))
    pieces = [stage.GetPrimAtPath(path) for path in paths]
    assert all(p.IsValid() for p in pieces) and len(pieces) == cache.piece_count
    c = frame_change(cache.model.meta["up_axis"], "Y")
    f = cache.frame_count - 1
    alive = np.flatnonzero(cache.piece_end_frame >= cache.frame_count)
    moved = np.linalg.norm(cache.piece_position[f, alive] - cache.piece_position[0, alive],
                           axis=1)
    p = int(alive[np.argmax(moved)])
    assert moved.max() > 0.01  # the blast moved something
    world = UsdGeom.XformCache(Usd.TimeCode(f)).GetLocalToWorldTransform(pieces[p])
    assert np.allclose(np.array(world.ExtractTranslation()),
                       c @ cache.piece_position[f, p].astype(np.float64), atol=1e-5)
    meshes = piece_meshes(cache, "Y")
    total = sum(len(s.GetIndicesAttr().Get()) for q in range(cache.piece_count)
                for n, s in _subsets(stage, q, paths).items() if n.startswith("damage_"))
    assert total == int(meshes.damage.sum())
    vanished = np.flatnonzero(cache.piece_end_frame < cache.frame_count)
    for q in vanished[:5].tolist():
        end = int(cache.piece_end_frame[q])
        prim = UsdGeom.Imageable(pieces[q])
        assert prim.ComputeVisibility(Usd.TimeCode(end)) == "invisible"
        if end > 0:
            assert prim.ComputeVisibility(Usd.TimeCode(end - 1)) == "inherited"
    if len(cache.dust_voxel):  # volumes by default (tests/test_export_volumes.py)
        assert stage.GetPrimAtPath("/Shot/Particles/dust").GetTypeName() == "Volume"


def _cli(*args, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "blastvox", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_cli_export(wall, tmp_path):
    _, sim = wall
    out = tmp_path / "out.usdc"
    result = _cli("export", sim, "-o", out, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert out.is_file() and validate_usd(out) == []
    result = _cli("export", sim, "-o", tmp_path / "inst.usda", "--layout", "instancer",
                  "--up-axis", "Z", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    stage = Usd.Stage.Open(str(tmp_path / "inst.usda"))
    assert UsdGeom.GetStageUpAxis(stage) == "Z"
    assert stage.GetPrimAtPath("/Shot/Pieces").IsA(UsdGeom.PointInstancer)


@pytest.mark.parametrize("case", ["missing", "suffix"])
def test_cli_export_errors(wall, tmp_path, case):
    _, sim = wall
    if case == "missing":
        args, out = (tmp_path / "nope.npz", "-o", tmp_path / "out.usdc"), tmp_path / "out.usdc"
    else:
        args, out = (sim, "-o", tmp_path / "out.xyz"), tmp_path / "out.xyz"
    result = _cli("export", *args, cwd=tmp_path)
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("blastvox: error:"), result.stderr
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []
