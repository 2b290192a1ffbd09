"""Fire, particles and cues: behaviour, closed forms, and effects that cost nothing when off."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.materials import MaterialLibrary
from blastvox.particles import SYSTEM_NAMES, SYSTEMS, positions_at
from blastvox.simulate import engine
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

LIBRARY = MaterialLibrary.builtin().extended({
    "dry_wood": {"base": "wood", "link_yield_mean": float("inf"), "link_yield_var": 0.0,
                 "voxel_yield_mean": float("inf"), "voxel_yield_var": 0.0},
}, "test")


def wall(tmp_path: Path, material: str, extents=(3.0, 0.25, 3.0), size=0.25, ground=0.0):
    path = tmp_path / "wall.stl"
    trimesh.creation.box(extents=extents).apply_translation((0, 0, extents[2] / 2)).export(path)
    return voxelize([ObjectRequest(mesh=path, voxel_size=(size,) * 3, material=material)],
                    VoxelizeSettings(up_axis="Z", ground=ground, library=LIBRARY))


def test_fire_climbs_faster_than_it_spreads_sideways(tmp_path):
    model = wall(tmp_path, "dry_wood", extents=(6.0, 0.25, 6.0))
    settings = SimSettings(fps=24.0, duration=10.0, charges=(ChargeSpec((1e5, 0, 0), 1e-3),))
    run = engine.Run.start(model, settings)
    assert run.fire is not None  # wood burns: the run models fire
    centre = run.model.voxels.centroid
    start = int(np.argmin(np.linalg.norm(centre - [0.0, 0.0, 1.0], axis=1)))
    burning = run.state.voxels.burning
    burning[start] = True  # one voxel set alight by hand
    run.fire.burning = 1
    for step in range(1, int(10.0 / run.dt) + 1):
        engine.step(run, step, 0)
    burnt = centre[burning]
    up = burnt[:, 2].max() - centre[start, 2]
    side = np.abs(burnt[:, 0] - centre[start, 0]).max()
    assert up > 1.5 * side > 0
    down = centre[start, 2] - burnt[:, 2].min()
    assert up > 1.5 * down


def test_non_combustible_scene_skips_fire(tmp_path):
    model = wall(tmp_path, "brick")
    cache = simulate(model, SimSettings(fps=24.0, duration=0.2,
                                        charges=(ChargeSpec((0, -3.0, 1.0), 1.0),)))
    assert cache.meta["effects"]["fire"] is False
    assert np.all(cache.voxel_ignite_frame == -1)


def test_blast_sets_wood_on_fire(tmp_path):
    model = wall(tmp_path, "dry_wood")
    cache = simulate(model, SimSettings(fps=24.0, duration=0.5,
                                        charges=(ChargeSpec((0, -2.0, 1.0), 5.0),)))
    assert (cache.voxel_ignite_frame >= 0).sum() > 0
    fire = SYSTEM_NAMES.index("fire")
    assert (cache.particle_system == fire).sum() > 0


@pytest.mark.parametrize("effect", ["dust", "fireball", "shock_sphere", "camera_shake", "fire"])
def test_switching_an_effect_off_leaves_the_rest_unchanged(tmp_path, effect):
    model = wall(tmp_path, "brick")
    base = SimSettings(fps=24.0, duration=0.5, camera=((0.0, -20.0, 2.0), (0, 0, 1.0), 35.0),
                       charges=(ChargeSpec((0, -2.0, 1.0), 3.0),))
    on = simulate(model, base)
    off = simulate(model, replace(base, **{effect: False}))
    for key in ("piece_position", "piece_orientation", "voxel_piece", "link_break_link"):
        np.testing.assert_array_equal(on.arrays[key], off.arrays[key])
    systems = {"dust": ["dust"], "fireball": ["fireball"]}.get(effect, [])
    for name in SYSTEM_NAMES:
        index = SYSTEM_NAMES.index(name)
        a = on.particle_position[on.particle_system == index]
        b = off.particle_position[off.particle_system == index]
        if name in systems:
            assert len(a) > 0 and len(b) == 0
        else:
            np.testing.assert_array_equal(a, b)
    if effect == "shock_sphere":
        assert on.shock_opacity.max() > 0 and off.shock_opacity.max() == 0
    if effect == "camera_shake":
        assert np.abs(on.camera_offset).max() > 0 and np.abs(off.camera_offset).max() == 0


def test_particle_closed_form_matches_numerical_integration():
    rng = np.random.default_rng(3)
    birth = rng.uniform(0, 1, 50)
    pos = rng.normal(size=(50, 3))
    vel = rng.normal(size=(50, 3)) * 5
    system = rng.integers(0, len(SYSTEM_NAMES), 50).astype(np.uint8)
    gravity = np.array([0.0, 0.0, -9.81])
    t = 1.3
    alive, x = positions_at(birth, pos, vel, system, t, gravity)
    for i, xi in zip(alive, x, strict=True):
        spec = SYSTEMS[SYSTEM_NAMES[system[i]]]
        p, v = pos[i].copy(), vel[i].copy()
        n = 20000
        h = (t - birth[i]) / n
        for _ in range(n):  # midpoint rule on dv/dt = a - k v
            a = spec.gravity_scale * gravity - spec.drag * v
            v_mid = v + 0.5 * h * a
            p += h * v_mid
            v += h * (spec.gravity_scale * gravity - spec.drag * v_mid)
        np.testing.assert_allclose(xi, p, rtol=1e-6, atol=1e-6)
    lifetime = np.array([SYSTEMS[n].lifetime for n in SYSTEM_NAMES])[system]
    expected = np.flatnonzero((t >= birth) & (t - birth < lifetime))
    np.testing.assert_array_equal(alive, expected)


def test_particles_settle_on_the_ground_and_go_on_across_it():
    """A particle that reaches the ground stays on it: its height along up is held at
    the ground's, its motion across the ground is the closed form's; above the ground
    nothing changes, and without a ground nothing does."""
    from blastvox.particles import ground_plane

    rng = np.random.default_rng(5)
    birth = np.zeros(200)
    pos = np.column_stack([rng.normal(size=200), rng.normal(size=200),
                           rng.uniform(0.0, 3.0, 200)])
    vel = rng.normal(size=(200, 3)) * 4.0
    system = np.zeros(200, dtype=np.uint8)  # dust: falls
    gravity = np.array([0.0, 0.0, -9.81])
    ground = ground_plane(0.5, np.array([0.0, 0.0, 2.0]))  # up need not be unit
    free = positions_at(birth, pos, vel, system, 3.0, gravity)[1]
    held = positions_at(birth, pos, vel, system, 3.0, gravity, ground)[1]
    assert (free[:, 2] < 0.5).sum() > 50  # most have fallen through without a ground
    np.testing.assert_allclose(held[~(free[:, 2] >= 0.5), 2], 0.5, atol=1e-12)
    np.testing.assert_array_equal(held[:, :2], free[:, :2])
    above = free[:, 2] >= 0.5
    np.testing.assert_array_equal(held[above], free[above])
    assert ground_plane(None, np.array([0.0, 0.0, 1.0])) is None
    # in a turned frame (Z-up model into a Y-up export) the plane turns with it
    change = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    turned = positions_at(birth, pos @ change.T, vel @ change.T, system, 3.0,
                          change @ gravity, ground_plane(0.5, np.array([0.0, 0.0, 1.0]),
                                                         change))[1]
    np.testing.assert_allclose(turned, held @ change.T, atol=1e-12)


def test_camera_shakes_only_after_the_wave_arrives(tmp_path):
    model = wall(tmp_path, "brick")
    camera = ((0.0, -40.0, 2.0), (0.0, 0.0, 1.0), 35.0)
    cache = simulate(model, SimSettings(fps=100.0, duration=0.5, camera=camera,
                                        charges=(ChargeSpec((0, -2.0, 1.0), 3.0),)))
    from blastvox.blast import blast_parameters

    arrival = float(blast_parameters(np.linalg.norm(np.subtract(camera[0], (0, -2, 1))),
                                     3.0).arrival_time_s)
    before = cache.frame_time < arrival
    assert np.all(cache.camera_offset[before] == 0)
    assert np.abs(cache.camera_offset[~before]).max() > 0
