"""What pieces resting on a founded structure weigh on it (issue 33, item 1): their
contacts' push goes into the structure's stress solve
(:class:`blastvox.simulate.contact.loads.SustainedLoads`), checked against beam theory.

The scene: a plain concrete cantilever, 0.5 x 0.5 m, reaching 3.5 m out of a founded
pier, and a separate concrete block resting on its tip (its centre 3.25 m out). At the
root the extreme fibre carries M / S with M = q L^2 / 2 + W a (q the beam's weight per
metre, W the block's weight at lever arm a) and S = b h^2 / 6.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.materials import MaterialLibrary
from blastvox.simulate import engine
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

LIBRARY = MaterialLibrary.builtin().extended({
    "concrete_mean": {"base": "concrete", "link_yield_var": 0.0, "voxel_yield_var": 0.0},
}, "tests/test_sustained_loads.py")
FAR = (ChargeSpec((1e5, 0.0, 0.0), 1e-3),)  # a charge whose wave never arrives
TOP = 1.5  # m: the cantilever's top face
REACH, DEPTH, WIDTH = 3.5, 0.5, 0.5  # m
ARM = 3.25  # m: the block's centre from the root


def _box(extents, centre) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=extents).apply_translation(centre)


def _model(tmp_path: Path, block_height: float, size: float):
    pier_and_beam = trimesh.boolean.union([
        _box((1.0, WIDTH, TOP), (-0.5, 0.0, TOP / 2)),
        _box((REACH, WIDTH, DEPTH), (REACH / 2, 0.0, TOP - DEPTH / 2))])
    block = _box((0.5, 0.5, block_height), (ARM, 0.0, TOP + block_height / 2))
    requests = []
    for name, mesh in (("beam", pier_and_beam), ("block", block)):
        path = tmp_path / f"{name}.stl"
        mesh.export(path)
        requests.append(ObjectRequest(mesh=path, voxel_size=(size,) * 3,
                                      material="concrete_mean", chunk_size=0.0))
    return voxelize(requests, VoxelizeSettings(up_axis="Z", ground=0.0, library=LIBRARY))


def _run(model, dt: float, seconds: float = 1.0) -> engine.Run:
    settings = SimSettings(dt=dt, duration=seconds, charges=FAR, dust=False, fire=False,
                           fireball=False, shock_sphere=False, camera_shake=False)
    run = engine.Run.start(model, settings)
    for n in range(1, round(seconds / run.dt) + 1):
        engine.step(run, n, 0)
    return run


def _beam_theory(block_height: float) -> float:
    """The root's extreme-fibre stress over the tensile strength, by beam theory."""
    concrete = LIBRARY["concrete_mean"]
    g = 9.81
    q = concrete.density * g * WIDTH * DEPTH
    w = concrete.density * g * 0.5 * 0.5 * block_height
    moment = q * REACH ** 2 / 2 + w * ARM
    return moment / (WIDTH * DEPTH ** 2 / 6) / concrete.tensile_strength


@pytest.mark.parametrize("dt", [1 / 240, 1 / 960])
def test_a_block_resting_on_a_cantilever_loads_its_root_as_beam_theory(tmp_path, dt):
    """A 0.5 m block (0.75 x the root's cracking moment with the beam's own weight): the
    solver's peak utilisation reads beam theory within 3 %, at either step; without the
    block's load (the beam alone) it would read 0.60."""
    run = _run(_model(tmp_path, 0.5, 0.25), dt)
    expected = _beam_theory(0.5)
    assert 0.7 < expected < 0.8
    assert run.stress.peak["utilization"] == pytest.approx(expected, rel=0.03)
    assert run.stress.broken == 0


def test_a_block_too_heavy_for_the_cantilever_breaks_it(tmp_path):
    """A 2 m block (1.3 x the cracking moment): the cantilever breaks at its root and its
    tip comes down, which it never did while what rested on a founded body did not
    weigh on it."""
    assert _beam_theory(2.0) > 1.2
    model = _model(tmp_path, 2.0, 0.25)
    run = _run(model, 1 / 240)
    assert run.stress.broken > 0
    centroid = model.arrays["voxel_centroid"]
    tip = (centroid[:, 0] > 3.0) & (centroid[:, 2] < TOP)
    state = run.state
    bodies = state.bodies
    body = state.voxels.body[tip]
    assert not bodies.fixed[body].any()
    assert np.median(bodies.pos[body, 2] - bodies.com[body, 2]) < -0.5
