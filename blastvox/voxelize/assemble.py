"""The last step of voxelize: the inputs' lattices into one VoxelModel.

Across inputs: split into objects (connected components), assign materials and region
rules, perturb yield limits from the seed, tag foundation voxels, and pack the flat
arrays. The model's arrays are allocated once at their final size and type and filled
lattice by lattice; each lattice is dropped as soon as it is copied (:func:`assemble`
consumes its list), so the model is held about once, not as the lattices, their
concatenation and its typed copies at once (1 M voxels of the city block: 2.0 GB at the
peak before, see docs/benchmarks.md).
"""

from __future__ import annotations

import ctypes
import functools
import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blastvox import __version__
from blastvox.materials import MaterialLibrary, material_table, perturbed
from blastvox.model import VoxelModel
from blastvox.voxelize import chunks
from blastvox.voxelize.components import component_labels
from blastvox.voxelize.lattice import Grid
from blastvox.voxelize.look import LookBuilder


@dataclass
class Lattice:
    """Voxels of one input before they are merged with the others."""

    request: Any  # the ObjectRequest (blastvox.voxelize.pipeline)
    name: str
    grid: Grid
    solids: list
    ijk: np.ndarray
    part: np.ndarray
    vertex_ids: np.ndarray      # (V,) lattice vertex ids used
    positions: np.ndarray       # (V, 3)
    voxel_vertices: np.ndarray  # (N, 8) into positions
    volume: np.ndarray
    centroid: np.ndarray
    inertia: np.ndarray
    conform_local: np.ndarray   # (C,) local voxel indices
    conform_offsets: np.ndarray
    conform_triangles: np.ndarray
    conform_tags: np.ndarray
    link_voxels: np.ndarray
    link_face: np.ndarray
    link_midpoint: np.ndarray
    link_area: np.ndarray
    boundary: np.ndarray
    parts: list = field(default_factory=list)  # the input surfaces, for the look
    fill: np.ndarray | None = None  # (N,) m^3 of solid per cube voxel (fill.py), None: volume
    solid_box: np.ndarray | None = None  # (N, 2, 3) m, the bounds of each voxel's solid


#: The packed columns: name -> (what it counts: voxels, links, vertices, conform voxels
#: or triangles; its type, None: the lattices' own; its shape after the first axis).
#: The names that are not model arrays (strength ... voxel_fill) feed the material
#: arrays, the chunks and the mass, and are dropped.
_COLUMNS: dict[str, tuple[str, Any, tuple[int, ...]]] = {
    "vertices": ("vertices", np.float64, (3,)),
    "voxel_vertices": ("voxels", np.int32, (8,)),
    "voxel_ijk": ("voxels", np.int32, (3,)),
    "voxel_object": ("voxels", np.int32, ()),
    "voxel_part": ("voxels", np.int32, ()),
    "voxel_solid_box": ("voxels", np.float64, (2, 3)),
    "voxel_material": ("voxels", np.int32, ()),
    "voxel_volume": ("voxels", np.float64, ()),
    "voxel_centroid": ("voxels", None, (3,)),
    "voxel_inertia": ("voxels", None, (3, 3)),
    "voxel_boundary": ("voxels", np.uint8, ()),
    "link_voxels": ("links", np.int32, (2,)),
    "link_face": ("links", np.uint8, ()),
    "link_midpoint": ("links", None, (3,)),
    "link_area": ("links", np.float64, ()),
    "conform_voxels": ("conform", np.int32, ()),
    "conform_offsets": ("conform", np.int64, ()),
    "conform_triangles": ("triangles", np.float64, (3, 3)),
    "conform_tag": ("triangles", np.uint8, ()),
    "strength": ("voxels", np.float64, ()),
    "chunk_size": ("voxels", np.float64, ()),
    "voxel_side": ("voxels", np.float64, ()),
    "link_bond": ("links", np.float64, ()),
    "anchored": ("voxels", bool, ()),
    "voxel_fill": ("voxels", np.float64, ()),
}
#: The lattice's own array of the columns whose type is the lattices' (None above).
_OWN = {"voxel_centroid": "centroid", "voxel_inertia": "inertia",
        "link_midpoint": "link_midpoint"}
#: Columns used only while assembling.
_WORK = ("strength", "chunk_size", "voxel_side", "link_bond", "anchored", "voxel_fill")


def release_freed_memory() -> None:
    """Hand the heap's free pages back to the system (glibc's ``malloc_trim``; nothing
    elsewhere). Arrays under glibc's mmap threshold (which rises to 32 MiB as large
    blocks are freed) live on the heap, and the heap keeps what is freed: without this
    the lattices freed one by one while the model is filled would still count in the
    process's memory (its RSS) when the model is complete."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@functools.cache
def _malloc_trim():
    """glibc's ``malloc_trim`` or None (another C library, or none to load)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL(None).malloc_trim
    except (AttributeError, OSError):
        return None


def _counts(lat: Lattice) -> dict[str, int]:
    return {"voxels": len(lat.ijk), "links": len(lat.link_voxels),
            "vertices": len(lat.positions), "conform": len(lat.conform_local),
            "triangles": len(lat.conform_triangles)}


def _columns(lattices: list[Lattice]) -> dict[str, np.ndarray]:
    """The packed columns, allocated (not filled) at their final size and type."""
    totals = {k: 0 for k in ("voxels", "links", "vertices", "conform", "triangles")}
    for lat in lattices:
        for key, count in _counts(lat).items():
            totals[key] += count
    out = {}
    for name, (kind, dtype, shape) in _COLUMNS.items():
        if dtype is None:
            dtype = np.result_type(*[getattr(lat, _OWN[name]).dtype for lat in lattices])
        out[name] = np.empty((totals[kind], *shape), dtype=dtype)
    return out


def assemble(lattices: list[Lattice], settings, up: int) -> VoxelModel:
    """The VoxelModel of ``lattices`` (``settings``: the VoxelizeSettings; ``up``: the up
    axis index). Consumes the list: each item is set to None once copied, which frees its
    arrays (the caller keeps no other reference to them)."""
    library = settings.library
    objects: list[dict] = []
    material_names: list[str] = []
    parts: list[dict] = []  # meta["parts"]: every input part (node) of every object
    at = {k: 0 for k in ("voxels", "links", "vertices", "conform", "triangles")}
    look = LookBuilder()
    col = _columns(lattices)

    def material_index(name: str) -> int:
        key = library[name].name
        if key not in material_names:
            material_names.append(key)
        return material_names.index(key)

    for index, lat in enumerate(lattices):
        n = len(lat.ijk)
        labels = component_labels(lat.link_voxels, n)  # numbered by lowest voxel
        count = int(labels.max()) + 1
        for c in range(count):
            objects.append({"name": lat.name if count == 1 else f"{lat.name}.{c:03d}",
                            "source": lat.request.recorded_source(),
                            "shape": lat.request.shape,
                            "voxel_size_m": lat.grid.spacing.tolist(),
                            "jitter": lat.request.jitter, "lattice_origin_m":
                            lat.grid.origin.tolist(), "voxel_count": int((labels == c).sum())})
        look.add_object(lat.name, lat.parts, len(parts))
        names = _voxel_materials(lat)
        scale = np.ones(n)
        for rule in lat.request.rules:
            inside = rule.contains(lat.centroid)
            if rule.material is not None:
                names[inside] = library[rule.material].name
            scale[inside] *= rule.strength_scale
        unique_names, inverse = np.unique(names, return_inverse=True)
        lookup = np.array([material_index(str(u)) for u in unique_names], dtype=np.int32)
        across = lat.part[lat.link_voxels[:, 0]] != lat.part[lat.link_voxels[:, 1]]
        values = {
            "vertices": lat.positions,
            "voxel_vertices": lat.voxel_vertices + at["vertices"],
            "voxel_ijk": lat.ijk,
            "voxel_object": len(objects) - count + labels,
            "voxel_part": len(parts) + _part_indices(lat)[lat.part],
            "voxel_solid_box": lat.solid_box,
            "voxel_material": lookup[inverse.ravel()],
            "voxel_volume": lat.volume,
            "voxel_centroid": lat.centroid,
            "voxel_inertia": lat.inertia,
            "voxel_boundary": lat.boundary,
            "link_voxels": lat.link_voxels + at["voxels"],
            "link_face": lat.link_face,
            "link_midpoint": lat.link_midpoint,
            "link_area": lat.link_area,
            "conform_voxels": lat.conform_local + at["voxels"],
            "conform_offsets": lat.conform_offsets[:-1] + at["triangles"],
            "conform_triangles": lat.conform_triangles,
            "conform_tag": lat.conform_tags,
            "strength": scale,
            "chunk_size": chunks.requested_sizes(lat.request, lat.centroid),
            "voxel_side": float(np.cbrt(np.prod(lat.grid.spacing))),
            "link_bond": np.where(across, lat.request.part_bond, 1.0),
            "anchored": lat.request.anchored,
            "voxel_fill": lat.volume if lat.fill is None else lat.fill,
        }
        parts.extend({"object": lat.name, "name": part.name, "material": part.material}
                     for part in lat.parts)
        counts = _counts(lat)
        for name, value in values.items():
            kind = _COLUMNS[name][0]
            target = col[name][at[kind]:at[kind] + counts[kind]]
            target[...] = np.reshape(value, target.shape) if np.ndim(value) else value
        for key, c in counts.items():
            at[key] += c
        lattices[index] = lat = None  # free this input's arrays: they are copied
        del values
        release_freed_memory()

    work = {name: col.pop(name) for name in _WORK}
    col["conform_offsets"] = np.append(col["conform_offsets"], at["triangles"])
    arrays = _material_arrays(col, work, material_names, library, settings)
    arrays.update(col)
    del col
    lv = arrays["link_voxels"]
    centroid = arrays["voxel_centroid"]
    d = centroid[lv[:, 1]] - centroid[lv[:, 0]]
    np.divide(d, np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300), out=d)
    arrays["link_direction"] = d
    density = arrays["material_density"][arrays["voxel_material"]]
    fill = work.pop("voxel_fill")  # the solid a voxel holds: its mass
    arrays["voxel_mass"] = fill * density
    inertia = arrays["voxel_inertia"]
    inertia *= density[:, None, None]
    inertia *= (fill / arrays["voxel_volume"])[:, None, None]
    del fill, density
    ground = _ground_height(settings.ground, arrays["voxel_solid_box"], up)
    meta = {
        "tool_version": __version__, "up_axis": settings.up_axis, "ground_height": ground,
        "seed": settings.seed, "settings": settings.recorded, "objects": objects,
        "materials": material_names, "parts": parts,
    }
    surface, textures = look.arrays()
    if surface:  # only a textured or smooth input adds the look (others are unchanged)
        arrays.update(surface)
        meta["textures"] = textures
    _foundations(arrays, ground, up, work["strength"], work["anchored"])
    return VoxelModel(arrays=arrays, meta=meta)


def _part_indices(lat: Lattice) -> np.ndarray:
    """(solids,) int: the index in ``lat.parts`` of each solid (a part that failed to
    clean has no solid)."""
    return np.array([next(i for i, part in enumerate(lat.parts) if part is solid.part)
                     for solid in lat.solids], dtype=np.int64)


def _voxel_materials(lat: Lattice) -> np.ndarray:
    """Material name per voxel before region rules: object default, then mesh material."""
    per_part = []
    mapping = {k.lower(): v for k, v in lat.request.material_map.items()}
    for solid in lat.solids:
        own = (solid.part.material or "").lower()
        per_part.append(mapping.get(own, lat.request.material))
    # object dtype: a fixed-width str array would truncate longer names set by rules
    return np.array(per_part, dtype=object)[lat.part]


def _material_arrays(col: dict, work: dict, material_names, library: MaterialLibrary,
                     settings) -> dict:
    """The material table and the seeded per-voxel and per-link values (yields, chunks)
    of the packed columns ``col`` and ``work`` (:data:`_COLUMNS`)."""
    table = material_table(library, material_names)
    mat = col["voxel_material"].astype(np.int64)
    strength = work["strength"]
    n = len(mat)
    seq = np.random.SeedSequence(settings.seed)
    rng_voxel, rng_link, rng_found, rng_chunk = (np.random.default_rng(s) for s in seq.spawn(4))
    voxel_yield = perturbed(table["material_voxel_yield_mean"][mat],
                            table["material_voxel_yield_var"][mat], rng_voxel, n) * strength
    lv = col["link_voxels"].astype(np.int64)
    la, lb = mat[lv[:, 0]], mat[lv[:, 1]]
    link_mean = table["material_link_yield_mean"]
    weaker = np.where(link_mean[la] <= link_mean[lb], la, lb)
    del la, lb
    link_strength = np.minimum(strength[lv[:, 0]], strength[lv[:, 1]])
    link_yield = perturbed(link_mean[weaker], table["material_link_yield_var"][weaker],
                           rng_link, len(lv)) * link_strength
    del link_strength
    voxel_chunk = chunks.group(mat, work["chunk_size"], work["voxel_side"], col["voxel_volume"],
                               col["voxel_centroid"], lv, table, rng_chunk)
    link_yield = link_yield * chunks.bond_factor(voxel_chunk, lv,
                                                 table["material_chunk_bond_scale"][weaker])
    link_yield = link_yield * work["link_bond"]  # touching parts: ObjectRequest.part_bond
    table.update(voxel_yield=voxel_yield, link_yield=link_yield, voxel_chunk=voxel_chunk,
                 voxel_combustibility=table["material_combustibility"][mat].astype(np.float64),
                 _rng_found=np.asarray(rng_found.random(n)))
    return table


def _ground_height(ground, solid_box: np.ndarray, up: int) -> float | None:
    """The ground plane's height (m along ``up``): as set, or "auto", the lowest point of
    the voxels' solid (solid_box (N, 2, 3) m), not of their cells: a crate whose cells
    reach below its mesh stands on the ground with the rest."""
    if ground is None or ground == "none":
        return None
    if ground == "auto":
        return float(solid_box[:, 0, up].min())
    return float(ground)


def _foundations(arrays: dict, ground: float | None, up: int, strength: np.ndarray,
                 anchored: np.ndarray) -> None:
    """Tag voxels touching the ground (of anchored objects, (N,) bool) and give them
    perturbed foundation yields."""
    u = arrays.pop("_rng_found")
    n = len(arrays["voxel_mass"])
    if ground is None:
        arrays["voxel_foundation"] = np.zeros(n, dtype=bool)
        arrays["voxel_foundation_yield"] = np.zeros(n)
        return
    lowest = arrays["voxel_solid_box"][:, 0, up]  # where its solid reaches down to
    size = np.cbrt(np.maximum(arrays["voxel_volume"], 0.0))
    found = (lowest <= ground + 1e-3 * size) & anchored
    mat = arrays["voxel_material"]
    mean = arrays["material_foundation_yield"][mat]
    voxel_mean = arrays["material_voxel_yield_mean"][mat]
    rel = np.divide(arrays["material_voxel_yield_var"][mat], voxel_mean, out=np.zeros(n),
                    where=np.isfinite(voxel_mean) & (voxel_mean > 0))
    value = mean * (1.0 + rel * (2.0 * u - 1.0)) * strength
    arrays["voxel_foundation"] = found
    arrays["voxel_foundation_yield"] = np.where(found, np.maximum(value, 0.0), 0.0)
