"""Debris of one-voxel pieces, and the Mazarak 1999 Table 5-1 comparison.

Shared by ``benchmarks/contacts.py`` and ``benchmarks/performance.py`` (one
implementation). A piece is a 0.2 m cube of unbreakable stone (stone's density
and restitution, infinite yields, so impacts never dust it and a run never
changes topology) voxelized to exactly one voxel, so every voxel is a boundary
voxel of a moving body. The pieces move under blastvox's own step
(:func:`blastvox.simulate.engine.step` of a :class:`~blastvox.simulate.engine.Run`,
what ``simulate()`` loops over, without recording frames) with a charge too far
away for its wave ever to arrive: gravity, ground contact and (optionally)
collisions between pieces, nothing else.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from blastvox.materials import MaterialLibrary
from blastvox.model import VoxelModel
from blastvox.simulate.engine import Run, step
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

PIECE_M = 0.2  # edge of a piece, m
DT = 1.0 / 240.0
MATERIAL = "debris"
LIBRARY = MaterialLibrary.builtin().extended({MATERIAL: {
    "base": "stone", "link_yield_mean": float("inf"), "link_yield_var": 0.0,
    "voxel_yield_mean": float("inf"), "voxel_yield_var": 0.0,
    "foundation_yield": float("inf")}}, "benchmarks")
FAR = (ChargeSpec((1e5, 0.0, 0.0), 1e-3),)  # a charge whose wave never arrives

#: Mazarak 1999 Table 5-1 (333 MHz Pentium II): frames/s by boundary voxels, for no
#: collision detection, pairwise collision detection, and detection with buckets.
PAPER_5_1 = (("1 – 10", 1, 10, "> 100", "> 100", "> 100"),
             ("10 – 100", 10, 100, "70", "20", "15"),
             ("100 – 1,000", 100, 1_000, "15", "0.25", "5"),
             ("1,000 – 10,000", 1_000, 10_000, "< 1", "< 0.017", "< 0.33"))
#: Pieces per Table 5-1 row: one inside each of the paper's bands.
TABLE_5_1_PIECES = (5, 50, 500, 5_000)
STEPS_PER_FRAME = 10  # 24 fps at 1/240 s


@dataclass(frozen=True)
class Debris:
    """Initial state of K pieces: centres (K, 3) m, orientations (K, 4) as (w, x, y, z),
    velocities (K, 3) m/s and angular velocities (K, 3) rad/s, world frame, Z up."""

    pos: np.ndarray
    quat: np.ndarray
    vel: np.ndarray
    omega: np.ndarray

    @property
    def count(self) -> int:
        return len(self.pos)


def cubes(centres: np.ndarray, directory: Path) -> VoxelModel:
    """A VoxelModel of one 0.2 m cube (one voxel, one object) at each of ``centres``.

    The centres must lie on a lattice of pitch 2 x 0.2 m or coarser so that every
    cube fills exactly one lattice cell and no two cubes touch.
    """
    import trimesh  # here, not at the top: blastvox first (see _machine's docstring)

    # a hair under the voxel, so float32 mesh files cannot stretch the lattice by a cell
    box = trimesh.creation.box(extents=(PIECE_M * (1 - 1e-3),) * 3)
    centres = np.asarray(centres, dtype=np.float64)
    k = len(centres)
    mesh = trimesh.Trimesh((box.vertices[None] + centres[:, None]).reshape(-1, 3),
                           (box.faces[None] + len(box.vertices) * np.arange(k)[:, None, None])
                           .reshape(-1, 3), process=False)
    path = directory / f"cubes{k}.stl"
    mesh.export(path)
    model = voxelize([ObjectRequest(mesh=path, voxel_size=(PIECE_M,) * 3, material=MATERIAL)],
                     VoxelizeSettings(up_axis="Z", ground=0.0, max_voxels=4_000_000,
                                      library=LIBRARY))
    if model.voxel_count != k or len(model.arrays["link_voxels"]):
        raise RuntimeError(f"{k} cubes made {model.voxel_count} voxels and "
                           f"{len(model.arrays['link_voxels'])} links; expected one voxel each")
    return model


def lattice(k: int, pitch: float = 2 * PIECE_M, layers: int = 4, z0: float = 1.0) -> np.ndarray:
    """(k, 3) rest positions: ``layers`` square layers ``pitch`` apart, from height z0."""
    side = max(1, math.ceil(math.sqrt(k / layers)))
    i = np.arange(k)
    return np.stack([pitch * (i % side), pitch * ((i // side) % side),
                     z0 + pitch * (i // (side * side))], axis=1).astype(np.float64)


def cloud(n: int, directory: Path) -> tuple[VoxelModel, Debris]:
    """n^3 pieces 0.4 m apart, at rest from 1 m up with a small random spin (seed 0)."""
    pos = lattice(n ** 3, layers=n)
    rng = np.random.default_rng(0)
    start = Debris(pos=pos, quat=np.tile([1.0, 0.0, 0.0, 0.0], (len(pos), 1)),
                   vel=np.zeros_like(pos), omega=rng.normal(0.0, 1.5, pos.shape))
    return cubes(pos, directory), start


def debris(k: int, seed: int = 0) -> Debris:
    """K pieces thrown about: 4 layers 0.5 m apart from 0.5 m up, jittered by +-5 cm,
    random orientations, horizontal speeds N(0, 1) m/s, upward U(0, 3) m/s, spin
    N(0, 5) rad/s per axis (seeded, so every engine gets the same start)."""
    rng = np.random.default_rng(seed)
    pos = lattice(k, pitch=0.5, layers=4, z0=0.5)
    pos[:, :2] += rng.uniform(-0.05, 0.05, (k, 2))
    quat = rng.normal(size=(k, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    vel = np.column_stack([rng.normal(0.0, 1.0, (k, 2)), rng.uniform(0.0, 3.0, k)])
    return Debris(pos=pos, quat=quat, vel=vel, omega=rng.normal(0.0, 5.0, (k, 3)))


def rotations(quat: np.ndarray) -> np.ndarray:
    """(K, 3, 3) rotation matrices of unit quaternions (K, 4) given as (w, x, y, z)."""
    w, x, y, z = np.asarray(quat, dtype=np.float64).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def debris_settings(collisions: bool = True, sleep: bool = True) -> SimSettings:
    """SimSettings for debris alone: no wave, no effects; ``sleep=False`` sets
    ``sleep_speed`` to 0, so no piece is ever clamped to rest or put to sleep."""
    settings = SimSettings(dt=DT, fps=24.0, duration=3600.0, charges=FAR, collisions=collisions,
                           dust=False, fireball=False, shock_sphere=False, camera_shake=False)
    return settings if sleep else replace(settings, sleep_speed=0.0)


def runner(model: VoxelModel, settings: SimSettings, start: Debris) -> Run:
    """blastvox's run of ``model`` with its pieces set to ``start``; advance it with
    :func:`blastvox.simulate.engine.step`.

    Piece b is body b (one object per cube, in voxel order); its momenta are
    m v and I_world omega. Foundations are cleared: every piece is free.
    """
    run = Run.start(model, settings)
    state, k = run.state, start.count
    if state.n_bodies != k:
        raise RuntimeError(f"{state.n_bodies} bodies for {k} pieces")
    bodies = state.bodies
    state.voxels.foundation[:] = False
    bodies.fixed[:] = False
    mass = bodies.mass[:k]
    rot = rotations(start.quat)
    inertia = rot @ bodies.inertia[:k] @ np.transpose(rot, (0, 2, 1))
    bodies.pos[:k] = start.pos
    bodies.quat[:k] = start.quat
    bodies.lin[:k] = mass[:, None] * start.vel
    bodies.ang[:k] = np.einsum("kij,kj->ki", inertia, start.omega)
    return run


def ms_per_step(model: VoxelModel, start: Debris, collisions: bool, steps: int,
                warm: int = 2) -> float:
    """Wall ms per step over ``steps`` steps, after ``warm`` untimed ones (compile / warm up)."""
    run = runner(model, debris_settings(collisions=collisions), start)
    for n in range(1, warm + 1):
        step(run, n, 0)
    started = time.perf_counter()
    for n in range(warm + 1, warm + 1 + steps):
        step(run, n, 0)
    return 1e3 * (time.perf_counter() - started) / steps


@dataclass(frozen=True)
class Row51:
    """One measured row of the Table 5-1 comparison."""

    boundary_voxels: int
    ms_collisions: float
    ms_ground_only: float


def table_5_1(directory: Path, pieces: tuple[int, ...] = TABLE_5_1_PIECES,
              steps: int = 120) -> list[Row51]:
    """Measure ms/step of :func:`debris` with collisions on and off for each piece count.

    The first ``steps`` steps (0.5 s at 1/240 s) after two warm-up steps: the
    pieces fly, collide and land, so contacts are being made throughout.
    """
    rows = []
    for k in pieces:
        model, start = cubes(lattice(k), directory), debris(k)
        rows.append(Row51(k, ms_per_step(model, start, True, steps),
                          ms_per_step(model, start, False, steps)))
    return rows


def band_of(voxels: int) -> tuple[str, str, str, str]:
    """The paper's row (band, no collisions, pairwise, buckets) that ``voxels`` falls in."""
    for band, lo, hi, *fps in PAPER_5_1:
        if lo <= voxels <= hi:
            return (band, *fps)
    return ("> 10,000", "—", "—", "—")


def print_table_5_1(rows: list[Row51]) -> None:
    """Frames/s (24 fps, 10 steps a frame) beside Mazarak 1999 Table 5-1, markdown."""
    print("| boundary voxels | paper: no collision detection | paper: without buckets | "
          "paper: with buckets | blastvox boundary voxels | blastvox: ground only | "
          "blastvox: collisions |")
    print("|---|--:|--:|--:|--:|--:|--:|")
    for row in rows:
        band, none, pairwise, buckets = band_of(row.boundary_voxels)
        print(f"| {band} | {none} | {pairwise} | {buckets} | {row.boundary_voxels:,} | "
              f"{1e3 / (STEPS_PER_FRAME * row.ms_ground_only):,.1f} | "
              f"{1e3 / (STEPS_PER_FRAME * row.ms_collisions):,.1f} |", flush=True)
