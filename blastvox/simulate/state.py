"""The simulator's immutable model and mutable state, as flat arrays.

Like MuJoCo's mjModel/mjData or Warp's Model/State: :class:`SimModel` is built
once from a VoxelModel and the scene and never changes during a run;
:class:`State` holds everything a step changes. Kernels take the arrays they
need explicitly; no per-voxel Python objects exist anywhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from blastvox.model import VoxelModel
from blastvox.simulate.shell import dense_grid

CONFORM_FACES = 7  # cell faces 0..5 plus the original surface


@dataclass(frozen=True)
class SimModel:
    """Static data of a run (SI units; model frame = the VoxelModel's frame).

    vertices (V, 3), voxel_vertices (N, 8): voxel corners at rest.
    voxel_mass (N,), voxel_centroid (N, 3), voxel_inertia (N, 3, 3): rest mass properties.
    link_voxels (L, 2), link_face (L,), link_midpoint (L, 3), link_direction (L, 3).
    voxel_link_offsets (N+1,), voxel_link_ids (2L,): links of each voxel (CSR).
    conform_slot (N,): row in the conform tables or -1; conform_face_area (C, 7, 3)
    vector areas (m^2, outward) and conform_face_centroid (C, 7, 3) of each face.
    voxel_restitution (N,): from the material; voxel_radius (N,): farthest corner
    from the centroid, m; voxel_contact_radius (N,): collision sphere,
    (volume)^(1/3) / 2, m. up (3,): unit up vector (axis index up_axis);
    ground_height: m along up, or None for no ground.
    link_grid, voxel_grid: :func:`blastvox.simulate.shell.dense_grid` of the link
    midpoints and voxel centroids at rest, cells of grid_cell m (about four voxels).
    """

    vertices: np.ndarray
    voxel_vertices: np.ndarray
    voxel_mass: np.ndarray
    voxel_centroid: np.ndarray
    voxel_inertia: np.ndarray
    link_voxels: np.ndarray
    link_face: np.ndarray
    link_midpoint: np.ndarray
    link_direction: np.ndarray
    voxel_link_offsets: np.ndarray
    voxel_link_ids: np.ndarray
    conform_slot: np.ndarray
    conform_face_area: np.ndarray
    conform_face_centroid: np.ndarray
    voxel_material: np.ndarray
    voxel_object: np.ndarray
    voxel_restitution: np.ndarray
    voxel_radius: np.ndarray
    voxel_contact_radius: np.ndarray
    up: np.ndarray
    up_axis: int
    ground_height: float | None
    grid_cell: float
    link_grid: tuple
    voxel_grid: tuple

    @property
    def n_voxels(self) -> int:
        return len(self.voxel_mass)

    @property
    def n_links(self) -> int:
        return len(self.link_voxels)


@dataclass
class State:
    """Everything a step changes.

    Voxels: body (N,) body slot; alive (N,); link_mask (N,) bit f = alive link
    across face f; yield_pa (N,) current voxel yield; foundation (N,) and
    foundation_pa (N,); damage (N,) Davison-Stevens damage (links' worth).
    Links: alive (L,), yield_pa (L,).
    Bodies (capacity B): see :mod:`blastvox.simulate.bodies`; plus fixed (has a
    foundation), live (exists now), dust (destroyed voxel), parent, born/died
    (step numbers; died = -1 while alive).
    """

    voxel_body: np.ndarray
    voxel_alive: np.ndarray
    voxel_link_mask: np.ndarray
    voxel_yield: np.ndarray
    voxel_foundation: np.ndarray
    voxel_foundation_yield: np.ndarray
    voxel_damage: np.ndarray
    voxel_combust: np.ndarray
    voxel_burning: np.ndarray
    link_alive: np.ndarray
    link_yield: np.ndarray
    body_mass: np.ndarray
    body_com: np.ndarray
    body_inertia: np.ndarray
    body_inv_inertia: np.ndarray
    body_radius: np.ndarray
    body_pos: np.ndarray
    body_quat: np.ndarray
    body_lin: np.ndarray
    body_ang: np.ndarray
    body_fixed: np.ndarray
    body_live: np.ndarray
    body_dust: np.ndarray
    body_asleep: np.ndarray
    body_parent: np.ndarray
    body_born: np.ndarray
    body_died: np.ndarray
    n_bodies: np.ndarray  # (1,) int64, slots used


def build_model(model: VoxelModel) -> SimModel:
    """Derive the static simulation arrays from a VoxelModel."""
    a = model.arrays
    n = model.voxel_count
    links = np.ascontiguousarray(a["link_voxels"], dtype=np.int64)
    offsets, link_ids = link_csr(links, n)
    slot = np.full(n, -1, dtype=np.int64)
    conform = a["conform_voxels"].astype(np.int64)
    slot[conform] = np.arange(len(conform))
    area, centroid = _conform_faces(a["conform_triangles"], a["conform_tag"],
                                    a["conform_offsets"])
    up = np.zeros(3)
    up[model.up_index] = 1.0
    vertices = np.ascontiguousarray(a["vertices"], dtype=np.float64)
    voxel_vertices = np.ascontiguousarray(a["voxel_vertices"], dtype=np.int64)
    voxel_centroid = np.ascontiguousarray(a["voxel_centroid"], dtype=np.float64)
    ground = model.meta.get("ground_height")
    contact_radius = 0.5 * np.cbrt(np.maximum(a["voxel_volume"], 0.0))
    grid_cell = 8.0 * float(np.median(contact_radius)) if n else 1.0
    grid_cell = grid_cell if grid_cell > 0.0 else 1.0
    link_midpoint = np.ascontiguousarray(a["link_midpoint"], dtype=np.float64)
    return SimModel(
        vertices=vertices,
        voxel_vertices=voxel_vertices,
        voxel_mass=a["voxel_mass"].astype(np.float64),
        voxel_centroid=voxel_centroid,
        voxel_inertia=np.ascontiguousarray(a["voxel_inertia"], dtype=np.float64),
        link_voxels=links, link_face=a["link_face"].astype(np.int64),
        link_midpoint=link_midpoint,
        link_direction=np.ascontiguousarray(a["link_direction"], dtype=np.float64),
        voxel_link_offsets=offsets, voxel_link_ids=link_ids,
        conform_slot=slot, conform_face_area=area, conform_face_centroid=centroid,
        voxel_material=a["voxel_material"].astype(np.int64),
        voxel_object=a["voxel_object"].astype(np.int64),
        voxel_restitution=a["material_restitution"][a["voxel_material"]].astype(np.float64),
        voxel_radius=corner_radius(vertices, voxel_vertices, voxel_centroid),
        voxel_contact_radius=contact_radius,
        up=up, up_axis=model.up_index, ground_height=None if ground is None else float(ground),
        grid_cell=grid_cell, link_grid=dense_grid(link_midpoint.reshape(-1, 3), grid_cell),
        voxel_grid=dense_grid(voxel_centroid, grid_cell))


@nb.njit(cache=True)
def link_csr(link_voxels, n_voxels):
    """Links of each voxel as CSR: offsets (N+1,) and link ids (2L,).

    A voxel lists the links it is the first end of, then those it is the
    second end of, each in link order (a counting sort, O(N + L)).
    """
    offsets = np.zeros(n_voxels + 1, dtype=np.int64)
    for link in range(link_voxels.shape[0]):
        offsets[link_voxels[link, 0] + 1] += 1
        offsets[link_voxels[link, 1] + 1] += 1
    for v in range(n_voxels):
        offsets[v + 1] += offsets[v]
    fill = offsets[:-1].copy()
    ids = np.empty(2 * link_voxels.shape[0], dtype=np.int64)
    for side in range(2):
        for link in range(link_voxels.shape[0]):
            v = link_voxels[link, side]
            ids[fill[v]] = link
            fill[v] += 1
    return offsets, ids


@nb.njit(cache=True)
def corner_radius(vertices, voxel_vertices, voxel_centroid):
    """Distance (N,) m from each voxel's centroid to its farthest corner."""
    out = np.empty(voxel_vertices.shape[0])
    for v in range(voxel_vertices.shape[0]):
        best = 0.0
        for c in range(8):
            q = voxel_vertices[v, c]
            d = ((vertices[q, 0] - voxel_centroid[v, 0]) ** 2
                 + (vertices[q, 1] - voxel_centroid[v, 1]) ** 2
                 + (vertices[q, 2] - voxel_centroid[v, 2]) ** 2)
            best = max(best, d)
        out[v] = np.sqrt(best)
    return out


def _conform_faces(triangles: np.ndarray, tags: np.ndarray, offsets: np.ndarray):
    """Per conform voxel and face (0..5 cell faces, 6 surface): vector area and centroid."""
    c = len(offsets) - 1
    area = np.zeros((c, CONFORM_FACES, 3))
    moment = np.zeros((c, CONFORM_FACES, 3))
    weight = np.zeros((c, CONFORM_FACES))
    if c == 0:
        return area, moment
    owner = np.repeat(np.arange(c), np.diff(offsets))
    vec = 0.5 * np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    mag = np.linalg.norm(vec, axis=1)
    np.add.at(area, (owner, tags.astype(np.int64)), vec)
    np.add.at(moment, (owner, tags.astype(np.int64)), mag[:, None] * triangles.mean(axis=1))
    np.add.at(weight, (owner, tags.astype(np.int64)), mag)
    centroid = moment / np.where(weight > 0, weight, 1.0)[..., None]
    return area, centroid
