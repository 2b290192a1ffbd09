"""Stability at the extremes (issue 6): finite, bounded, unit, deterministic, or a warning.

Every scenario runs the real :func:`blastvox.simulate.engine.simulate` twice
watched by :class:`Probe`, which wraps the engine's public ``Run.start``,
``step`` and blast phase and checks the float64 state after every step (the
SimCache stores positions and orientations as float32, so the state is where
unit quaternions to 1e-9 can be seen). Each scenario asserts:

* **finite**: no NaN or Inf in any float array of either SimCache, in the
  energy of the bodies' float64 state after any step, or in any array of the
  final state (yields: no NaN; they are +inf for unbreakable materials);
* **energy**: the kinetic energy never exceeds what the blast's impulses can have
  given (:class:`Probe` derives the bound, gravity's work included);
* **unit quaternions**: | |q| - 1 | <= 1e-9 for every live body after every step;
* **determinism**: the two runs' saved ``.npz`` files are byte-identical, and
  both issue the same :class:`~blastvox.errors.SimulationLimitWarning` s, at
  most one per limit.

Where a setting is beyond what the simulator can honour
(:mod:`blastvox.simulate.limits`), the tests check that it says so once, with
the step that fixes it, and that it says nothing for the bundled examples.
"""

from __future__ import annotations

import functools
import math
import re
import subprocess
import sys
import tempfile
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from unittest import mock

import numba as nb
import numpy as np
import pytest
import trimesh
from hypothesis import example, given, settings
from hypothesis import strategies as st

from blastvox import cache as cache_module
from blastvox.blast import Z_MAX, Z_MIN, blast_parameters
from blastvox.errors import SimulationLimitWarning
from blastvox.geometry.quaternion_nb import matrix_into
from blastvox.io.npz import write_npz
from blastvox.materials import MaterialLibrary, material_table
from blastvox.model import VoxelModel
from blastvox.simulate import engine, fracture, limits, topology
from blastvox.simulate.integrate import angular_velocity
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.simulate.state import State
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

ROOT = Path(__file__).resolve().parent.parent
UNBREAKABLE = {"link_yield_mean": float("inf"), "link_yield_var": 0.0,
               "voxel_yield_mean": float("inf"), "voxel_yield_var": 0.0,
               "foundation_yield": float("inf")}
LIBRARY = MaterialLibrary.builtin().extended({"solid": {"base": "steel", **UNBREAKABLE}}, "test")
FAR = (ChargeSpec((1e5, 0.0, 0.0), 1e-3),)  # a charge whose wave never arrives
BASE = SimSettings(gravity=0.0, ground=False, fps=24.0, duration=0.5)
EXAMPLES = settings(max_examples=8, deadline=None, derandomize=True)
#: brick dusts near a charge, reinforced concrete cracks, steel breaks into fragments that fly
MATERIALS = ("brick", "reinforced_concrete", "steel")
QUAT_TOL = 1e-9
ENERGY_TOL = 1e-9  # relative: round-off of the energy sums and of the rotation's iteration


# --------------------------------------------------------------------------- models


@functools.lru_cache(maxsize=32)
def box(extents: tuple[float, float, float], size: float, material: str = "brick",
        ground: float | None = None) -> VoxelModel:
    """A voxelized box (real voxelize of a trimesh box), its lowest face at z = 0, Z up."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "box.stl"
        trimesh.creation.box(extents=extents).apply_translation(
            (0.0, 0.0, extents[2] / 2)).export(path)
        return voxelize([ObjectRequest(mesh=path, voxel_size=(size,) * 3, material=material)],
                        VoxelizeSettings(up_axis="Z", ground=ground, library=LIBRARY))


def boxes(parts: list[tuple[tuple[float, float, float], tuple[float, float, float], float]],
          material: str = "solid") -> VoxelModel:
    """One object per (extents, centre, voxel size) part: bodies of any voxel size."""
    with tempfile.TemporaryDirectory() as tmp:
        requests = []
        for i, (extents, centre, size) in enumerate(parts):
            path = Path(tmp) / f"part{i}.stl"
            trimesh.creation.box(extents=extents).apply_translation(centre).export(path)
            requests.append(ObjectRequest(mesh=path, voxel_size=(size,) * 3, material=material))
        return voxelize(requests, VoxelizeSettings(up_axis="Z", ground=None, library=LIBRARY))


def grid_model(shape: tuple[int, int, int], size: float, material: str,
               grounded: bool = False) -> VoxelModel:
    """A block of shape[0] x shape[1] x shape[2] cubes of ``size`` m, built directly as arrays.

    The VoxelModel that ``voxelize`` makes of a box, without meshes (a 1M-voxel
    block costs a few seconds instead of ~20 s): corner c = dx + 2dy + 4dz, links
    +x/+y/+z (faces 1, 3, 5) sorted by voxel pair, yields at the material's mean
    (no variance), Z up; ``grounded``: ground at z = 0 and the bottom layer on
    foundations, else no ground. ``test_grid_model_is_what_voxelize_makes`` checks
    it against voxelize.
    """
    nx, ny, nz = shape
    k, j, i = (a.ravel() for a in np.indices((nz, ny, nx)))
    ijk = np.stack([i, j, k], axis=1)  # voxel v = i + nx (j + ny k)
    n = len(ijk)
    corners = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)])
    vertex_id = np.array([1, nx + 1, (nx + 1) * (ny + 1)])  # lattice vertex (a, b, c) -> id
    voxel_vertices = (ijk @ vertex_id)[:, None] + (corners @ vertex_id)[None, :]
    vk, vj, vi = (a.ravel() for a in np.indices((nz + 1, ny + 1, nx + 1)))
    vertices = np.stack([vi, vj, vk], axis=1) * size
    table = material_table(LIBRARY, [material])
    density = float(table["material_density"][0])
    mass = density * size ** 3
    inertia = np.zeros((n, 3, 3))
    inertia[:, [0, 1, 2], [0, 1, 2]] = mass * size * size / 6.0
    boundary = np.zeros(n, dtype=np.uint8)
    ends = np.empty((n, 3, 2), dtype=np.int64)
    valid = np.empty((n, 3), dtype=bool)
    for axis, stride in enumerate((1, nx, nx * ny)):
        dims = (nx, ny, nz)[axis]
        boundary[ijk[:, axis] == 0] |= np.uint8(1 << (2 * axis))
        boundary[ijk[:, axis] == dims - 1] |= np.uint8(1 << (2 * axis + 1))
        ends[:, axis, 0] = np.arange(n)
        ends[:, axis, 1] = np.arange(n) + stride
        valid[:, axis] = ijk[:, axis] < dims - 1
    # row-major: sorted by voxel a, then by b (the strides grow with the axis)
    link_voxels = ends[valid]
    link_face = np.broadcast_to(np.array([1, 3, 5]), (n, 3))[valid]
    axis = (link_face - 1) // 2
    centroid = (ijk + 0.5) * size
    direction = np.zeros((len(link_voxels), 3))
    direction[np.arange(len(axis)), axis] = 1.0
    foundation = (ijk[:, 2] == 0) & grounded
    arrays = dict(table)
    arrays.update(
        vertices=vertices.astype(np.float64), voxel_vertices=voxel_vertices.astype(np.int32),
        voxel_ijk=ijk.astype(np.int32), voxel_object=np.zeros(n, np.int32),
        voxel_material=np.zeros(n, np.int32), voxel_volume=np.full(n, size ** 3),
        voxel_mass=np.full(n, mass), voxel_centroid=centroid, voxel_inertia=inertia,
        voxel_boundary=boundary,
        voxel_yield=np.full(n, float(table["material_voxel_yield_mean"][0])),
        voxel_foundation=foundation,
        voxel_foundation_yield=np.where(foundation, table["material_foundation_yield"][0], 0.0),
        voxel_combustibility=np.full(n, float(table["material_combustibility"][0])),
        link_voxels=link_voxels.astype(np.int32), link_face=link_face.astype(np.uint8),
        link_midpoint=centroid[link_voxels[:, 0]] + 0.5 * size * direction,
        link_direction=direction, link_area=np.full(len(link_voxels), size * size),
        link_yield=np.full(len(link_voxels), float(table["material_link_yield_mean"][0])),
        conform_voxels=np.zeros(0, np.int32), conform_offsets=np.zeros(1, np.int64),
        conform_triangles=np.zeros((0, 3, 3)), conform_tag=np.zeros(0, np.uint8))
    meta = {"up_axis": "Z", "ground_height": 0.0 if grounded else None, "seed": 0,
            "settings": {},
            "objects": [{"name": "block", "source": "synthetic", "voxel_count": n}],
            "materials": [material]}
    return VoxelModel(arrays=arrays, meta=meta)


# --------------------------------------------------------------------------- the probe


@nb.njit(cache=True)
def _mechanics(bodies, n, up_axis, gravity, floor):
    """(kinetic J, potential above ``floor`` J, lowest height above it m, worst ||q| - 1|)
    of the first n live bodies (dust excluded from the energies): |p|^2/2m + L . omega / 2
    and m g (h - floor)."""
    rot = np.empty((3, 3))
    kinetic = potential = 0.0
    lowest = np.inf
    quat = 0.0
    for b in range(n):
        if not bodies.live[b]:
            continue
        q = bodies.quat[b]
        quat = max(quat, abs(math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2) - 1.0))
        if bodies.dust[b]:
            continue
        matrix_into(q, rot)
        ang = bodies.ang[b]
        wx, wy, wz = angular_velocity(rot, bodies.inv_inertia[b], ang)
        p = bodies.lin[b]
        kinetic += 0.5 * (p[0] ** 2 + p[1] ** 2 + p[2] ** 2) / bodies.mass[b]
        kinetic += 0.5 * (wx * ang[0] + wy * ang[1] + wz * ang[2])
        height = bodies.pos[b, up_axis] - floor
        potential += gravity * bodies.mass[b] * height
        lowest = min(lowest, height)
    return kinetic, potential, lowest, quat


class Probe:
    """Checks of one run's float64 state after every step of the simulator's own step.

    :meth:`watching` wraps the engine's public pieces while a scenario runs the
    real :func:`~blastvox.simulate.engine.simulate`: :meth:`Run.start
    <blastvox.simulate.engine.Run.start>` (a probe per run, which measures the
    initial energy), :func:`~blastvox.simulate.forces.blast_phase` as the step
    calls it (:meth:`blasted`: the work the step's blast impulses can do),
    :func:`~blastvox.simulate.kernels.release_held` as fracture and split call it
    (:meth:`released`: the work of the blast impulse a fixed body's voxels held,
    handed to a piece when it breaks free or its foundation lets go) and
    :func:`~blastvox.simulate.engine.step` (:meth:`stepped`: the checks).

    **The energy bound.** Let v be the generalised velocity of all bodies and
    ||v||_M = sqrt(2 KE) its norm in the mass metric (|p|^2/m + L . I_w^-1 L summed
    over bodies). A set of impulses g applied at once (one step's blast: linear
    J_b and angular K_b per body) changes v by M^-1 g, so by the triangle
    inequality sqrt(2 KE) grows by at most ||g||_{M^-1} =
    sqrt(sum_b |J_b|^2/m_b + K_b . I_w,b^-1 K_b). The blast impulse a fixed body's
    voxels held, given to a piece when it breaks free later in the wave, is such a
    set too (counted when handed over, over the non-dust bodies it reaches).
    Nothing else in a step adds energy: splits keep every voxel's velocity
    (kinetic energy is additive over the voxels), dust leaves with its own
    energy, contacts only remove approach
    velocity or reflect it with e <= 1, drag, damping and sleep only shrink
    momenta, and the rotation conserves L . omega / 2. With gravity g and the
    ground at height h_g, E' = KE + g sum_b m_b (h_b - h_floor) (h_floor = h_g
    minus the largest voxel radius, so E' >= KE while nothing sinks) obeys the
    same inequality: semi-implicit Euler's free fall loses m g^2 dt^2 / 2 per
    step, and a step's impulse J adds J . v_n + |J|^2/2m to E', which is at most
    ||v_n|| ||J|| + ||J||^2 / 2. Hence after every step

        KE <= E' <= (sqrt(2 E'_0) + sum over steps ||g||_{M^-1})^2 / 2,

    E'_0 the initial kinetic plus potential energy. The bound is tight (equal)
    for one step's impulse on bodies at rest, so an integrator or contact that
    adds energy fails it (the papers' explicit rotation update does, 2.1x, in
    the spin scenario). A ground contact also moves the body within the step
    it acts in, so under gravity "contacts only remove energy" is a property of
    the discrete scheme that the ground scenarios check rather than assume.
    Without a ground, gravity must be 0.
    """

    runs: list[Probe] = []

    def __init__(self, run: engine.Run) -> None:
        self.run = run
        s = run.settings
        assert s.gravity == 0.0 or run.ground is not None, "gravity needs a ground to bound"
        self.floor = (run.ground - float(run.model.voxels.radius.max(initial=0.0))
                      if run.ground is not None else 0.0)
        self.quat_error = 0.0
        self.energy0 = self.energy()
        self.root = math.sqrt(2.0 * self.energy0)
        self.work = 0.0  # sum over steps of ||g||_{M^-1}, sqrt(J)
        self.energy_ratio = 0.0  # worst E' / bound
        self.energy_range = [self.energy0, self.energy0]
        self.steps = 0
        Probe.runs.append(self)

    @property
    def state(self) -> State:
        return self.run.state

    @classmethod
    @contextmanager
    def watching(cls):
        """While open, every run that :meth:`Run.start <blastvox.simulate.engine.Run.start>`
        starts has a probe (in :attr:`runs`) that checks each of its steps."""
        start, step, blast_phase = engine.Run.start, engine.step, engine.blast_phase
        release_held = fracture.release_held
        assert topology.release_held is release_held

        def probed_start(model, settings):
            run = start(model, settings)
            cls(run)
            return run

        def probed_blast_phase(model, state, charges, t0, t1, front_out):
            blast_phase(model, state, charges, t0, t1, front_out)
            cls.of(state).blasted()

        def probed_release_held(geometry, voxels, bodies, loads):
            lin, ang = bodies.lin.copy(), bodies.ang.copy()
            release_held(geometry, voxels, bodies, loads)
            (probe,) = (p for p in cls.runs if p.state.bodies is bodies)
            probe.released(bodies.lin - lin, bodies.ang - ang)

        def probed_step(run, n, frame_next):
            step(run, n, frame_next)
            cls.of(run.state).stepped(n)

        with mock.patch.object(engine.Run, "start", probed_start), \
                mock.patch.object(engine, "blast_phase", probed_blast_phase), \
                mock.patch.object(fracture, "release_held", probed_release_held), \
                mock.patch.object(topology, "release_held", probed_release_held), \
                mock.patch.object(engine, "step", probed_step):
            yield

    @classmethod
    def of(cls, state: State) -> Probe:
        """The probe of the run whose state this is."""
        (probe,) = (p for p in cls.runs if p.state is state)
        return probe

    def energy(self) -> float:
        """E' = kinetic + g sum m (h - h_floor) of the live, non-dust bodies (J); also
        updates the worst quaternion error."""
        kinetic, potential, lowest, quat = _mechanics(
            self.state.bodies, self.state.n_bodies, self.run.model.up_axis,
            float(self.run.settings.gravity), self.floor)
        if self.run.settings.gravity:
            assert lowest >= 0.0, "a body sank below the ground"
        self.quat_error = max(self.quat_error, quat)
        return kinetic + potential

    def blasted(self) -> None:
        """After the blast phase: add ||g||_{M^-1} of the step's impulses (loads.impulse,
        loads.angular) to the work."""
        n = self.state.n_bodies
        self.push(self.state.loads.impulse[:n], self.state.loads.angular[:n])

    def released(self, impulse: np.ndarray, angular: np.ndarray) -> None:
        """After held blast impulse was handed to freed pieces: the change of each body's
        linear and angular momentum, (B, 3) each; dust is outside the energy, so skipped."""
        n = self.state.n_bodies
        keep = ~self.state.bodies.dust[:n, None]
        self.push(impulse[:n] * keep, angular[:n] * keep)

    def push(self, impulse: np.ndarray, angular: np.ndarray) -> None:
        """Add ||g||_{M^-1} of a set of impulses applied at once, (n, 3) linear (N s) and
        angular about each centre of mass (N m s), to the work."""
        st = self.state
        if not (impulse.any() or angular.any()):
            return
        hit = np.flatnonzero(impulse.any(axis=1) | angular.any(axis=1))
        r, k = st.bodies.rot[hit], angular[hit]
        turn = r @ (st.bodies.inv_inertia[hit] @ (np.swapaxes(r, 1, 2) @ k[:, :, None]))
        norm2 = (np.sum(impulse[hit] ** 2, axis=1) / st.bodies.mass[hit]
                 + np.sum(turn[..., 0] * k, axis=1))
        self.work += math.sqrt(float(norm2.sum()))

    def stepped(self, step: int) -> None:
        """After a step: finite energy, within the bound."""
        self.steps += 1
        # NaN or Inf in any position, orientation, momentum, mass or inertia shows here
        energy = self.energy()
        assert math.isfinite(energy), f"step {step}: energy {energy}"
        self.energy_range = [min(self.energy_range[0], energy), max(self.energy_range[1], energy)]
        bound = 0.5 * (self.root + self.work) ** 2
        if bound > 0.0:
            self.energy_ratio = max(self.energy_ratio, energy / bound)
        else:
            assert energy == 0.0, f"step {step}: energy {energy} J from nothing"

    def check_state(self) -> None:
        """Every float array of the final state: finite (yields: not NaN; +inf is 'never')."""
        st, n = self.state, self.state.n_bodies
        bodies, voxels = st.bodies, st.voxels
        for name in ("pos", "quat", "lin", "ang", "com", "mass", "inertia", "inv_inertia",
                     "radius"):
            assert np.isfinite(getattr(bodies, name)[:n]).all(), f"non-finite bodies.{name}"
        assert np.isfinite(voxels.damage).all(), "non-finite voxels.damage"
        for name, values in (("voxels.yield_pa", voxels.yield_pa),
                             ("voxels.foundation_pa", voxels.foundation_pa),
                             ("links.yield_pa", st.links.yield_pa),
                             ("voxels.combust", voxels.combust)):
            assert not np.isnan(values).any(), f"NaN in {name}"


@dataclass
class Checked:
    """Two runs of one scenario, checked (see the module doc)."""

    cache: cache_module.SimCache
    probe: Probe
    warnings: list[str]


def cache_bytes(cache: cache_module.SimCache, whole: bool = True) -> bytes:
    """The bytes :meth:`SimCache.save` writes; ``whole=False``: the same but stored, not
    deflated, and without the embedded VoxelModel (the input, identical by construction;
    a 1M-voxel model is 450 MB)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sim.npz"
        if whole:
            cache.save(path)
        else:
            write_npz(path, cache.arrays, cache.meta, compress=False)
        return path.read_bytes()


def set_motion(motion: dict[int, tuple[tuple[float, ...], tuple[float, ...]]]):
    """Patch the initial state (:func:`engine.initial_state`, which ``Run.start`` calls):
    object -> (velocity m/s, angular velocity rad/s)."""
    original = engine.initial_state

    def initial_state(model, sm, ground=True):
        state = original(model, sm, ground=ground)
        bodies = state.bodies
        for body, (v, w) in motion.items():
            bodies.lin[body] = bodies.mass[body] * np.asarray(v, dtype=np.float64)
            bodies.ang[body] = bodies.inertia[body] @ np.asarray(w, dtype=np.float64)
        return state

    return mock.patch.object(engine, "initial_state", initial_state)


def run_twice(model: VoxelModel, settings: SimSettings, motion=None, whole: bool = True,
              energy: bool = True, runs: int = 2) -> Checked:
    """Simulate twice (``runs``) under the probe; assert finite, bounded, unit and
    deterministic (the runs' bytes equal)."""
    outputs = []
    for _ in range(runs):
        Probe.runs.clear()
        with Probe.watching(), set_motion(motion or {}), \
                warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            cache = engine.simulate(model, settings)
        (probe,) = Probe.runs
        probe.check_state()
        issued = [str(w.message) for w in caught if issubclass(w.category,
                                                                SimulationLimitWarning)]
        outputs.append((cache, probe, issued, cache_bytes(cache, whole)))
    (cache, probe, issued, data), (_, _, issued2, data2) = outputs[0], outputs[-1]
    assert probe.steps > 0
    for name, array in cache.arrays.items():
        if array.dtype.kind in "fc":
            assert np.isfinite(array).all(), f"non-finite values in cache array {name}"
    orientation = cache.piece_orientation.astype(np.float64)
    assert np.abs(np.linalg.norm(orientation, axis=-1) - 1.0).max(initial=0.0) < 1e-6
    assert probe.quat_error <= QUAT_TOL, probe.quat_error
    if energy:
        assert probe.energy_ratio <= 1.0 + ENERGY_TOL, (
            f"kinetic energy {probe.energy_ratio:.6g} x what the blast can have done")
    assert data == data2, "two runs of the same scenario differ"
    assert issued == issued2
    kinds = [re.search(r"lets fragments (\w+)", m).group(1) for m in issued]  # move, spin
    assert len(kinds) == len(set(kinds)), f"a limit warned more than once: {issued}"
    return Checked(cache, probe, issued)


def honoured(checked: Checked) -> bool:
    return not checked.warnings


# --------------------------------------------------------------------------- the builder


def test_grid_model_is_what_voxelize_makes():
    made = box((1.0, 0.75, 0.5), 0.25, material="solid")
    grid = grid_model((4, 3, 2), 0.25, "solid")
    order = np.lexsort(made.voxel_centroid.T)  # z slowest, x fastest, as the grid
    corners = made.hexahedra()[order]
    np.testing.assert_allclose(grid.hexahedra() - grid.voxel_centroid.mean(axis=0),
                               corners - made.voxel_centroid.mean(axis=0), atol=1e-12)
    for name in ("voxel_mass", "voxel_volume", "voxel_boundary"):
        np.testing.assert_allclose(grid.arrays[name], made.arrays[name][order], rtol=1e-12)
    np.testing.assert_allclose(grid.voxel_inertia, made.voxel_inertia[order], rtol=1e-9,
                               atol=1e-12)
    rank = np.argsort(order)  # voxelize's voxel -> grid voxel
    np.testing.assert_array_equal(np.sort(rank[made.link_voxels], axis=1)[
        np.lexsort(np.sort(rank[made.link_voxels], axis=1).T[::-1])], grid.link_voxels)
    assert sorted(made.link_face.tolist()) == sorted(grid.link_face.tolist())
    assert made.link_area.sum() == pytest.approx(grid.link_area.sum(), rel=1e-12)


# --------------------------------------------------------------------------- charges


def _far_enough(kg: float, distance: float) -> float:
    """Shot length (s) that lets the wave at ``distance`` m arrive and pass."""
    arrival = float(blast_parameters(distance, kg).arrival_time_s)
    return min(1.0, arrival + 0.25)


@EXAMPLES
@given(log_kg=st.floats(-3.0, 6.0), log_z=st.floats(math.log10(Z_MIN) - 2, 3.0),
       inside=st.booleans(), offset=st.tuples(*[st.floats(-0.45, 0.45)] * 3),
       material=st.sampled_from(MATERIALS))
@example(log_kg=-3.0, log_z=0.0, inside=True, offset=(0.0, 0.0, 0.0), material="steel")
@example(log_kg=6.0, log_z=0.0, inside=True, offset=(0.3, -0.2, 0.1), material="steel")
@example(log_kg=6.0, log_z=math.log10(Z_MIN), inside=False, offset=(0, 0, 0), material="brick")
@example(log_kg=-3.0, log_z=3.0, inside=False, offset=(0, 0, 0), material="steel")
def test_charge_mass_and_distance(log_kg, log_z, inside, offset, material):
    """1 g to 1 kt, from inside a voxel (distance 0) to far beyond the reference data.

    Examples: 1 g and 1 kt in a voxel, 1 kt at a face (Z = 0.0531), 1 g at Z = 1000
    (100 m). Off the box the charge is at Z W^(1/3) from its face, at most 100 m
    (so the wave arrives within the shot): Z > 40 for up to 34 kg.
    """
    model = box((1.5, 1.0, 0.5), 0.25, material=material)
    kg = 10.0 ** log_kg
    if inside:  # distance 0: in a voxel (its centre, or off it)
        centre = model.voxel_centroid[5]
        position = tuple(centre + 0.25 * np.asarray(offset))
        duration = 0.25
    else:  # off the -x face at Z, at most 100 m (the wave arrives within ~0.3 s)
        distance = min(10.0 ** log_z * kg ** (1 / 3), 100.0)
        position = (-0.75 - distance, 0.1, 0.3)
        duration = _far_enough(kg, distance + 0.75)
    charges = (ChargeSpec(position, kg),)
    checked = run_twice(model, replace(BASE, duration=duration, charges=charges))
    if not inside and distance / kg ** (1 / 3) > Z_MAX:
        assert checked.probe.work > 0.0  # the far wave did arrive and push


# --------------------------------------------------------------------------- voxel size


@EXAMPLES
@given(log_size=st.floats(-3.0, 1.0), material=st.sampled_from(MATERIALS))
@example(log_size=-3.0, material="steel")
@example(log_size=1.0, material="steel")
def test_voxel_size(log_size, material):
    """1 mm to 10 m voxels on the ground, with gravity; charge scaled with the voxel (Hopkinson).

    Speeds do not scale with the voxel, so 1 mm voxels move many voxels per step at
    dt = 1/240 s: then the motion limit warns (once), and everything else holds.
    """
    size = 10.0 ** log_size
    model = box((4 * size, 2 * size, 2 * size), size, material=material, ground=-1e-3 * size)
    kg = min(max(2.0 * (size / 0.25) ** 3, 1e-9), 1e6)
    charges = (ChargeSpec((-5 * size, 0.0, size), kg),)
    checked = run_twice(model, replace(BASE, gravity=9.81, ground=True, charges=charges))
    if size >= 0.1:
        assert honoured(checked), checked.warnings


# --------------------------------------------------------------------------- time step


@EXAMPLES
@given(log_dt=st.floats(-5.0, math.log10(1 / 24)), ground=st.booleans(),
       material=st.sampled_from(MATERIALS))
@example(log_dt=-5.0, ground=True, material="steel")
@example(log_dt=math.log10(1 / 24), ground=True, material="steel")
@example(log_dt=math.log10(1 / 24), ground=False, material="brick")
def test_time_step(log_dt, ground, material):
    """dt from 1e-5 s to 1/24 s (130x the positive phase), with ground and gravity or not.

    1 kg 0.5 m off the box: the wave arrives at 0.15 ms and its positive phase
    ends at 0.47 ms; a shot of 120 steps, at least 1 ms, covers it at any step.
    """
    dt = 10.0 ** log_dt
    fps = min(4000.0, 1.0 / dt)  # so that dt divides the frame interval
    duration = max(min(120 * dt, 1.0), 4.0 / fps)
    model = box((1.5, 1.0, 0.5), 0.25, material=material, ground=-1e-3)
    charges = (ChargeSpec((-1.25, 0.1, 0.3), 1.0),)
    run_twice(model, replace(BASE, dt=dt, fps=fps, duration=duration, ground=ground,
                             gravity=9.81 if ground else 0.0, charges=charges))


def test_impulse_does_not_depend_on_a_step_longer_than_the_blast():
    """A dt of 1/24 s, 18x the positive phase, gives the momentum of a dt of 1e-4 s."""
    model = box((1.0, 1.0, 1.0), 1.0, material="solid")
    charges = (ChargeSpec((-3.0, 0.0, 0.5), 2.0),)
    speeds = []
    for dt, fps, duration in ((1 / 24, 24.0, 1 / 24), (1e-4, 1000.0, 0.04)):  # both: whole wave
        checked = run_twice(model, replace(BASE, dt=dt, fps=fps, duration=duration,
                                           charges=charges))
        bodies = checked.probe.state.bodies
        speeds.append(bodies.lin[0] / bodies.mass[0])
    assert float(blast_parameters(2.5, 2.0).positive_duration_s) < 1 / 24 / 10
    assert speeds[0][0] > 0.01
    # equal but for the cube's own motion during the wave (5e-5 m of 2.5 m: 1e-5)
    np.testing.assert_allclose(speeds[0], speeds[1], rtol=1e-4, atol=1e-9)


# --------------------------------------------------------------------------- collisions


@pytest.mark.parametrize("mover", ["light", "heavy"])
def test_collision_with_mass_ratio_one_to_a_million(mover):
    """A 0.1 m steel cube and a 10 m one (7.85 kg and 7.85e6 kg) collide head on.

    One impulse with e = 0.5 (steel) along the line of centres: the 1-D closed
    form to 1e-9, momentum to 1e-12 (within 0.25 s, before the slow one may sleep).
    """
    model = boxes([((0.1, 0.1, 0.1), (-5.2, 0.0, 0.0), 0.1),
                   ((10.0, 10.0, 10.0), (0.0, 0.0, 0.0), 10.0)])
    m = model.voxel_mass  # one voxel per object: object = body = voxel
    assert m[1] / m[0] == pytest.approx(1e6, rel=1e-9)
    moving, other = (0, 1) if mover == "light" else (1, 0)
    v = 10.0 if mover == "light" else -1.0  # towards the other, along x
    checked = run_twice(model, replace(BASE, duration=0.25, charges=FAR),
                        motion={moving: ((v, 0.0, 0.0), (0.0, 0.0, 0.0))})
    state = checked.probe.state
    bodies = state.bodies
    assert state.n_bodies == 2 and checked.cache.meta["collisions"] >= 1
    p0 = m[moving] * v
    np.testing.assert_allclose(bodies.lin[:2].sum(axis=0), [p0, 0.0, 0.0], rtol=1e-12,
                               atol=1e-12 * abs(p0))
    e, total = 0.5, m[0] + m[1]
    expected = {other: m[moving] * (1 + e) * v / total,
                moving: (m[moving] - e * m[other]) * v / total}
    for body, speed in expected.items():
        np.testing.assert_allclose(bodies.lin[body] / m[body], [speed, 0.0, 0.0], rtol=1e-9,
                                   atol=1e-9 * abs(v))
    assert honoured(checked), checked.warnings


# --------------------------------------------------------------------------- spin


def test_body_spinning_at_a_thousand_radians_per_second_for_ten_seconds():
    """An asymmetric 3 x 2 x 1 voxel body tumbling at 1e3 rad/s (4.2 rad per step) for 10 s.

    Torque-free: L stays fixed and the kinetic energy is conserved to 1e-9 (the
    papers' explicit rotation update doubled it within the 10 s).
    """
    model = box((0.75, 0.5, 0.25), 0.25, material="solid")
    axis = np.array([0.6, 0.48, 0.64])
    omega = 1e3 * axis / np.linalg.norm(axis)
    checked = run_twice(model, replace(BASE, duration=10.0, charges=FAR),
                        motion={0: ((0.0, 0.0, 0.0), tuple(omega))})
    probe = checked.probe
    assert probe.steps == 2400
    low, high = probe.energy_range
    assert high / probe.energy0 - 1.0 <= 1e-9 and 1.0 - low / probe.energy0 <= 1e-9
    bodies = probe.state.bodies
    np.testing.assert_array_equal(bodies.ang[0], bodies.inertia[0] @ omega)
    assert honoured(checked)


# --------------------------------------------------------------------------- scale


def test_a_million_voxels():
    """A 10 m reinforced-concrete block of 100^3 voxels on its foundations, 1 t of TNT
    5 m off a face: a crater of ~50k pieces (~1.3k fragments that fall and collide, the
    rest dust), for 3 steps. (Under pressure-impulse fracture the old 1 kg at 1 m
    broke nothing, and 200 kg at 1 m mostly dusts the face: ~100 fragments.)"""
    model = grid_model((100, 100, 100), 0.1, "reinforced_concrete", grounded=True)
    assert model.voxel_count == 1_000_000
    charges = (ChargeSpec((15.0, 5.0, 5.0), 1000.0),)
    settings_ = replace(BASE, dt=1 / 240, fps=240.0, duration=3 / 240, gravity=9.81,
                        ground=True, charges=charges)
    checked = run_twice(model, settings_, whole=False, runs=1)  # determinism: smaller cases
    assert checked.probe.steps == 3
    assert checked.cache.piece_count > 1000 and checked.probe.work > 0.0


# --------------------------------------------------------------------------- warnings


MOTION = re.compile(r"^dt ([\d.e-]+) s lets fragments move ([\d.]+) voxels per step "
                    r"\(limit 0\.5; the fastest: [\d.e+-]+ kg at [\d.e+-]+ m/s\), so collisions "
                    r"can be missed; use --dt ([\d.e-]+) or "
                    r"smaller \(scene: \[simulation\] dt\)$")
SPIN = re.compile(r"^dt ([\d.e-]+) s lets fragments spin ([\d.]+) rad per step "
                  r"\(limit 40\), so their rotation no longer conserves energy; use --dt "
                  r"([\d.e-]+) or smaller \(scene: \[simulation\] dt\)$")


def _small_steel() -> tuple[VoxelModel, ChargeSpec]:
    """48 steel voxels of 2 cm and 2 kg of TNT 8 cm off a face: it tears off ~10
    fragments at up to ~20 m/s, ~9 voxels per step at dt = 1/24 s. (Steel's
    pressure-impulse strength, scaled with the element's thickness, holds 1 kg there:
    3 pieces at under 4 m/s.)"""
    return (box((0.12, 0.08, 0.04), 0.02, material="steel"),
            ChargeSpec((-0.14, 0.008, 0.024), 2.0))


def test_fast_fragments_at_a_long_step_warn_once_and_the_advice_works():
    model, charge = _small_steel()
    coarse = replace(BASE, dt=1 / 24, fps=24.0, charges=(charge,))
    checked = run_twice(model, coarse)
    (message,) = checked.warnings
    match = MOTION.match(message)
    assert match, message
    assert float(match.group(1)) == pytest.approx(1 / 24, rel=1e-2)
    assert float(match.group(2)) > 0.5
    advice = float(match.group(3))
    assert advice < 1 / 24
    fine = run_twice(model, replace(coarse, dt=advice))
    assert honoured(fine), fine.warnings


def test_spin_beyond_the_rotation_limit_warns_once_and_stays_bounded():
    """1e3 rad/s at dt = 1/24 s is 42 rad per step: beyond the 40 rad the rotation conserves.

    Then the energy is no longer conserved but stays bounded by L^2 / (2 I_min)
    (|L| is), everything stays finite and unit, and the advised step honours it.
    """
    model = box((0.75, 0.5, 0.25), 0.25, material="solid")
    omega = (0.0, 1e3, 20.0)
    coarse = replace(BASE, dt=1 / 24, fps=24.0, duration=2.0, charges=FAR)
    checked = run_twice(model, coarse, motion={0: ((0.0, 0.0, 0.0), omega)}, energy=False)
    (message,) = checked.warnings
    match = SPIN.match(message)
    assert match, message
    bodies = checked.probe.state.bodies
    ang = bodies.ang[0]
    i_min = np.linalg.eigvalsh(bodies.inertia[0]).min()
    assert checked.probe.energy_range[1] <= ang @ ang / (2 * i_min) * (1 + 1e-12)
    fine = run_twice(model, replace(coarse, dt=float(match.group(3))),
                     motion={0: ((0.0, 0.0, 0.0), omega)})
    assert honoured(fine), fine.warnings


def test_limits_measure_what_they_say():
    assert limits.motion_per_step(3.0, 10.0, 0.5, 0.01, 0.25) == pytest.approx(0.32)
    assert limits.suggested_dt(1 / 24, 3.2, 0.5) == pytest.approx(0.006)
    assert limits.suggested_dt(0.01, 1.0, 0.5) == pytest.approx(0.005)
    inv = np.diag([1.0, 2.0, 3.0])[None]
    assert limits.spin_per_step(np.array([[0.0, 3.0, 4.0]]), inv, 0.1)[0] == pytest.approx(1.0)
    assert limits.voxel_size(np.array([0.01, 0.125, 0.125, 0.2])) == pytest.approx(0.25)


def test_cli_prints_a_limit_warning_once_as_one_line(tmp_path):
    model, charge = _small_steel()
    model.save(tmp_path / "model.npz")
    where = ",".join(repr(x) for x in charge.position)
    run = subprocess.run([sys.executable, "-m", "blastvox", "simulate", "model.npz", "-o",
                          "sim.npz", "--charge", f"{where}:{charge.mass_kg!r}", "--dt",
                          repr(1 / 24), "--duration", "0.5", "--gravity", "0", "--no-ground",
                          "-q"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    lines = run.stderr.splitlines()
    assert len(lines) == 1, run.stderr
    assert lines[0].startswith("blastvox: warning: dt 0.0417 s lets fragments move "), lines[0]
    assert MOTION.match(lines[0][len("blastvox: warning: "):]), lines[0]
