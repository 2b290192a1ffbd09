"""Collecting output frames and events during a run, and packing the SimCache arrays.

During the run only live bodies' transforms are kept per frame (each body is
a rigid set of voxels); at the end every final piece's transform at every
frame is reconstructed from its ancestry: the ancestor alive at that frame
moves the piece rigidly, so the piece pivot's world position is
``pos_a + R(q_a) (pivot - com_a)`` with the ancestor's orientation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from blastvox.cache import quantised
from blastvox.geometry import quaternion
from blastvox.simulate.kernels import damage_levels
from blastvox.simulate.state import State


@dataclass
class Recorder:
    """Frames and events of one run."""

    n_voxels: int
    voxel_link_offsets: np.ndarray
    initial_voxel_yield: np.ndarray
    frame_steps: list[int] = field(default_factory=list)
    frame_bodies: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=list)
    shock_radius: list[np.ndarray] = field(default_factory=list)
    damage_last: np.ndarray | None = None
    damage_events: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    breaks: list[tuple[np.ndarray, float]] = field(default_factory=list)
    dust: list[tuple[np.ndarray, float, np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=list)
    destroyed_frame: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.damage_last = np.zeros(self.n_voxels, dtype=np.uint8)
        self.destroyed_frame = np.full(self.n_voxels, -1, dtype=np.int32)

    def frame(self, step: int, state: State, link_alive_count: np.ndarray,
              radii: np.ndarray) -> None:
        """Record the live bodies and the damage after ``step``."""
        n = state.n_bodies
        live = np.flatnonzero(state.bodies.live[:n])
        self.frame_steps.append(step)
        bodies = state.bodies
        self.frame_bodies.append((live, bodies.pos[live].copy(), bodies.quat[live].copy(),
                                  bodies.com[live].copy()))
        self.shock_radius.append(np.asarray(radii, dtype=np.float64).copy())
        self._damage(len(self.frame_steps) - 1, state, link_alive_count)

    def _damage(self, frame: int, state: State, link_alive_count: np.ndarray) -> None:
        level = np.empty(self.n_voxels, dtype=np.uint8)
        damage_levels(self.voxel_link_offsets, link_alive_count, state.voxels.yield_pa,
                      self.initial_voxel_yield, state.voxels.damage, state.voxels.alive, level)
        changed = np.flatnonzero(level != self.damage_last)
        if changed.size:
            self.damage_events.append((np.full(changed.size, frame, np.int32),
                                       changed.astype(np.int32), level[changed]))
            self.damage_last = level

    def link_breaks(self, links: np.ndarray, time: float) -> None:
        if links.size:
            self.breaks.append((links.astype(np.int32), time))

    def voxels_destroyed(self, voxels: np.ndarray, time: float, frame: int, state: State,
                         voxel_mass: np.ndarray) -> None:
        """Dust emitters: each destroyed voxel's body (already split off) carries its momentum."""
        if not voxels.size:
            return
        bodies = state.voxels.body[voxels]
        self.destroyed_frame[voxels] = frame
        velocity = state.bodies.lin[bodies] / state.bodies.mass[bodies][:, None]
        self.dust.append((voxels.astype(np.int32), time, voxel_mass[voxels].copy(),
                          state.bodies.pos[bodies].copy(), velocity))

    def pack(self, state: State, voxel_mass: np.ndarray, frame_time: np.ndarray) -> dict:
        """The SimCache arrays (see :mod:`blastvox.cache`)."""
        n = state.n_bodies
        final = np.flatnonzero(state.bodies.live[:n])
        # pieces numbered by their lowest voxel, so ids are stable and meaningful
        first_voxel = np.full(n, np.iinfo(np.int64).max)
        np.minimum.at(first_voxel, state.voxels.body, np.arange(self.n_voxels))
        final = final[np.argsort(first_voxel[final], kind="stable")]
        piece_of_body = np.full(n, -1, dtype=np.int64)
        piece_of_body[final] = np.arange(len(final))
        voxel_piece = piece_of_body[state.voxels.body].astype(np.int32)
        pivot = state.bodies.com[final].copy()
        positions, orientations = self._piece_transforms(state, final, pivot, n)
        end = np.full(len(final), len(frame_time), dtype=np.int32)
        dust_piece = state.bodies.dust[final]
        if dust_piece.any():
            members = np.flatnonzero(state.bodies.dust[state.voxels.body])
            end[voxel_piece[members]] = self.destroyed_frame[members]
        return {
            "frame_time": frame_time, "voxel_piece": voxel_piece, "piece_pivot": pivot,
            "piece_mass": state.bodies.mass[final].copy(),
            # float32 offsets from an origin near the scene, as the file holds them
            **dict(zip(("position_origin", "piece_position"), quantised(positions),
                       strict=True)),
            "piece_orientation": orientations.astype(np.float32),
            "piece_end_frame": end, "voxel_destroyed_frame": self.destroyed_frame,
            **self._damage_arrays(), **self._break_arrays(), **self._dust_arrays(),
            "shock_radius": np.array(self.shock_radius, dtype=np.float64).reshape(
                len(frame_time), -1),
        }

    def _piece_transforms(self, state: State, final: np.ndarray, pivot: np.ndarray, n: int):
        frames = len(self.frame_steps)
        positions = np.zeros((frames, len(final), 3))
        orientations = np.zeros((frames, len(final), 4))
        born, died, parent = state.bodies.born[:n], state.bodies.died[:n], state.bodies.parent[:n]
        slot = np.full(n, -1, dtype=np.int64)
        for f, (step, (ids, pos, quat, com)) in enumerate(zip(self.frame_steps,
                                                              self.frame_bodies, strict=True)):
            ancestor = final.copy()
            for _ in range(n):
                alive = (born[ancestor] <= step) & ((died[ancestor] < 0) | (died[ancestor] > step))
                if alive.all():
                    break
                ancestor = np.where(alive, ancestor, parent[ancestor])
            slot[ids] = np.arange(len(ids))
            row = slot[ancestor]
            q = quat[row]
            offset = pivot - com[row]
            positions[f] = pos[row] + quaternion.rotate(q, offset)
            orientations[f] = q
            slot[ids] = -1
        return positions, orientations

    def _damage_arrays(self) -> dict:
        if self.damage_events:
            f, v, x = (np.concatenate(parts) for parts in zip(*self.damage_events, strict=True))
        else:
            f, v, x = (np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0, np.uint8))
        return {"damage_frame": f, "damage_voxel": v, "damage_value": x}

    def _break_arrays(self) -> dict:
        links = [b[0] for b in self.breaks]
        times = [np.full(len(b[0]), b[1]) for b in self.breaks]
        return {"link_break_link": np.concatenate(links) if links else np.zeros(0, np.int32),
                "link_break_time": np.concatenate(times) if times else np.zeros(0)}

    def _dust_arrays(self) -> dict:
        if not self.dust:
            return {"dust_voxel": np.zeros(0, np.int32), "dust_time": np.zeros(0),
                    "dust_mass": np.zeros(0), "dust_position": np.zeros((0, 3)),
                    "dust_velocity": np.zeros((0, 3))}
        return {"dust_voxel": np.concatenate([d[0] for d in self.dust]),
                "dust_time": np.concatenate([np.full(len(d[0]), d[1]) for d in self.dust]),
                "dust_mass": np.concatenate([d[2] for d in self.dust]),
                "dust_position": np.concatenate([d[3] for d in self.dust]),
                "dust_velocity": np.concatenate([d[4] for d in self.dust])}

