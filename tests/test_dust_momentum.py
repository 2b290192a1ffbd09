"""Dust carries its voxel's momentum in every fracture model (issue 34).

A voxel that turns to dust leaves with its body's velocity at its place and the net
impulse of the wave on its face (:func:`blastvox.simulate.fracture.fracture_wave`): the
papers' yield and damage models gave it only the first, so a wall dusted by a blast
hung in the air where it stood. Here a free glass block drifting sideways at 2 m/s is
dusted from the front: the total momentum of bodies and dust across the step that
dusts it changes by exactly what the ledger books, the dust keeps the block's drift,
and it leaves away from the charge with the wave's impulse.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from blastvox.materials import MaterialLibrary
from blastvox.simulate import engine
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

DRIFT = np.array([0.0, 2.0, 0.0])  # m/s, the block's velocity before the wave
#: each model's charge (kg TNT, m in front of the block's face at x = -0.5): one that
#: dusts the front of the block, not all of it
CHARGES = {"pressure-impulse": (10.0, 1.0), "yield": (10.0, 2.5), "damage": (10.0, 2.5)}


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    path = tmp_path_factory.mktemp("dust") / "block.stl"
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(path)
    return voxelize([ObjectRequest(mesh=path, voxel_size=(0.25,) * 3, material="glass")],
                    VoxelizeSettings(up_axis="Z", ground=None, library=MaterialLibrary.builtin()))


@pytest.mark.parametrize("fracture", sorted(CHARGES))
def test_dust_carries_its_voxels_momentum_and_the_waves(block, fracture):
    kg, standoff = CHARGES[fracture]
    charge = np.array([-0.5 - standoff, 0.0, 0.0])
    settings = SimSettings(gravity=0.0, ground=False, fps=240.0, duration=0.02, dt=1 / 960,
                           fracture=fracture, charges=(ChargeSpec(tuple(charge), kg),),
                           collisions=False, dust=True, fire=False, fireball=False)
    run = engine.Run.start(block, settings)
    state, ledger = run.state, run.ledger
    state.bodies.lin[0] = state.bodies.mass[0] * DRIFT
    ledger.book(state, "initial")  # as a step books it
    for n in range(1, 20):
        before = ledger.measure(state).copy()
        totals = {term: value.copy() for term, value in ledger.totals.items()}
        engine.step(run, n, 0)
        if not state.voxels.alive.all():
            break
    else:
        pytest.fail(f"{fracture}: nothing turned to dust")
    b, k = state.bodies, state.n_bodies
    dust = np.flatnonzero(b.dust[:k] & b.live[:k])
    rest = np.flatnonzero(~b.dust[:k] & b.live[:k])
    assert dust.size and rest.size, (dust.size, rest.size)  # the front dusted, not all
    # bodies + dust: what changed across the step is what the ledger booked for it
    after = ledger.measure(state).copy()
    booked = sum(ledger.totals[t] - totals[t] for t in ledger.totals)
    np.testing.assert_allclose(after - before, booked, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(after, b.lin[dust].sum(axis=0) + b.lin[rest].sum(axis=0),
                               rtol=1e-12, atol=1e-9)
    # the dust's momentum beyond its voxels' share of the drift is the wave's impulse,
    # booked as released to it
    extra = b.lin[dust].sum(axis=0) - b.mass[dust].sum() * DRIFT
    released = ledger.totals["released"] - totals["released"]
    np.testing.assert_allclose(extra, released, rtol=1e-9, atol=1e-9)
    # the block's drift kept (the wave and any spin nearly symmetric about its y = 0)
    assert b.lin[dust, 1].sum() / b.mass[dust].sum() == pytest.approx(DRIFT[1], rel=1e-3)
    velocity = b.lin[dust] / b.mass[dust][:, None]
    away = b.pos[dust] - charge
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    radial = np.einsum("ij,ij->i", velocity - DRIFT, away)
    assert radial.min() > 0.0, radial  # every grain pushed away from the charge
    assert extra[0] > 0.0  # and the dust as a whole leaves with the wave's impulse
