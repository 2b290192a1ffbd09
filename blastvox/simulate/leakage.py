"""Rooms that an outside wave enters only through openings: their air fills through them.

A house's side wall is loaded on its outside face as the wave sweeps along it
(UFC 3-340-02's side-wall loading) and, on its inside face, only by the air of
the room behind it, which rises as the wave flows in through the windows, the
door and, once the front wall gives way, the breach. The wave does not wrap
round into a room as it wraps round a free-standing wall: treating the inside
faces as shadowed faces of the open air loaded them as much as the outside
ones, and a house's side and back walls cracked but stood (issue 34: 0-3 % of
them moved at Jarrett's "almost complete demolition" distance).

Rooms are found once, on the structure at rest (:func:`find_leaky_rooms`): the
solid of the shielding grid is closed (dilated, then eroded) by a box that
spans :data:`OPENING`, which shuts doors and windows (any opening whose
narrower side is at most OPENING); the air that the outside no longer reaches
is a room (a room must itself be wider and taller than OPENING, or the closing
fills it: a narrower space is open air here; and a grid that with the closing's
margin of OPENING all round holds more than the shielding grid's MAX_CELLS is
not searched: its rooms are open air, as before), and its openings are the faces between it and the
air those openings held. A room whose openings are shut already is sealed
(:mod:`blastvox.simulate.confinement`); a room that holds a charge is that
charge's own air; an opening wider than :data:`OPENING` is not one, the room
is outside (an open courtyard, a roofless ruin: the wave pours in).

The room's (gauge) pressure p follows quasi-steady orifice flow through each
opening (a sharp-edged orifice, discharge coefficient :data:`DISCHARGE`), the
air compressed isentropically (dp = c^2 drho):

    dp/dt = (c^2 / V) sum_f C_d A_f sign(p_f - p) sqrt(2 rho |p_f - p|)

with p_f the incident overpressure of the waves at the opening (Friedlander,
Kingery-Bulmash parameters at its distance, :mod:`blastvox.blast.face_load`, then
the negative phase, :mod:`blastvox.blast.underpressure`: the room breathes out
again),
V the room's volume. A 75 m^3 room with 2 m^2 of windows under 200 kPa fills
at about 1.3 MPa/s: some 5 kPa by the end of a 4 ms positive phase, so the
wave pushes its walls in. A wall voxel of the room that turns to dust or whose
piece has moved half a cell opens its face as a breach (:meth:`LeakyRooms.breach`).
The pressure acts on every face of a free piece whose outside lies in the
room (:func:`blastvox.simulate.confinement.gas_impulses`), and the outside
wave does not reach those faces (their cells are left out of its reach,
:func:`blastvox.simulate.clearing.exposure_of`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from blastvox.blast.face_load import face_params_at
from blastvox.jit import helper, kernel
from blastvox.simulate.boundary import boundary_of
from blastvox.simulate.confinement import (
    cell_neighbour,
    flood_outside,
    gas_impulses,
    room_walls,
)
from blastvox.simulate.shielding import MAX_CELLS

#: m: the widest opening (a door, a window) that leaves a room a room.
OPENING = 2.0
#: The discharge coefficient of a sharp-edged orifice.
DISCHARGE = 0.6
AIR_DENSITY = 1.225  # kg/m^3, ambient
SOUND_SPEED = 340.0  # m/s, ambient
#: s: the sub-step of the fill's integration (a tenth of a 1 kg charge's positive
#: phase at its shortest).
FILL_STEP = 2e-5


@dataclass
class LeakyRooms:
    """The leaky rooms of a run, and their air.

    label (X*Y*Z,) int32: the room of each shielding-grid cell (-1: none); volume
    (R,) m^3; pressure (R,) Pa (gauge, now); vents: the openings' faces, vent_room
    (F,) int64, vent_area (F,) m^2, vent_wave (F, C, 6) the waves' incident
    terms at each (:func:`incident_waves`); wall (N,)
    int32: the room each voxel walls (-1: none), walls (W,) those voxels' ids;
    breached (N,) bool: wall voxels opened already; cell: the grid's edge, m;
    openings_m2 (R,): each room's openings at rest."""

    label: np.ndarray
    volume: np.ndarray
    pressure: np.ndarray
    vent_room: np.ndarray
    vent_area: np.ndarray
    vent_wave: np.ndarray
    wall: np.ndarray
    walls: np.ndarray
    breached: np.ndarray
    cell: float
    openings_m2: np.ndarray

    @property
    def cells(self) -> np.ndarray:
        """(X*Y*Z,) bool: the cells of every room."""
        return self.label >= 0

    def breach(self, charges, state, centroid: np.ndarray, area: np.ndarray) -> None:
        """Open as vents the wall voxels that turned to dust or whose piece moved more
        than half a cell from rest (centroid (N, 3) m at rest, area (N,) m^2 each one's
        face towards its room)."""
        candidates = self.walls[~self.breached[self.walls]]
        if not candidates.size:
            return
        voxels, bodies = state.voxels, state.bodies
        body = voxels.body[candidates]
        gone = ~voxels.alive[candidates] | bodies.dust[body]
        moving = ~gone & ~bodies.fixed[body]
        if moving.any():
            v, b = candidates[moving], body[moving]
            now = np.einsum("kij,kj->ki", bodies.rot[b], centroid[v] - bodies.com[b]) \
                + bodies.pos[b]
            shifted = np.linalg.norm(now - centroid[v], axis=1) > 0.5 * self.cell
            gone[np.flatnonzero(moving)[shifted]] = True
        opened = candidates[gone]
        if not opened.size:
            return
        self.breached[opened] = True
        self.vent_room = np.concatenate([self.vent_room, self.wall[opened].astype(np.int64)])
        self.vent_area = np.concatenate([self.vent_area, area[opened]])
        self.vent_wave = np.concatenate([self.vent_wave, incident_waves(charges,
                                                                        centroid[opened])])

    def settled(self, t: float) -> bool:
        """Are the rooms at ambient pressure at t (s), after the waves have left every
        opening? Then nothing changes them any more: no breach needs looking for."""
        return not self.pressure.any() and t >= wave_span(self.vent_wave)[1]

    def step_pressure_integrals(self, t0: float, t1: float) -> np.ndarray:
        """(R,) each room's pressure integrated over [t0, t1], Pa s; advances the
        pressure to t1."""
        out = np.zeros(len(self.volume))
        if len(self.vent_room):
            _fill(self.pressure, (self.vent_room, self.vent_area, self.vent_wave),
                  wave_span(self.vent_wave), self.volume, t0, t1, out)
        return out

    def meta(self) -> list[dict]:
        """What the SimCache records: each room's volume and its openings' area at rest."""
        return [{"free_volume_m3": float(self.volume[r]),
                 "openings_m2": float(self.openings_m2[r])} for r in range(len(self.volume))]


def wave_span(vent_wave: np.ndarray) -> np.ndarray:
    """(2,) s: when the waves (:func:`incident_waves`, (F, C, 6)) reach the first
    opening and leave the last (inf, 0 without openings)."""
    if not vent_wave.size:
        return np.array([np.inf, 0.0])
    return np.array([float(vent_wave[..., 1].min()),
                     float((vent_wave[..., 1] + vent_wave[..., 2] + vent_wave[..., 5]).max())])


def incident_waves(charges, points: np.ndarray) -> np.ndarray:
    """(P, C, 6) each charge's incident wave at ``points`` (P, 3) m: peak overpressure
    (Pa), arrival (s, from the shot's start), positive duration (s), decay b, peak
    underpressure (Pa, > 0) and negative duration (s) (:mod:`blastvox.blast.underpressure`)."""
    out = np.zeros((len(points), len(charges.tnt_kg), 6))
    _waves_at(charges.table, charges.burst, charges.scale, charges.time, charges.position,
              np.ascontiguousarray(points, dtype=np.float64), out)
    return out


@kernel
def _waves_at(table, burst, scale, time, position, points, out) -> None:
    for k in range(points.shape[0]):
        for c in range(position.shape[0]):
            r = math.sqrt((points[k, 0] - position[c, 0]) ** 2
                          + (points[k, 1] - position[c, 1]) ** 2
                          + (points[k, 2] - position[c, 2]) ** 2)
            (ps, ta, td, b, _, _, _, _, _, p_neg, _,
             td_neg) = face_params_at(table, burst[c], r, scale[c])
            out[k, c, 0], out[k, c, 1], out[k, c, 2], out[k, c, 3] = ps, ta + time[c], td, b
            out[k, c, 4], out[k, c, 5] = p_neg, td_neg


@kernel
def _fill(pressure, vents, span, volume, t0, t1, out) -> None:
    """Advance the rooms' pressure (R,) Pa over [t0, t1] by the orifice flow through
    the vents ((room, area, wave) of each, see :class:`LeakyRooms`; span: their
    :func:`wave_span`), in sub-steps of at most FILL_STEP; out (R,) += the pressure's
    integral, Pa s. A sub-step never carries a room past the pressures that drive it
    (the flow's square root is stiff where they meet)."""
    vent_room, vent_area, vent_wave = vents
    first, last = span[0], span[1]
    n_rooms = volume.shape[0]
    area = np.zeros(n_rooms)
    for f in range(vent_room.shape[0]):
        area[vent_room[f]] += vent_area[f]
    quiet = True
    for r in range(n_rooms):
        quiet = quiet and pressure[r] == 0.0
    if quiet and (t1 <= first or t0 >= last):
        return
    steps = max(1, int(math.ceil((t1 - t0) / FILL_STEP)))
    h = (t1 - t0) / steps
    flow = np.zeros(n_rooms)
    lo = np.empty(n_rooms)
    hi = np.empty(n_rooms)
    for s in range(steps):
        t = t0 + (s + 0.5) * h
        for r in range(n_rooms):
            flow[r] = 0.0
            lo[r] = pressure[r]
            hi[r] = pressure[r]
        if t > last:  # the waves have passed every opening: the rooms breathe out to ambient
            for r in range(n_rooms):
                flow[r] = -area[r] * math.copysign(
                    math.sqrt(2.0 * AIR_DENSITY * abs(pressure[r])), pressure[r])
                lo[r], hi[r] = min(lo[r], 0.0), max(hi[r], 0.0)
        else:
            for f in range(vent_room.shape[0]):
                r = vent_room[f]
                outside = 0.0
                for c in range(vent_wave.shape[1]):
                    outside += _overpressure(vent_wave[f, c], t)
                drive = outside - pressure[r]
                flow[r] += vent_area[f] * math.copysign(
                    math.sqrt(2.0 * AIR_DENSITY * abs(drive)), drive)
                lo[r] = min(lo[r], outside)
                hi[r] = max(hi[r], outside)
        for r in range(n_rooms):
            new = pressure[r] + h * DISCHARGE * SOUND_SPEED ** 2 / volume[r] * flow[r]
            new = min(max(new, lo[r]), hi[r])
            out[r] += 0.5 * (pressure[r] + new) * h
            pressure[r] = new


@helper
def _overpressure(wave, t):
    """Overpressure (Pa) at t (s) of a wave (:func:`incident_waves`): the Friedlander
    positive phase, then the cubic negative lobe."""
    tau = t - wave[1]
    if tau < 0.0 or wave[2] <= 0.0:
        return 0.0
    if tau <= wave[2]:
        x = tau / wave[2]
        return wave[0] * (1.0 - x) * math.exp(-wave[3] * x)
    s = (tau - wave[2]) / wave[5] if wave[5] > 0.0 else 1.0
    if s >= 1.0:
        return 0.0
    return -wave[4] * 6.75 * s * (1.0 - s) * (1.0 - s)


def find_leaky_rooms(grid, charges, centroid: np.ndarray,
                     half_extent: Callable[[], np.ndarray], up: np.ndarray,
                     ground: float | None) -> LeakyRooms | None:
    """The leaky rooms of the shielding grid at rest (see the module), or None.

    centroid (N, 3) m: the voxels' rest centres; half_extent() (N, 3) m: their half
    boxes, to find the voxels that wall a room (asked for only if there is one); up (3,) unit
    (an axis); ground: the ground's height along up (m), or None: the grid's floor
    is open air."""
    dims = tuple(int(d) for d in grid.dims)
    cell = float(grid.cell[0])
    solid = (grid.count > 0).reshape(dims)
    if not solid.any():
        return None
    k = max(1, math.ceil(OPENING / cell / 2.0 - 1e-6))  # cells: the box's half-width
    if min(dims) < 2 * k + 3 or math.prod(d + 2 * k + 2 for d in dims) > MAX_CELLS:
        return None  # no room wider than OPENING fits, or the closing's grid is too big
    axis = int(np.argmax(np.abs(up)))
    floor_low = up[axis] > 0
    on_ground = ground is not None
    closed, padded = _closed(solid, k, axis, floor_low, on_ground)
    outside_closed, outside_open = _outside(closed), _outside(padded)
    crop = tuple(slice(k + 1, k + 1 + d) for d in dims)
    closed = closed[crop]
    rooms_air = ~closed & ~outside_closed[crop] & outside_open[crop]
    if not rooms_air.any():
        return None
    label, volumes = _label(rooms_air, charges, grid)
    if not volumes:
        return None
    vent_room, vent_area, vent_point = _vents(label.reshape(dims), closed & ~solid,
                                              outside_open[crop], grid)
    keep = np.unique(vent_room)  # a room with no opening is sealed: confinement's
    if not keep.size:
        return None
    renumber = np.full(len(volumes), -1, dtype=np.int64)
    renumber[keep] = np.arange(len(keep))
    label = np.where(label >= 0, renumber[np.maximum(label, 0)], -1).astype(np.int32)
    vent_room = renumber[vent_room]
    wall = room_walls(grid, label, centroid, half_extent())
    return LeakyRooms(label=label, volume=np.asarray(volumes)[keep],
                      pressure=np.zeros(len(keep)), vent_room=vent_room, vent_area=vent_area,
                      vent_wave=incident_waves(charges, vent_point), wall=wall,
                      walls=np.flatnonzero(wall >= 0),
                      breached=np.zeros(len(centroid), dtype=bool), cell=cell,
                      openings_m2=np.bincount(vent_room, vent_area, minlength=len(keep)))


def _closed(solid: np.ndarray, k: int, axis: int, floor_low: bool, on_ground: bool):
    """(the solid closed by a box of half-width k cells, the solid as it is), both
    padded by k + 1 cells: air all round, solid below the floor when the model stands
    on the ground."""
    padded = np.pad(solid, k + 1)
    if on_ground:
        _fill_floor(padded, k + 1, axis, floor_low)
    grown = padded
    for a in range(3):
        grown = _sweep(grown, k, a, np.logical_or)
    for a in range(3):
        grown = _sweep(grown, k, a, np.logical_and)
    return grown | padded, padded


def _fill_floor(grid: np.ndarray, pad: int, axis: int, floor_low: bool) -> None:
    index = [slice(None)] * 3
    index[axis] = slice(0, pad) if floor_low else slice(grid.shape[axis] - pad, None)
    grid[tuple(index)] = True


def _sweep(grid: np.ndarray, k: int, axis: int, op) -> np.ndarray:
    """Box filter of half-width k along ``axis``: op (or: dilate, and: erode) of the
    grid shifted by -k..k (the shifts past the edge see the edge's own cells)."""
    out = grid.copy()
    n = grid.shape[axis]
    for s in range(1, k + 1):
        if s >= n:
            break
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(0, n - s), slice(s, n)
        lo, hi = tuple(lo), tuple(hi)
        out[lo] = op(out[lo], grid[hi])
        out[hi] = op(out[hi], grid[lo])
    return out


def _outside(solid: np.ndarray) -> np.ndarray:
    """(X, Y, Z) bool: the air of ``solid`` connected to the grid's sides (a padded
    grid's floor is solid when the model stands on the ground)."""
    count = solid.astype(np.int16).ravel()
    dims = np.array(solid.shape, dtype=np.int64)
    return flood_outside(count, dims).reshape(solid.shape)


def _label(rooms_air: np.ndarray, charges, grid) -> tuple[np.ndarray, list[float]]:
    """(X*Y*Z,) int32 the connected rooms of ``rooms_air``, and their volumes (m^3); a
    room that holds a charge is left out (the wave starts in it)."""
    label, n = _components(rooms_air.ravel(), np.asarray(grid.dims, dtype=np.int64))
    holds = np.zeros(n + 1, dtype=bool)  # [-1]: no room
    for c in range(len(charges.tnt_kg)):
        idx = np.floor((charges.position[c] - grid.origin) / grid.cell[0]).astype(np.int64)
        if (idx >= 0).all() and (idx < grid.dims).all():
            holds[label[(idx[0] * grid.dims[1] + idx[1]) * grid.dims[2] + idx[2]]] = True
    keep = np.flatnonzero(~holds[:n])
    renumber = np.full(n + 1, -1, dtype=np.int32)
    renumber[keep] = np.arange(len(keep))
    label = renumber[label]
    volumes = np.bincount(label[label >= 0], minlength=len(keep)) * float(grid.cell[0]) ** 3
    return label, [float(v) for v in volumes]


@kernel
def _components(mask, dims):
    """(X*Y*Z,) int32 the 6-connected components of ``mask`` (-1 outside it), numbered
    in cell order, and how many."""
    label = np.full(mask.shape[0], -1, dtype=np.int32)
    stack = np.empty(mask.shape[0], dtype=np.int64)
    n = 0
    for seed in range(mask.shape[0]):
        if not mask[seed] or label[seed] >= 0:
            continue
        label[seed] = n
        stack[0] = seed
        top = 1
        while top > 0:
            top -= 1
            q = stack[top]
            for side in range(6):
                m = cell_neighbour(q, side, dims)
                if m >= 0 and mask[m] and label[m] < 0:
                    label[m] = n
                    stack[top] = m
                    top += 1
        n += 1
    return label, n


def _vents(label: np.ndarray, openings: np.ndarray, outside: np.ndarray, grid):
    """The faces between room cells and the air of openings that the outside reaches:
    (room (F,) int64, area (F,) m^2, centre (F, 3) m)."""
    cell = float(grid.cell[0])
    rooms, points = [], []
    gate = openings & outside
    for a in range(3):
        n = label.shape[a]
        for s in (-1, 1):
            src = [slice(None)] * 3
            dst = [slice(None)] * 3
            src[a] = slice(0, n - 1) if s == 1 else slice(1, n)
            dst[a] = slice(1, n) if s == 1 else slice(0, n - 1)
            room, door = label[tuple(src)], gate[tuple(dst)]
            hit = np.argwhere((room >= 0) & door)
            if not len(hit):
                continue
            rooms.append(room[tuple(hit.T)])
            centre = (hit + 0.5) * cell + grid.origin
            centre[:, a] = (hit[:, a] + 1) * cell + grid.origin[a]  # the shared face
            points.append(centre)
    if not rooms:
        return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, 3))
    room = np.concatenate(rooms).astype(np.int64)
    return room, np.full(len(room), cell * cell), np.concatenate(points)


def leak_phase(model, state, rooms: LeakyRooms, charges, t0: float, t1: float) -> bool:
    """Phase: the leaky rooms' air over [t0, t1] on the faces of free pieces that wall
    them (after the blast phase), their breaches opened first. Adds to loads.impulse and
    loads.angular; returns whether it added anything."""
    if rooms.settled(t0):
        return False
    voxels = model.voxels
    rooms.breach(charges, state, voxels.centroid, (2.0 * voxels.contact_radius) ** 2)
    integral = rooms.step_pressure_integrals(t0, t1)
    if not integral.any():
        return False
    gas_impulses(state.shielding, rooms.label, integral, boundary_of(model, state)[1], voxels,
                 state.voxels, state.bodies, state.loads)
    return True
