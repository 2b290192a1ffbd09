"""What a preview draws, frame by frame, from a SimCache (model frame, metres).

* **Pieces**: the static piece meshes of :func:`blastvox.export.pieces.piece_meshes`
  (the export's triangles, in the model's own frame) moved rigidly by each
  frame's piece transform; surface faces take the material colour, damage
  faces (inside the intact object) the material's damage colour, and a burning
  voxel chars towards black over ``CHAR_S`` seconds. Pieces are gone from their
  end frame on (voxels turned to dust).
* **Particles**: dust, fire, smoke and fireball particles at the frame time, in
  closed form (:func:`blastvox.particles.positions_at`), with a colour
  and opacity per system that fade with age.
* **Shock fronts**: one sphere per charge, radius and opacity per frame.
* **Ground**: the plane at ``meta["ground_height"]`` (none if the shot has none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blastvox.cache import SimCache
from blastvox.export.pieces import piece_meshes
from blastvox.geometry import quaternion
from blastvox.geometry.frames import gravity_vector, up_vector
from blastvox.particles import SYSTEM_NAMES, SYSTEMS, ground_plane, positions_at

CHAR_S = 3.0                             #: s for a burning voxel to char fully
CHAR_COLOR = np.array([0.02, 0.015, 0.012])  #: linear RGB of fully charred faces

#: per particle system: linear RGB (above 1 = emissive, clipped on output), opacity at
#: birth, how its radius grows over its life (x (1 + grow * age / lifetime))
PARTICLE_STYLE: dict[str, tuple[tuple[float, float, float], float, float]] = {
    "dust": ((0.36, 0.32, 0.27), 0.55, 0.5),
    "fire": ((2.0, 0.65, 0.1), 0.6, 0.3),
    "smoke": ((0.05, 0.05, 0.055), 0.3, 1.5),
    "fireball": ((1.8, 0.6, 0.12), 0.3, 0.6),
}


@dataclass(frozen=True)
class PieceFrame:
    """Pieces at one frame. Per triangle (T of all pieces): local (T, 3, 3) m and normals
    (T, 3), piece-local; piece (T,) index; albedo (T, 3) linear RGB. Per piece (P):
    rotation (P, 3, 3) and position (P, 3) m (local -> world), alive (P,) bool."""

    local: np.ndarray
    normals: np.ndarray
    piece: np.ndarray
    albedo: np.ndarray
    rotation: np.ndarray
    position: np.ndarray
    alive: np.ndarray


@dataclass(frozen=True)
class ParticleFrame:
    """Alive particles: position (K, 3) m, radius (K,) m, color (K, 3), alpha (K,)."""

    position: np.ndarray
    radius: np.ndarray
    color: np.ndarray
    alpha: np.ndarray


class PreviewScene:
    """The drawable contents of a SimCache (see the module doc), in the model frame."""

    def __init__(self, cache: SimCache) -> None:
        self.cache = cache
        up_axis = str(cache.model.meta.get("up_axis", "Y"))
        self.up = up_vector(up_axis)
        ground = cache.meta.get("ground_height", cache.model.meta.get("ground_height"))
        self.ground_height: float | None = None if ground is None else float(ground)
        self.times = np.asarray(cache.frame_time, dtype=np.float64)
        self.frame_count = len(self.times)
        self.fps = float(cache.meta.get("fps") or (1.0 / np.diff(self.times[:2])[0]
                                                   if self.frame_count > 1 else 24.0))
        meshes = piece_meshes(cache, up_axis)  # the model's own frame: no change of axes
        self.tri_local = meshes.vertices
        self.tri_normal = meshes.normals
        self.tri_voxel = meshes.voxel
        self.tri_piece = cache.voxel_piece.astype(np.int64)[meshes.voxel]
        a = cache.model.arrays
        count = int(max(len(a.get("material_color", ())), meshes.material.max(initial=-1) + 1))
        color = np.full((count, 3), 0.5)
        damage = np.full((count, 3), 0.6)
        if "material_color" in a:
            color[:len(a["material_color"])] = a["material_color"]
        if "material_damage_color" in a:
            damage[:len(a["material_damage_color"])] = a["material_damage_color"]
        self.tri_albedo = np.where(meshes.damage[:, None], damage[meshes.material],
                                   color[meshes.material])
        self.end_frame = cache.piece_end_frame.astype(np.int64)
        ignite = cache.arrays.get("voxel_ignite_frame")
        ignite_frame = (np.full(len(cache.voxel_piece), -1) if ignite is None
                        else ignite.astype(np.int64))
        self.tri_ignite = ignite_frame[self.tri_voxel]
        self.gravity = np.asarray(cache.meta.get("gravity_vector", gravity_vector(up_axis)),
                                  dtype=np.float64).reshape(3)
        self.ground = ground_plane(cache.meta.get("ground_height"), up_vector(up_axis))
        get = cache.arrays.get
        self.particle_birth = np.asarray(get("particle_birth", np.zeros(0)), dtype=np.float64)
        self.particle_position = np.asarray(get("particle_position", np.zeros((0, 3))),
                                            dtype=np.float64).reshape(-1, 3)
        self.particle_velocity = np.asarray(get("particle_velocity", np.zeros((0, 3))),
                                            dtype=np.float64).reshape(-1, 3)
        self.particle_system = np.asarray(get("particle_system", np.zeros(0)), dtype=np.int64)
        self.particle_size = np.asarray(get("particle_size", np.zeros(0)), dtype=np.float64)
        self.rest_min = a["vertices"].min(axis=0) if len(a["vertices"]) else np.zeros(3)
        self.rest_max = a["vertices"].max(axis=0) if len(a["vertices"]) else np.zeros(3)

    # -- pieces
    def pieces_at(self, frame: int) -> PieceFrame:
        """Every piece's triangles, transforms and colours at ``frame`` (gone pieces are
        flagged, not removed)."""
        albedo = self.tri_albedo
        burning = (self.tri_ignite >= 0) & (self.tri_ignite <= frame)
        if burning.any():
            age = self.times[frame] - self.times[self.tri_ignite[burning]]
            char = np.clip(age / CHAR_S, 0.0, 1.0)[:, None]
            albedo = albedo.copy()
            albedo[burning] = albedo[burning] * (1.0 - char) + CHAR_COLOR * char
        return PieceFrame(local=self.tri_local, normals=self.tri_normal, piece=self.tri_piece,
                          albedo=albedo,
                          rotation=quaternion.to_matrix(quaternion.normalize(
                              self.cache.piece_orientation[frame])),
                          position=self.cache.piece_position[frame].astype(np.float64),
                          alive=self.end_frame > frame)

    # -- particles
    def particles_at(self, frame: int) -> ParticleFrame:
        """Alive particles at ``frame``'s time, with their colour and opacity."""
        system = self.particle_system
        t = float(self.times[frame])
        alive, pos = positions_at(self.particle_birth, self.particle_position,
                                  self.particle_velocity, system, t, self.gravity,
                                  self.ground)
        sys_alive = system[alive]
        life = np.array([SYSTEMS[n].lifetime for n in SYSTEM_NAMES])[sys_alive]
        age = np.clip((t - self.particle_birth[alive]) / life, 0.0, 1.0)
        style_color = np.array([PARTICLE_STYLE[n][0] for n in SYSTEM_NAMES])
        style_alpha = np.array([PARTICLE_STYLE[n][1] for n in SYSTEM_NAMES])
        style_grow = np.array([PARTICLE_STYLE[n][2] for n in SYSTEM_NAMES])
        radius = 0.5 * self.particle_size[alive] * (
            1.0 + style_grow[sys_alive] * age)
        alpha = style_alpha[sys_alive] * (1.0 - age)
        return ParticleFrame(position=pos, radius=radius, color=style_color[sys_alive],
                             alpha=alpha)

    # -- shock fronts
    def shock_at(self, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Shock spheres at ``frame``: centres (C, 3) m, radius (C,) m, opacity (C,) 0..1."""
        c = self.cache
        centres = np.asarray(c.charge_position, dtype=np.float64).reshape(-1, 3)
        radius = np.nan_to_num(np.asarray(c.shock_radius, dtype=np.float64)
                               .reshape(self.frame_count, -1)[frame])
        opacity = c.arrays.get("shock_opacity")
        opacity = (np.ones_like(radius) if opacity is None else np.nan_to_num(
            np.asarray(opacity, dtype=np.float64).reshape(self.frame_count, -1)[frame]))
        return centres, radius, np.clip(opacity, 0.0, 1.0)

    def camera_offset(self, frame: int) -> np.ndarray:
        """Camera shake (3,) m at ``frame`` (zeros if the cache has none)."""
        offset = self.cache.arrays.get("camera_offset")
        if offset is None or len(offset) <= frame:
            return np.zeros(3)
        return np.nan_to_num(np.asarray(offset[frame], dtype=np.float64))

    # -- framing
    def action_box(self, frames: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Box (min (3,), max (3,)) m around the action in ``frames``: the intact model,
        and the 3rd to 97th percentile of the alive pieces' positions (so that a few
        far-flung fragments do not shrink everything else), above the ground."""
        lo, hi = self.rest_min.astype(np.float64), self.rest_max.astype(np.float64)
        pos = self.cache.piece_position[frames].astype(np.float64)  # (n, P, 3)
        alive = self.end_frame[None, :] > np.asarray(frames)[:, None]
        points = pos[alive]
        if len(points):
            lo = np.minimum(lo, np.percentile(points, 3, axis=0))
            hi = np.maximum(hi, np.percentile(points, 97, axis=0))
        if self.ground_height is not None:  # nothing to see below the ground
            axis = int(np.argmax(self.up))
            lo[axis] = max(lo[axis], self.ground_height)
            hi[axis] = max(hi[axis], lo[axis])
        return lo, hi

    def charge_direction(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
        """From the box centre towards the charges' mean position, or None if no charge
        lies clearly to one side of the box."""
        charges = np.asarray(self.cache.charge_position, dtype=np.float64).reshape(-1, 3)
        if not len(charges):
            return None
        d = charges.mean(axis=0) - 0.5 * (lo + hi)
        d = d - np.dot(d, self.up) * self.up
        size = float(np.linalg.norm(hi - lo))
        return d if np.linalg.norm(d) > 0.1 * size else None
