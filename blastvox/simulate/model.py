"""The simulator's immutable model: what a run reads and never changes.

Like MuJoCo's mjModel or Warp's Model: :class:`SimModel` is built once from a
VoxelModel (:func:`build_model`) and shared by every phase of every step. Its
per-voxel and per-link arrays are grouped in two NumPy-array NamedTuples,
:class:`VoxelGeometry` and :class:`LinkGeometry`, that numba kernels take as
single arguments. SI units; rest frame = the VoxelModel's frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from blastvox.blast._numeric import cbrt
from blastvox.geometry.voxel_faces import SURFACE_TAG
from blastvox.jit import helper, kernel
from blastvox.model import VoxelModel
from blastvox.simulate.members import MEMBER_NORMALS, thickness_at_rest, wave_speeds
from blastvox.simulate.shell import dense_grid
from blastvox.simulate.shielding import (
    Occupancy,
    build_occupancy,
    conform_boxes,
    corner_boxes,
    solid_boxes,
    typical_edge,
)

#: A conform voxel's loaded faces: its cell faces 0..5, then its part of the original
#: surface split by the direction its triangles face most (-x, +x, -y, +y, -z, +z):
#: 6..11. One surface face would sum to nothing where a thin wall passes through a
#: voxel, its two sides facing opposite ways.
CONFORM_FACES = SURFACE_TAG + 6


class VoxelGeometry(NamedTuple):
    """Rest geometry and mass properties of the N voxels (read-only).

    vertices (V, 3) m and corners (N, 8) int32: voxel corners at rest (rows of
    ``vertices``). mass (N,) kg, centroid (N, 3) m, inertia (N, 3, 3) kg m^2
    about the voxel centroid. restitution (N,) from the material. radius (N,):
    farthest corner from the centroid, m; contact_radius (N,): collision sphere,
    (volume)^(1/3) / 2, m; density (N,) kg/m^3 (mass over the contact cube).
    conform_slot (N,) int32: row in the conform tables or -1; conform_area (C, 7, 3)
    vector areas (m^2, outward) and conform_centroid (C, 7, 3) m of each face.
    link_offsets (N+1,) int64, link_ids (2L,) int32: the links of each voxel (CSR).
    box_half (N, 3) m and box_radius (N,) m: each voxel's contact box about its
    centroid (:func:`voxel_boxes`), half extents along the rest axes and half
    diagonal; contact_vertices (V', 3) m and contact_corners (N, 8) int32: the corners
    the ground touches, the lattice's, or the contact box's where it is not the
    voxel's cell (a cell the surface crosses, a conform cell).
    """

    vertices: np.ndarray
    corners: np.ndarray
    mass: np.ndarray
    centroid: np.ndarray
    inertia: np.ndarray
    restitution: np.ndarray
    radius: np.ndarray
    contact_radius: np.ndarray
    density: np.ndarray
    conform_slot: np.ndarray
    conform_area: np.ndarray
    conform_centroid: np.ndarray
    link_offsets: np.ndarray
    link_ids: np.ndarray
    box_half: np.ndarray
    box_radius: np.ndarray
    contact_vertices: np.ndarray
    contact_corners: np.ndarray


class LinkGeometry(NamedTuple):
    """The L links between face-adjacent voxels (read-only).

    voxels (L, 2) int32; face (L,) uint8: the face of voxels[:, 0] the link
    crosses (voxels[:, 1] sees face - 1); midpoint (L, 3) m; direction (L, 3)
    unit vector from the first voxel to the second, at rest.
    """

    voxels: np.ndarray
    face: np.ndarray
    midpoint: np.ndarray
    direction: np.ndarray


class Strength(NamedTuple):
    """Pressure-impulse strength. Of each material (M,), indexed by material (N,) int32,
    each voxel's (the model's): link_impulse and voxel_impulse, Pa s, the impulse
    asymptotes for a 0.25 m element; pi_shape, K / (P0 I0) (see
    :func:`blastvox.simulate.criteria.pi_exceeded`); crush, Pa, the material's
    crush_pressure (0 for none; a voxel's crush pressure, below which it never turns
    to dust: :func:`crush_pressures`). Of each voxel (N,): shatter_pa, Pa: for a voxel
    that is a chunk of its own (or of a model without chunks: each voxel is the
    smallest rubble), its material's crush_pressure (0 for none): failing below it,
    the voxel comes off as rubble (its links break), above it as dust. Of each link
    (L,): link_yield Pa, the model's, with yield_mean (M,) Pa, each material's
    link_yield_mean: each link's strength relative to its material
    (:func:`link_factor`), which scales its impulse asymptote as its yield; inner
    bool: the link holds together a chunk (both voxels in one chunk of
    ``voxel_chunk``) of a material that crushes (crush pressure > 0): neither the
    blast nor an impact breaks it; interface int32: the interface between two chunks
    a link crosses, numbered from 0 in order of the pair of chunk ids (-1: an inner
    link, or a model without chunks)."""

    material: np.ndarray
    link_impulse: np.ndarray
    voxel_impulse: np.ndarray
    pi_shape: np.ndarray
    crush: np.ndarray
    shatter_pa: np.ndarray
    link_yield: np.ndarray
    yield_mean: np.ndarray
    inner: np.ndarray
    interface: np.ndarray


#: Links per block of the start-up's per-link passes (link_strength_factor,
#: member_chunks): their temporaries stay a few MB whatever the model's size.
LINK_BLOCK = 1 << 18


def link_blocks(count: int):
    """Slices of ``count`` links, LINK_BLOCK at a time."""
    return (slice(start, min(start + LINK_BLOCK, count)) for start in range(0, count, LINK_BLOCK))


def link_strength_factor(arrays: dict, links=slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """The strength relative to its material of each link of ``links`` (ids, or a
    slice: all by default), and that material, int32.

    The material is the weaker of the link's two voxels (the lower link_yield_mean,
    as the voxelizer chose it); the factor is the link's yield over that material's
    mean: its random spread, the scene's strength_scale and a chunk bond's scale
    (1 where the mean is 0 or infinite). Block by block: the same values, elementwise
    (:func:`link_factor` works out one link's in a kernel)."""
    lv = np.asarray(arrays["link_voxels"]).reshape(-1, 2)[links]
    mat = np.asarray(arrays["voxel_material"])
    mean = np.asarray(arrays["material_link_yield_mean"], dtype=np.float64)
    link_yield = np.asarray(arrays["link_yield"], dtype=np.float64)[links]
    factor = np.empty(len(lv))
    weaker = np.empty(len(lv), dtype=np.int32)
    for block in link_blocks(len(lv)):
        la, lb = mat[lv[block, 0]], mat[lv[block, 1]]
        weaker[block] = np.where(mean[la] <= mean[lb], la, lb)
        with np.errstate(divide="ignore", invalid="ignore"):
            f = link_yield[block] / mean[weaker[block]]
        factor[block] = np.where(np.isfinite(f) & (f > 0.0), f, 1.0)
    return factor, weaker


@helper
def link_factor(strength, link_voxels, link) -> float:
    """Link ``link``'s strength relative to its material (``strength``: the model's
    :class:`Strength`; link_voxels (L, 2)): :func:`link_strength_factor`'s, to the bit
    (one IEEE division), without keeping a float per link."""
    la, lb = strength.material[link_voxels[link, 0]], strength.material[link_voxels[link, 1]]
    mean = strength.yield_mean[la]
    if not mean <= strength.yield_mean[lb]:
        mean = strength.yield_mean[lb]
    if mean == 0.0:  # the yield over it is infinite or undefined
        return 1.0
    f = strength.link_yield[link] / mean
    return f if math.isfinite(f) and f > 0.0 else 1.0


@dataclass(frozen=True)
class SimModel:
    """Static data of a run.

    voxels, links, strength: see :class:`VoxelGeometry`, :class:`LinkGeometry` and
    :class:`Strength`.
    material (N,), object (N,) int32: indices from the VoxelModel. up (3,): unit up
    vector (axis index up_axis); ground_height: m along up, or None for no
    ground. voxel_grid: :func:`blastvox.simulate.shell.dense_grid` of
    the voxel centroids at rest, cells of grid_cell m (about
    four voxels). rest_grid: the shielding
    :class:`~blastvox.simulate.shielding.Occupancy` of every voxel at rest (a run
    shields with a copy); thickness (N,) m: each voxel's member thickness
    (:mod:`blastvox.simulate.members`) and member_axis (N,) uint8 the unit direction,
    at rest, it is measured along (a row of
    :data:`~blastvox.simulate.members.MEMBER_NORMALS`); wave_speed (M,) m/s: each
    material's longitudinal (bar) wave speed sqrt(E / rho) (a voxel's:
    ``wave_speed[material[v]]``).
    """

    voxels: VoxelGeometry
    links: LinkGeometry
    strength: Strength
    material: np.ndarray
    object: np.ndarray
    up: np.ndarray
    up_axis: int
    ground_height: float | None
    grid_cell: float
    voxel_grid: tuple
    rest_grid: Occupancy
    thickness: np.ndarray
    member_axis: np.ndarray
    wave_speed: np.ndarray

    @property
    def n_voxels(self) -> int:
        return len(self.voxels.mass)

    @property
    def n_links(self) -> int:
        return len(self.links.voxels)

    @property
    def max_contact_radius(self) -> float:
        return float(self.voxels.contact_radius.max(initial=0.0))


def build_model(model: VoxelModel) -> SimModel:
    """Derive the static simulation arrays from a VoxelModel."""
    a = model.arrays
    n = model.voxel_count
    # index arrays stay the model's int32 (shared, not copied: 150 MB at a million voxels)
    links = np.ascontiguousarray(a["link_voxels"], dtype=np.int32)
    offsets, link_ids = link_csr(links, n)
    slot = np.full(n, -1, dtype=np.int32)
    slot[a["conform_voxels"]] = np.arange(len(a["conform_voxels"]), dtype=np.int32)
    area, centroid = _conform_faces(a["conform_triangles"], a["conform_tag"],
                                    a["conform_offsets"])
    up = np.zeros(3)
    up[model.up_index] = 1.0
    vertices = np.ascontiguousarray(a["vertices"], dtype=np.float64)
    corners = np.ascontiguousarray(a["voxel_vertices"], dtype=np.int32)
    voxel_centroid = np.ascontiguousarray(a["voxel_centroid"], dtype=np.float64)
    ground = model.meta.get("ground_height")
    contact_radius = 0.5 * cbrt(np.maximum(a["voxel_volume"], 0.0))
    grid_cell = 8.0 * float(np.median(contact_radius)) if n else 1.0
    grid_cell = grid_cell if grid_cell > 0.0 else 1.0
    link_midpoint = np.ascontiguousarray(a["link_midpoint"], dtype=np.float64)
    mass = np.ascontiguousarray(a["voxel_mass"], dtype=np.float64)
    corner = corner_boxes(vertices, corners)  # (lo, hi): both box sets start from it
    box_half, box_radius, contact_vertices, contact_corners = _contact_boxes(
        a, vertices, corners, voxel_centroid, corner)
    voxels = VoxelGeometry(
        vertices=vertices, corners=corners, mass=mass, centroid=voxel_centroid,
        inertia=np.ascontiguousarray(a["voxel_inertia"], dtype=np.float64),
        restitution=a["material_restitution"][a["voxel_material"]].astype(np.float64),
        radius=corner_radius(vertices, corners, voxel_centroid),
        contact_radius=contact_radius,
        density=mass / np.maximum((2.0 * contact_radius) ** 3, 1e-300),
        conform_slot=slot, conform_area=area, conform_centroid=centroid,
        link_offsets=offsets, link_ids=link_ids, box_half=box_half, box_radius=box_radius,
        contact_vertices=contact_vertices, contact_corners=contact_corners)
    link_geometry = LinkGeometry(
        voxels=links, face=np.ascontiguousarray(a["link_face"], dtype=np.uint8),
        midpoint=link_midpoint,
        direction=np.ascontiguousarray(a["link_direction"], dtype=np.float64))
    conform = conform_boxes(vertices, corners, a["conform_voxels"], a["conform_offsets"],
                            a["conform_triangles"])
    boxes = solid_boxes(vertices, corners, a["conform_voxels"], *conform,
                        corner=corner)  # start-up only; corner's arrays become its own
    del corner
    rest_grid = build_occupancy(
        vertices, corners, (slot, *conform), boxes, voxel_centroid,
        typical_edge(a["voxel_volume"], slot >= 0, vertices, corners))
    thickness, member_axis = thickness_at_rest(rest_grid, boxes, _solid_volume(a),
                                               voxel_centroid)
    del boxes
    return SimModel(
        voxels=voxels, links=link_geometry, strength=_strength(a, member_axis),
        material=np.ascontiguousarray(a["voxel_material"], dtype=np.int32),
        object=np.ascontiguousarray(a["voxel_object"], dtype=np.int32),
        up=up, up_axis=model.up_index, ground_height=None if ground is None else float(ground),
        grid_cell=grid_cell,
        voxel_grid=dense_grid(voxel_centroid, grid_cell), rest_grid=rest_grid,
        thickness=thickness, member_axis=member_axis, wave_speed=wave_speeds(a))


@kernel
def voxel_boxes(lo, hi, volume):
    """Contact boxes (half extents (N, 3) m, half diagonals (N,) m) of the voxels.

    A voxel's box is the box of its solid at rest (lo, hi (N, 3) m: the model's
    ``voxel_solid_box``, or its corners' box), scaled about the centroid down to the
    solid's volume (N,) m^3 where that box holds more: the voxel itself for a lattice
    cell, the solid it holds for a cell the surface crosses (a 0.25 m slab in 0.2 m
    cubes is 0.25 m thick, not 0.4, and a block resting on it does not start 0.15 m
    inside it), a box of the same volume and proportions for a jittered cell or a
    conform one cut on a slant.
    """
    n = lo.shape[0]
    half = np.empty((n, 3))
    radius = np.empty(n)
    for v in range(n):
        for a in range(3):
            half[v, a] = 0.5 * (hi[v, a] - lo[v, a])
        box = 8.0 * half[v, 0] * half[v, 1] * half[v, 2]
        if box > 0.0 and volume[v] < box * (1.0 - 1e-9):
            scale = (volume[v] / box) ** (1.0 / 3.0)
            for a in range(3):
                half[v, a] *= scale
        radius[v] = math.sqrt(half[v, 0] ** 2 + half[v, 1] ** 2 + half[v, 2] ** 2)
    return half, radius


#: A voxel's solid is box-like when it fills at least this fraction of its bounding box
#: (a wall's or slab's cell cut along a lattice plane); then its contact box is that box.
BOX_LIKE = 0.9


def _contact_boxes(a: dict, vertices: np.ndarray, corners: np.ndarray,
                   centroid: np.ndarray, corner: tuple[np.ndarray, np.ndarray]) -> tuple:
    """The voxels' contact boxes and ground corners (see :class:`VoxelGeometry`): a
    box-like solid's box (the model's ``voxel_solid_box``: a wall's cell cut along a
    lattice plane), else its corners' box, scaled to the solid's volume
    (:func:`voxel_boxes`); the 8 corners of a solid box about the centroid are the
    ground's. A cell cut on a slant (a roof's) keeps its cell's proportions: the box of
    a thin wedge, centred on its centroid, would stand out of the wedge (the house's
    roof cells sank 0.52 voxels into each other, against 0.37). corner: (lo, hi) (N, 3)
    m, the :func:`~blastvox.geometry.boxes.corner_boxes` of the voxels (read only)."""
    lo, hi = corner
    own = np.zeros(len(corners), dtype=bool)
    solid = _solid_volume(a)
    if "voxel_solid_box" in a:
        box = np.asarray(a["voxel_solid_box"], dtype=np.float64)
        own = ((box[:, 0] != lo) | (box[:, 1] != hi)).any(axis=1) & (
            solid >= BOX_LIKE * np.prod(box[:, 1] - box[:, 0], axis=1))
        if own.any():
            lo, hi = lo.copy(), hi.copy()
            lo[own], hi[own] = box[own, 0], box[own, 1]
    half, radius = voxel_boxes(lo, hi, solid)
    mine = np.flatnonzero(own)
    if not mine.size:  # cubes and cells cut along lattice planes only: the model's corners
        return half, radius, vertices, corners
    signs = np.array([[(c >> k & 1) * 2.0 - 1.0 for k in range(3)] for c in range(8)])
    extra = (centroid[mine, None, :] + signs[None] * half[mine, None, :]).reshape(-1, 3)
    contact_corners = corners.copy()
    contact_corners[mine] = len(vertices) + np.arange(8 * len(mine), dtype=np.int32
                                                      ).reshape(-1, 8)
    return (half, radius, np.ascontiguousarray(np.concatenate([vertices, extra])),
            contact_corners)


def _solid_volume(arrays: dict) -> np.ndarray:
    """(N,) m^3: the solid each voxel holds, its mass over its material's density (a
    cell the surface crosses holds less than its volume); its volume where the
    density is unknown."""
    volume = np.asarray(arrays["voxel_volume"], dtype=np.float64)
    density = arrays.get("material_density")
    if density is None:
        return volume
    rho = np.asarray(density, dtype=np.float64)[np.asarray(arrays["voxel_material"],
                                                            dtype=np.int64)]
    with np.errstate(divide="ignore", invalid="ignore"):
        solid = np.asarray(arrays["voxel_mass"], dtype=np.float64) / rho
    return np.where(np.isfinite(solid) & (solid > 0.0), solid, volume)


def _strength(arrays: dict, member_axis: np.ndarray | None = None) -> Strength:
    """P-I strength from the material table (0 where a model predates it).

    member_axis (N,): each voxel's member normal at rest, a row of MEMBER_NORMALS
    (:mod:`blastvox.simulate.members`); a chunk is cut where two members meet
    (:func:`member_chunks`)."""
    material = arrays["voxel_material"]

    def table(name: str) -> np.ndarray:  # of each material (M,)
        values = arrays.get(f"material_{name}")
        if values is None:
            return np.zeros(len(arrays["material_density"]))
        return np.ascontiguousarray(values, dtype=np.float64)

    def column(name: str) -> np.ndarray:  # of each voxel (N,)
        return np.ascontiguousarray(table(name)[material])

    crush = column("crush_pressure")
    shatter = crush.copy()
    ends = np.asarray(arrays["link_voxels"]).reshape(-1, 2)
    inner = np.zeros(len(ends), dtype=bool)
    interface = np.full(len(ends), -1, dtype=np.int32)
    if "voxel_chunk" not in arrays:
        crush[:] = 0.0
    else:
        # a voxel that is a whole chunk is the material's fragment size or larger: when
        # it fails it comes off as rubble, and only a crushing load pulverizes it
        voxel_chunk = member_chunks(np.asarray(arrays["voxel_chunk"], dtype=np.int32), ends,
                                    member_axis)
        whole = np.bincount(voxel_chunk)[voxel_chunk] < 2
        crush[whole] = 0.0
        shatter[~whole] = 0.0
        first, second = voxel_chunk[ends[:, 0]], voxel_chunk[ends[:, 1]]
        within = first == second
        inner = within & (crush > 0.0)[ends[:, 0]]
        lo, hi = first[~within].astype(np.int64), second[~within].astype(np.int64)
        pair = np.minimum(lo, hi) * (max(int(first.max(initial=0)), int(second.max(initial=0)))
                                     + 1) + np.maximum(lo, hi)  # each pair sorted
        interface[~within] = np.unique(pair, return_inverse=True)[1]
    return Strength(np.ascontiguousarray(material, dtype=np.int32), table("link_impulse"),
                    table("voxel_impulse"), table("pi_shape"), table("crush_pressure"), shatter,
                    np.ascontiguousarray(arrays["link_yield"], dtype=np.float64),
                    table("link_yield_mean"), inner, interface)


def crush_pressures(strength: Strength, chunked: bool) -> np.ndarray:
    """(N,) Pa: each voxel's crush pressure, below which it never turns to dust: its
    material's crush_pressure if it is part of a chunk of several voxels (of a model
    with chunks, ``chunked``), else 0. A voxel of a chunk of its own shatters at that
    pressure instead (strength.shatter_pa, 0 for the others): the same values as the
    start-up worked out (see :func:`_strength`), not kept for the run."""
    if not chunked:
        return np.zeros(len(strength.material))
    return np.where(strength.shatter_pa > 0.0, 0.0, strength.crush[strength.material])


#: Two voxels are of one member when their member normals are within 45 degrees.
SAME_MEMBER = math.sqrt(0.5)


def member_chunks(voxel_chunk: np.ndarray, ends: np.ndarray,
                  member_axis: np.ndarray | None) -> np.ndarray:
    """(N,) int32 chunk ids with every chunk cut where two members meet: a chunk that holds
    voxels of a wall and of the wall or slab it joins (member normals more than 45
    degrees apart; member_axis (N,): each voxel's row of MEMBER_NORMALS) becomes one
    chunk per member. Chunks are the material's fragment size, but a junction is where
    a wall breaks off from the walls that hold it (it carries the bending of both): a
    chunk across it made the front wall of a house leave with pieces of its side walls
    and slabs, which jam in line with the rest of them. ends (L, 2): the links' voxels."""
    if member_axis is None or not len(ends):
        return voxel_chunk
    from blastvox.simulate.stress import node_labels

    # of each pair of member normals (D, D), the same bits as the dot of each link's two
    # (one per pair, not per link: the (L, 3) normals of both ends took 140 MB)
    pairs = np.indices((len(MEMBER_NORMALS),) * 2).reshape(2, -1)
    same = (np.abs(np.einsum("ij,ij->i", MEMBER_NORMALS[pairs[0]], MEMBER_NORMALS[pairs[1]]))
            >= SAME_MEMBER).reshape(len(MEMBER_NORMALS), len(MEMBER_NORMALS))
    together = np.empty(len(ends), dtype=bool)
    for block in link_blocks(len(ends)):
        a, b = ends[block, 0], ends[block, 1]
        together[block] = (voxel_chunk[a] == voxel_chunk[b]) & same[member_axis[a],
                                                                    member_axis[b]]
    n = len(voxel_chunk)  # the components of the links kept, numbered as components does
    labels = np.empty(n, dtype=np.int32)
    node_labels(np.ascontiguousarray(ends, dtype=np.int32), together, np.ones(n, dtype=bool),
                np.zeros((n, 0), dtype=np.int32), labels)
    return labels


@kernel
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
    ids = np.empty(2 * link_voxels.shape[0], dtype=np.int32)
    for side in range(2):
        for link in range(link_voxels.shape[0]):
            v = link_voxels[link, side]
            ids[fill[v]] = link
            fill[v] += 1
    return offsets, ids


@kernel
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
    """Per conform voxel and face (:data:`CONFORM_FACES`: 0..5 cell faces, 6..11 the
    surface by facing): vector area (C, 12, 3) m^2 and area centroid (C, 12, 3) m."""
    c = len(offsets) - 1
    area = np.zeros((c, CONFORM_FACES, 3))
    moment = np.zeros((c, CONFORM_FACES, 3))
    weight = np.zeros((c, CONFORM_FACES))
    if c == 0:
        return area, moment
    owner = np.repeat(np.arange(c), np.diff(offsets))
    vec = 0.5 * np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    mag = np.linalg.norm(vec, axis=1)
    face = tags.astype(np.int64)
    axis = np.abs(vec).argmax(axis=1)
    facing = 2 * axis + (vec[np.arange(len(vec)), axis] > 0.0)
    face = np.where(face == SURFACE_TAG, SURFACE_TAG + facing, face)
    np.add.at(area, (owner, face), vec)
    np.add.at(moment, (owner, face), mag[:, None] * triangles.mean(axis=1))
    np.add.at(weight, (owner, face), mag)
    centroid = moment / np.where(weight > 0, weight, 1.0)[..., None]
    return area, centroid
