"""Charges in closed rooms: their quasi-static gas pressure on the room's walls.

A room is a connected set of empty cells of the shielding grid
(:mod:`blastvox.simulate.shielding`) that the outside air cannot reach: empty
cells are flooded from the grid's faces, and a charge whose cell stays dry is
confined, in the room its own flood fills (free volume V = cells x cell^3).
The room's pressure (:func:`blastvox.blast.confinement.gas_pressure`, UFC
3-340-02 Fig 2-152 for the TNT of all its charges over V) acts from the first
detonation on every face whose outside lies in the room, pushing along -n,
while the room is closed; once a wall of it breaks it decays with the vent
time (:func:`blastvox.blast.confinement.vent_time`). Faces of pieces that leave
the room stop feeling it. Fracture sees the gas as a sustained load: an
element in line of sight of a confined charge takes max(P, P_gas) and its
impulse plus P_gas tau (see :func:`blastvox.simulate.fracture.element_load`).

Rooms are found once, when the run starts, on the structure at rest.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from blastvox.blast.confinement import gas_pressure, vent_time
from blastvox.geometry.transforms_nb import rotate_into, to_world_into
from blastvox.geometry.voxel_faces import FACE_CORNERS
from blastvox.jit import helper, kernel
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.forces import face_area_into
from blastvox.simulate.model import CONFORM_FACES
from blastvox.simulate.shielding import grid_cell


@kernel
def flood_outside(count, dims):
    """(X*Y*Z,) bool: the empty cells (count 0) connected to the grid's faces."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    wet = np.zeros(count.shape[0], dtype=np.bool_)
    stack = np.empty(count.shape[0], dtype=np.int64)
    top = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if i in (0, nx - 1) or j in (0, ny - 1) or k in (0, nz - 1):
                    q = (i * ny + j) * nz + k
                    if count[q] == 0 and not wet[q]:
                        wet[q] = True
                        stack[top] = q
                        top += 1
    return _spread(count, dims, wet, stack, top)


@kernel
def flood_from(count, dims, start):
    """(X*Y*Z,) bool: the empty cells connected to cell ``start``."""
    wet = np.zeros(count.shape[0], dtype=np.bool_)
    stack = np.empty(count.shape[0], dtype=np.int64)
    wet[start] = True
    stack[0] = start
    return _spread(count, dims, wet, stack, 1)


@kernel
def _spread(count, dims, wet, stack, top):
    while top > 0:
        top -= 1
        q = stack[top]
        for side in range(6):
            n = cell_neighbour(q, side, dims)
            if n >= 0 and count[n] == 0 and not wet[n]:
                wet[n] = True
                stack[top] = n
                top += 1
    return wet


@helper
def cell_neighbour(q, side, dims) -> int:
    """The flat index of cell q's neighbour across its face ``side`` (0..5: -x, +x, -y,
    +y, -z, +z) in a grid of ``dims`` (3,) cells, or -1 past the grid's edge."""
    ny, nz = dims[1], dims[2]
    i, rest = q // (ny * nz), q % (ny * nz)
    j, k = rest // nz, rest % nz
    step = 1 if side % 2 else -1
    axis = side // 2
    if axis == 0:
        i += step
    elif axis == 1:
        j += step
    else:
        k += step
    if i < 0 or j < 0 or k < 0 or i >= dims[0] or j >= ny or k >= nz:
        return -1
    return (i * ny + j) * nz + k


@dataclass
class Rooms:
    """The closed rooms of a run's charges.

    label (X*Y*Z,) int32: the room of each grid cell (-1: none); pressure (R,) Pa,
    volume (R,) m^3, start (R,) s (first detonation), tau (R,) s (vent time),
    vented (R,) s (when a wall broke; inf while closed); of_charge (C,) room or -1;
    wall (N,) int32: the room a voxel borders (-1: none)."""

    label: np.ndarray
    pressure: np.ndarray
    volume: np.ndarray
    start: np.ndarray
    tau: np.ndarray
    vented: np.ndarray
    of_charge: np.ndarray
    wall: np.ndarray

    @property
    def any(self) -> bool:
        return bool(len(self.pressure))

    def gas(self) -> np.ndarray:
        """(C, 2): each charge's room pressure (Pa) and its vent time (s), 0 if open."""
        out = np.zeros((len(self.of_charge), 2))
        for c, room in enumerate(self.of_charge):
            if room >= 0:
                out[c] = self.pressure[room], self.tau[room]
        return out

    def vent(self, voxels: np.ndarray, t: float) -> None:
        """Rooms walled by any of ``voxels`` (ids) open at t (s) if still closed."""
        if not voxels.size:
            return
        for room in np.unique(self.wall[voxels]):
            if room >= 0 and not math.isfinite(self.vented[room]):
                self.vented[room] = t

    def step_pressure_integrals(self, t0: float, t1: float) -> np.ndarray:
        """(R,) integral of each room's pressure over [t0, t1], Pa s (closed form)."""
        out = np.zeros(len(self.pressure))
        for room in range(len(out)):
            a, b = max(t0, self.start[room]), t1
            if b <= a:
                continue
            p, tau, vent = self.pressure[room], self.tau[room], self.vented[room]
            closed = max(min(b, vent) - a, 0.0)
            out[room] = p * closed
            lo = max(a, vent)
            if b > lo:
                out[room] += p * tau * (math.exp(-(lo - vent) / tau) - math.exp(-(b - vent) / tau))
        return out

    def meta(self) -> list[dict]:
        """What the SimCache records: each room's volume, pressure and charges."""
        return [{"charges": [int(c) for c in np.flatnonzero(self.of_charge == room)],
                 "free_volume_m3": float(self.volume[room]),
                 "gas_pressure_pa": float(self.pressure[room]),
                 "vent_time_s": float(self.tau[room]),
                 "vented_s": None if not math.isfinite(self.vented[room])
                 else float(self.vented[room])}
                for room in range(len(self.pressure))]


def find_rooms(grid, charges, centroid: np.ndarray,
               half_extent: Callable[[], np.ndarray]) -> Rooms:
    """The rooms of the charges (a :class:`~blastvox.simulate.wave.Charges`) in the grid.

    centroid (N, 3) m: each voxel's rest centre; half_extent() (N, 3) m: their half
    boxes, to find the voxels that wall a room (asked for only if there is one)."""
    cells = len(grid.count)
    label = np.full(cells, -1, dtype=np.int32)
    n_charges = len(charges.tnt_kg)
    of_charge = np.full(n_charges, -1, dtype=np.int64)
    outside = None
    volumes: list[float] = []
    for c in range(n_charges):
        q = _cell_of(grid, charges.position[c])
        if q < 0 or grid.count[q] != 0:
            continue  # outside the grid, or buried (warned about elsewhere)
        if label[q] >= 0:
            of_charge[c] = label[q]
            continue
        if outside is None:
            outside = flood_outside(grid.count, grid.dims)
        if outside[q]:
            continue
        room = flood_from(grid.count, grid.dims, q)
        label[room] = len(volumes)
        of_charge[c] = len(volumes)
        volumes.append(float(room.sum()) * float(grid.cell[0]) ** 3)
    n_rooms = len(volumes)
    volume = np.array(volumes, dtype=np.float64)
    tnt = np.array([charges.tnt_kg[of_charge == r].sum() for r in range(n_rooms)])
    start = np.array([charges.time[of_charge == r].min() for r in range(n_rooms)])
    return Rooms(label=label,
                 pressure=np.array([gas_pressure(w, v) for w, v in zip(tnt, volume,
                                                                       strict=True)]),
                 volume=volume, start=start,
                 tau=np.array([vent_time(v) for v in volume]),
                 vented=np.full(n_rooms, np.inf), of_charge=of_charge,
                 wall=room_walls(grid, label, centroid, half_extent()) if n_rooms else np.full(
                     len(centroid), -1, dtype=np.int32))


def wave_reach(grid, charge_pos: np.ndarray) -> np.ndarray:
    """(C, X*Y*Z) bool: the cells of the shielding grid each charge's wave reaches
    through air. A charge in the open reaches the empty cells flooded from the grid's
    faces (not a sealed room's; outside the grid is the open air); a charge in a room,
    that room's cells; a charge buried in solid, every cell. (Occupied cells count as
    reached: what a face pressed against solid takes is its line of sight's business.)"""
    reach = np.ones((len(charge_pos), len(grid.count)), dtype=np.bool_)
    solid = grid.count != 0
    outside = None
    for c in range(len(charge_pos)):
        q = _cell_of(grid, charge_pos[c])
        if q >= 0 and solid[q]:
            continue
        if outside is None:
            outside = flood_outside(grid.count, grid.dims)
        in_open = q < 0 or outside[q]  # outside the grid is the open air
        reach[c] = (outside if in_open else flood_from(grid.count, grid.dims, q)) | solid
    return reach


def _cell_of(grid, point: np.ndarray) -> int:
    idx = np.floor((np.asarray(point) - grid.origin) / grid.cell[0]).astype(np.int64)
    if (idx < 0).any() or (idx >= grid.dims).any():
        return -1
    return int((idx[0] * grid.dims[1] + idx[1]) * grid.dims[2] + idx[2])


def room_walls(grid, label: np.ndarray, centroid: np.ndarray, half: np.ndarray) -> np.ndarray:
    """(N,) the room next to each voxel across one of its six faces, or -1."""
    out = np.full(len(centroid), -1, dtype=np.int32)
    for axis in range(3):
        for sign in (-1.0, 1.0):
            probe = centroid.copy()
            probe[:, axis] += sign * (half[:, axis] + 0.51 * grid.cell[0])
            idx = np.floor((probe - grid.origin) / grid.cell[0]).astype(np.int64)
            inside = ((idx >= 0) & (idx < grid.dims)).all(axis=1)
            q = (idx[:, 0] * grid.dims[1] + idx[:, 1]) * grid.dims[2] + idx[:, 2]
            room = np.where(inside, label[np.where(inside, q, 0)], -1)
            out = np.where((out < 0) & (room >= 0), room, out)
    return out.astype(np.int32)


@kernel
def gas_impulses(grid, label, integral, boundary, geometry, voxels, bodies, loads) -> None:
    """Add each room's pressure integral over the step (``integral`` (R,) Pa s) on every
    exposed face of a free body whose outside lies in the room (cells ``label``), to
    loads.impulse and loads.angular (B, 3): -j A n at the face's centre."""
    vertices, corners = geometry.vertices, geometry.corners
    conform_slot, conform_area = geometry.conform_slot, geometry.conform_area
    conform_centroid = geometry.conform_centroid
    cell = grid.cell[0]
    area = np.empty(3)
    rest = np.empty(3)
    point = np.empty(3)
    corner = np.empty(3)
    for k in range(boundary.shape[0]):
        v = boundary[k]
        b = voxels.body[v]
        if not voxels.alive[v] or not bodies.live[b] or bodies.dust[b] or bodies.fixed[b]:
            continue
        exposed = (~voxels.link_mask[v]) & 0x3F
        slot = conform_slot[v]
        rot, pos, com = bodies.rot[b], bodies.pos[b], bodies.com[b]
        for f in range(CONFORM_FACES):
            if f < 6 and not (exposed >> f) & 1:
                continue
            if slot >= 0:
                to_world_into(rot, pos, com, conform_centroid[slot, f], point)
                rotate_into(rot, conform_area[slot, f], area)
            elif f < 6:
                face_area_into(vertices, corners, v, f, rest)
                rotate_into(rot, rest, area)
                point[:] = 0.0
                for n in range(4):
                    to_world_into(rot, pos, com, vertices[corners[v, FACE_CORNERS[f, n]]], corner)
                    point += 0.25 * corner
            else:
                continue
            norm = math.sqrt(area[0] ** 2 + area[1] ** 2 + area[2] ** 2)
            if norm <= 0.0:
                continue
            q = grid_cell(grid, point[0] + 0.51 * cell * area[0] / norm,
                         point[1] + 0.51 * cell * area[1] / norm,
                         point[2] + 0.51 * cell * area[2] / norm)
            if q < 0 or label[q] < 0:
                continue
            j = integral[label[q]]
            fx, fy, fz = -j * area[0], -j * area[1], -j * area[2]
            loads.impulse[b, 0] += fx
            loads.impulse[b, 1] += fy
            loads.impulse[b, 2] += fz
            dx, dy, dz = point[0] - pos[0], point[1] - pos[1], point[2] - pos[2]
            loads.angular[b, 0] += dy * fz - dz * fy
            loads.angular[b, 1] += dz * fx - dx * fz
            loads.angular[b, 2] += dx * fy - dy * fx


def gas_phase(model, state, rooms: Rooms, t0: float, t1: float) -> None:
    """Phase: the rooms' gas pressure over [t0, t1] on the faces that wall them.

    Reads the rooms, the bodies' poses and the boundary; adds to loads.impulse and
    loads.angular (after :func:`blastvox.simulate.forces.blast_phase` zeroed them)."""
    integral = rooms.step_pressure_integrals(t0, t1)
    if not integral.any():
        return
    gas_impulses(state.shielding, rooms.label, integral, boundary_of(model, state)[1],
                 model.voxels, state.voxels, state.bodies, state.loads)
