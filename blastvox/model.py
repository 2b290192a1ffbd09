"""The VoxelModel contract: what ``voxelize`` writes and ``simulate`` reads.

A VoxelModel is immutable connected-voxel geometry plus per-voxel and per-link
material limits, stored as flat arrays (structure of arrays) in a versioned
``.npz`` file (see :mod:`blastvox.io.npz`). Coordinates are in the input's own
frame, in metres; ``meta["up_axis"]`` says which axis points up (gravity acts
along its negative direction and the ground plane is perpendicular to it).

Arrays (N voxels, L links, V lattice vertices, M materials, C conform voxels,
T conform triangles):

========================  ==============  ==========================================
name                      shape, dtype    meaning
========================  ==============  ==========================================
vertices                  (V, 3) f8       lattice vertices (after jitter), m
voxel_vertices            (N, 8) i4       corner ``dx + 2dy + 4dz`` -> vertex index
voxel_ijk                 (N, 3) i4       lattice index within its object's grid
voxel_object              (N,) i4         object index (``meta["objects"]``)
voxel_part                (N,) i4         optional: the input part (a mesh file's node or
                                          group) the voxel was cut from (``meta["parts"]``:
                                          object, name and material of each)
voxel_material            (N,) i4         material index (``meta["materials"]``)
voxel_volume              (N,) f8         m^3, of the actual (jittered/conform) shape
voxel_mass                (N,) f8         kg
voxel_centroid            (N, 3) f8       m
voxel_inertia             (N, 3, 3) f8    kg m^2, about the voxel centroid
voxel_boundary            (N,) u1         bit f set: face f (-x,+x,-y,+y,-z,+z) exposed
                                          in the intact object; bit 6: has original
                                          surface (conform geometry)
voxel_yield               (N,) f8         Pa, overpressure at the centre that dusts it
voxel_foundation          (N,) bool       touches the ground
voxel_foundation_yield    (N,) f8         Pa (0 where not a foundation voxel)
voxel_combustibility      (N,) f8         Pa of scaled overpressure to ignite (inf: never)
link_voxels               (L, 2) i4       voxel a < voxel b, face-adjacent
link_face                 (L,) u1         face of voxel a that the link crosses (1, 3, 5)
link_midpoint             (L, 3) f8       m, area centroid of the shared face
link_direction            (L, 3) f8       unit vector from centroid a to centroid b
link_area                 (L,) f8         m^2, contact area
link_yield                (L,) f8         Pa, overpressure at the midpoint that breaks it
                                          (x the chunk_bond_scale inside a chunk)
voxel_chunk               (N,) i4         optional: chunk of the voxel, 0..K-1 numbered by
                                          lowest voxel (absent: every voxel its own chunk)
voxel_solid_box           (N, 2, 3) f8    optional: m, (lo, hi) of the solid the voxel holds
                                          (a cube cell the surface crosses: the cell clipped
                                          by the mesh; absent: its corners'); contacts and
                                          the ground use it
conform_voxels            (C,) i4         voxels with exact cell-and-mesh geometry
conform_offsets           (C+1,) i8       triangle ranges per conform voxel
conform_triangles         (T, 3, 3) f8    m, outward triangles of cell and mesh
conform_tag               (T,) u1         0..5: on cell face f; 6: on the original surface
surface_triangles         (S, 3, 3) f8    optional, the source look (all five or none; see
surface_uv                (S, 3, 2) f4    :mod:`blastvox.voxelize.look`): textured or
surface_normals           (S, 3, 3) f4    smooth inputs' triangles, their corners' UVs
surface_part              (S,) i4         and unit normals, texture or -1 and part (the
                                          normals and parts optional: older files),
texture_data              (B,) u1         the textures' PNG bytes and their ranges;
texture_offsets           (K+1,) i8       ``meta["textures"]`` names the K textures
material_*                (M, ...)        material table (see materials.material_table)
========================  ==============  ==========================================
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blastvox import __version__
from blastvox.damage_look import PATTERNS
from blastvox.geometry.frames import UP_AXES, up_index
from blastvox.geometry.voxel_faces import SURFACE_BIT as SURFACE_BIT  # voxel_boundary's bit 6
from blastvox.geometry.voxel_faces import SURFACE_TAG
from blastvox.io.npz import check_schema_version, read_npz, write_npz
from blastvox.io.validate import (
    Spec,
    check_bound,
    check_finite,
    check_index,
    check_layout,
    check_meta_number,
    check_offsets,
    check_range,
    check_shapes,
    check_unique,
    check_unit,
    check_values,
    fail,
)

SCHEMA = "blastvox.VoxelModel"
SCHEMA_VERSION = 1
UNITS = {"length": "m", "mass": "kg", "pressure": "Pa", "inertia": "kg m^2",
         "density": "kg m^-3"}

#: Largest |coordinate| (m) a VoxelModel may hold: room for georeferenced (UTM)
#: meshes. Far from the origin the SimCache's float32 piece positions lose precision
#: (about 1 m at 1e7 m), so keep models near it.
COORD_LIMIT_M = 1e7
#: Largest extent of the vertices, voxel centroids or link midpoints along an axis, in
#: median voxel sizes (cube root of the median volume): 2^20. The simulator's dense
#: grids and 21-bit hash cells count in voxel-size cells; this keeps their sizes far
#: from int64 overflow.
MAX_SPAN_VOXELS = 2**20

_F8, _I4, _I8, _U1 = np.float64, np.int32, np.int64, np.uint8

#: The per-voxel, per-link and conform arrays: name -> (dtype, shape). Symbols: N
#: voxels, V vertices, L links, C conform voxels (C1 = C + 1), T conform triangles.
_REQUIRED: dict[str, Spec] = {
    "vertices": (_F8, ("V", 3)), "voxel_vertices": (_I4, ("N", 8)),
    "voxel_ijk": (_I4, ("N", 3)), "voxel_object": (_I4, ("N",)),
    "voxel_material": (_I4, ("N",)), "voxel_volume": (_F8, ("N",)),
    "voxel_mass": (_F8, ("N",)), "voxel_centroid": (_F8, ("N", 3)),
    "voxel_inertia": (_F8, ("N", 3, 3)), "voxel_boundary": (_U1, ("N",)),
    "voxel_yield": (_F8, ("N",)), "voxel_foundation": (np.bool_, ("N",)),
    "voxel_foundation_yield": (_F8, ("N",)), "voxel_combustibility": (_F8, ("N",)),
    "link_voxels": (_I4, ("L", 2)), "link_face": (_U1, ("L",)),
    "link_midpoint": (_F8, ("L", 3)), "link_direction": (_F8, ("L", 3)),
    "link_area": (_F8, ("L",)), "link_yield": (_F8, ("L",)),
    "conform_voxels": (_I4, ("C",)), "conform_offsets": (_I8, ("C1",)),
    "conform_triangles": (_F8, ("T", 3, 3)), "conform_tag": (_U1, ("T",)),
}

#: Per-voxel arrays a file may lack (older models): name -> (dtype, shape).
OPTIONAL_ARRAYS: dict[str, Spec] = {"voxel_chunk": (_I4, ("N",)), "voxel_part": (_I4, ("N",)),
                                    "voxel_solid_box": (_F8, ("N", 2, 3))}
#: The source look (blastvox.voxelize.look): all present or all absent. S surface
#: triangles, B texture bytes, K1 = textures + 1.
SURFACE_ARRAYS: dict[str, Spec] = {
    "surface_triangles": (_F8, ("S", 3, 3)), "surface_uv": (np.float32, ("S", 3, 2)),
    "surface_texture": (_I4, ("S",)), "texture_data": (_U1, ("B",)),
    "texture_offsets": (_I8, ("K1",)), "surface_normals": (np.float32, ("S", 3, 3)),
    "surface_part": (_I4, ("S",)),
}
#: Look arrays a file with a look may lack (written before they existed).
SURFACE_OPTIONAL = ("surface_normals", "surface_part")

#: The material table (blastvox.materials.material_table), one row per name in
#: meta["materials"] (M): name -> (dtype, shape).
MATERIAL_ARRAYS: dict[str, Spec] = {
    "material_density": (_F8, ("M",)), "material_link_yield_mean": (_F8, ("M",)),
    "material_link_yield_var": (_F8, ("M",)), "material_voxel_yield_mean": (_F8, ("M",)),
    "material_voxel_yield_var": (_F8, ("M",)), "material_foundation_yield": (_F8, ("M",)),
    "material_restitution": (_F8, ("M",)), "material_combustibility": (_F8, ("M",)),
    "material_link_impulse": (_F8, ("M",)), "material_voxel_impulse": (_F8, ("M",)),
    "material_pi_shape": (_F8, ("M",)), "material_compressive_strength": (_F8, ("M",)),
    "material_tensile_strength": (_F8, ("M",)), "material_shear_strength": (_F8, ("M",)),
    "material_youngs_modulus": (_F8, ("M",)), "material_crush_pressure": (_F8, ("M",)),
    "material_chunk_size": (_F8, ("M",)),
    "material_chunk_weibull": (_F8, ("M",)), "material_chunk_bond_scale": (_F8, ("M",)),
    "material_color": (_F8, ("M", 3)),
    "material_damage_color": (_F8, ("M", 3)), "material_description": (np.str_, ("M",)),
    "material_damage_pattern": (np.str_, ("M",)),
}
#: Material arrays a file may lack (older models: the simulator reads the
#: Material defaults, e.g. 0 impulse and infinite strengths).
OPTIONAL_MATERIAL_ARRAYS = ("material_link_impulse", "material_voxel_impulse",
                            "material_pi_shape", "material_description",
                            "material_compressive_strength", "material_tensile_strength",
                            "material_shear_strength", "material_youngs_modulus",
                            "material_crush_pressure", "material_chunk_size",
                            "material_chunk_weibull", "material_chunk_bond_scale",
                            "material_damage_pattern")
#: Every member a VoxelModel file may hold besides ``meta``; others are never read.
ARRAY_NAMES = (frozenset(_REQUIRED) | frozenset(OPTIONAL_ARRAYS) | frozenset(MATERIAL_ARRAYS)
               | frozenset(SURFACE_ARRAYS))

_MEANING = {"N": "one per voxel", "L": "one per link", "V": "one per vertex",
            "C": "one per conform voxel", "C1": "one more than the conform voxels",
            "S": "one per surface triangle", "K1": "one more than meta textures",
            "T": "one per conform triangle", "M": "one per name in meta materials"}


@dataclass(frozen=True)
class VoxelModel:
    """Immutable connected-voxel model: ``arrays`` (see module doc) and ``meta``.

    ``meta`` holds schema, tool version, units, ``up_axis`` ("Y"/"Z"),
    ``ground_height`` (m or None), ``seed``, ``settings``, ``objects`` (list of
    dicts with at least ``name`` and ``source``) and ``materials`` (names).
    """

    arrays: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    def __getattr__(self, name: str) -> np.ndarray:
        try:
            return self.__dict__["arrays"][name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def voxel_count(self) -> int:
        return int(len(self.arrays["voxel_mass"]))

    @property
    def link_count(self) -> int:
        return int(len(self.arrays["link_voxels"]))

    @property
    def up_index(self) -> int:
        """0, 1 or 2: the index of the up axis."""
        return up_index(self.meta["up_axis"])

    @property
    def textures(self) -> list[dict]:
        """``meta["textures"]``: one dict (name, mime_type) per texture of the look."""
        return list(self.meta.get("textures", []))

    def texture_file(self, k: int) -> bytes:
        """The encoded image (PNG) of texture ``k`` of the source look."""
        offsets = self.arrays["texture_offsets"]
        return self.arrays["texture_data"][int(offsets[k]):int(offsets[k + 1])].tobytes()

    def hexahedra(self) -> np.ndarray:
        """Voxel corners (N, 8, 3) in metres."""
        return self.arrays["vertices"][self.arrays["voxel_vertices"]]

    def contract_meta(self) -> dict[str, Any]:
        """``meta`` with the contract's stamps (schema, version, units, tool version)."""
        meta = dict(self.meta)
        meta.update(schema=SCHEMA, schema_version=SCHEMA_VERSION, units=UNITS,
                    tool_version=meta.get("tool_version", __version__))
        return meta

    def save(self, path: str | Path) -> None:
        """Write atomically and deterministically to ``path``."""
        write_npz(path, self.arrays, self.contract_meta())

    @classmethod
    def load(cls, path: str | Path) -> VoxelModel:
        """Read and validate a VoxelModel file; :class:`ContractError` if it is not one."""
        meta, arrays = read_npz(path, SCHEMA, SCHEMA_VERSION, what="VoxelModel",
                                members=ARRAY_NAMES)
        check_model(path, arrays, meta)
        return cls(arrays=arrays, meta=meta)

    def summary(self) -> dict[str, Any]:
        """Counts, bounds, mass and materials, as a JSON-safe dict (``blastvox info``)."""
        a = self.arrays
        verts = a["vertices"]
        bounds = ([verts.min(axis=0).tolist(), verts.max(axis=0).tolist()] if len(verts)
                  else [[0.0] * 3, [0.0] * 3])
        used = np.unique(a["voxel_material"])
        names = self.meta.get("materials", [])
        return {
            "kind": "VoxelModel",
            "schema_version": self.meta.get("schema_version"),
            "tool_version": self.meta.get("tool_version"),
            "up_axis": self.meta.get("up_axis"),
            "ground_height_m": self.meta.get("ground_height"),
            "voxel_count": self.voxel_count,
            "link_count": self.link_count,
            "object_count": len(self.meta.get("objects", [])),
            "objects": [o["name"] for o in self.meta.get("objects", [])],
            "foundation_voxel_count": int(np.count_nonzero(a["voxel_foundation"])),
            "boundary_voxel_count": int(np.count_nonzero(a["voxel_boundary"])),
            "conform_voxel_count": int(len(a["conform_voxels"])),
            "chunk_count": (len(np.unique(a["voxel_chunk"])) if "voxel_chunk" in a
                            else self.voxel_count),
            "total_volume_m3": float(a["voxel_volume"].sum()),
            "total_mass_kg": float(a["voxel_mass"].sum()),
            "bounds_m": bounds,
            "materials_used": [names[i] for i in used.tolist() if i < len(names)],
            "seed": self.meta.get("seed"),
        }


def check_model(path: str | os.PathLike, arrays: Mapping[str, np.ndarray],
                meta: Mapping[str, Any], prefix: str = "") -> None:
    """Check a VoxelModel's ``arrays`` and ``meta`` against the contract (module doc).

    Raises :class:`~blastvox.errors.ContractError`, one line naming ``path`` and the
    array or meta key, for: a missing array; a wrong dtype or shape (every
    dimension, against N, L, V, C, T and M = len(meta["materials"])); NaN or inf
    where a number must be finite (yields and combustibility may be +inf:
    unbreakable, never burns); a value out of range (masses, volumes and link
    areas > 0, yields >= 0, voxel_boundary < 128, link_face 1/3/5, conform_tag
    <= 6, inertia symmetric with a positive diagonal, unit link directions,
    material values as :mod:`blastvox.materials` allows them); an index out of
    bounds (vertices, voxels, objects, materials, chunks < N; link_voxels a < b; conform
    voxels listed once; conform_offsets from 0 to T, never decreasing);
    coordinates beyond :data:`COORD_LIMIT_M` or spanning more than
    :data:`MAX_SPAN_VOXELS` voxel sizes; and bad meta (``up_axis``,
    ``ground_height``, ``objects``, ``materials``). ``prefix`` (``"model."``) is
    added to array and meta names: the embedded model of a SimCache, whose meta is
    also checked for its schema and ``schema_version``.

    Vectorised: one or two passes per array, ~0.1 s per million voxels.
    """
    a = arrays
    if prefix:
        schema = meta.get("schema")
        if schema != SCHEMA:
            fail(path, f"meta {prefix}schema is {schema!r}; expected {SCHEMA!r}")
        check_schema_version(path, "embedded model: ", meta, SCHEMA, SCHEMA_VERSION)
    check_layout(path, a, _REQUIRED, prefix, "VoxelModel")
    names = _check_meta(path, meta, prefix)
    check_layout(path, a, MATERIAL_ARRAYS, prefix, "VoxelModel", OPTIONAL_MATERIAL_ARRAYS)
    check_layout(path, a, OPTIONAL_ARRAYS, prefix, "VoxelModel", tuple(OPTIONAL_ARRAYS))
    n, c = len(a["voxel_mass"]), len(a["conform_voxels"])
    dims = {"N": n, "V": len(a["vertices"]), "L": len(a["link_voxels"]), "C": c,
            "C1": c + 1, "T": len(a["conform_triangles"]), "M": len(names)}
    check_shapes(path, a, _REQUIRED, dims, prefix, _MEANING)
    check_shapes(path, a, MATERIAL_ARRAYS, dims, prefix, _MEANING)
    check_shapes(path, a, OPTIONAL_ARRAYS, dims, prefix, _MEANING)
    _check_look(path, a, meta, prefix)
    if n == 0:
        fail(path, f"array '{prefix}voxel_mass' is empty: the VoxelModel holds no voxels")

    def name(key: str) -> str:
        return prefix + key

    _check_materials(path, a, prefix)
    # indices: every one a kernel follows must land inside its table
    check_index(path, name("voxel_vertices"), a["voxel_vertices"], dims["V"], "vertex")
    check_index(path, name("voxel_object"), a["voxel_object"], len(meta["objects"]), "object")
    check_index(path, name("voxel_material"), a["voxel_material"], dims["M"], "material")
    if "voxel_chunk" in a:  # ids only: a chunk's connectedness is not checked
        check_index(path, name("voxel_chunk"), a["voxel_chunk"], n, "chunk")
    if "voxel_part" in a:
        check_index(path, name("voxel_part"), a["voxel_part"], _part_count(path, meta, prefix),
                    "part")
    check_range(path, name("voxel_ijk"), a["voxel_ijk"], 0, rule="a lattice index >= 0")
    links = a["link_voxels"]
    check_index(path, name("link_voxels"), links, n, "voxel")
    if links.size:
        backwards = links[:, 0] >= links[:, 1]
        if backwards.any():
            i = int(np.flatnonzero(backwards)[0])
            fail(path, f"array '{name('link_voxels')}' holds the link {links[i].tolist()} at "
                       f"[{i}]; expected voxel a < voxel b")
    check_values(path, name("link_face"), a["link_face"], (1, 3, 5))
    check_unique(path, name("conform_voxels"), a["conform_voxels"], n, "voxel")
    check_offsets(path, name("conform_offsets"), a["conform_offsets"], dims["T"],
                  "conform triangles")
    check_range(path, name("conform_tag"), a["conform_tag"], 0, SURFACE_TAG,
                rule=f"a face tag 0..{SURFACE_TAG}")
    check_range(path, name("voxel_boundary"), a["voxel_boundary"], 0, 2 ** (SURFACE_BIT + 1) - 1,
                rule=f"a bit mask below {2 ** (SURFACE_BIT + 1)}")
    # geometry: finite, bounded, and not so spread out that the simulator's grids overflow
    check_bound(path, name("conform_triangles"), a["conform_triangles"], COORD_LIMIT_M)
    for key in ("voxel_volume", "voxel_mass", "link_area"):
        check_range(path, name(key), a[key], 0.0, lo_open=True)
    _check_density(path, name("voxel_mass"), a["voxel_mass"], a["voxel_volume"])
    size = float(np.cbrt(np.median(a["voxel_volume"])))
    for key in ("vertices", "voxel_centroid", "link_midpoint"):
        _check_points(path, name(key), a[key], size)
    if "voxel_solid_box" in a:
        _check_solid_box(path, name("voxel_solid_box"), a["voxel_solid_box"], size)
    _check_inertia(path, name("voxel_inertia"), a["voxel_inertia"])
    check_unit(path, name("link_direction"), a["link_direction"], 1e-6)
    # limits: >= 0; +inf means unbreakable / never burns
    for key in ("voxel_yield", "voxel_foundation_yield", "voxel_combustibility", "link_yield"):
        check_range(path, name(key), a[key], 0.0, finite=False)
    loose = a["voxel_foundation_yield"][~a["voxel_foundation"]]
    if loose.size and loose.any():
        i = int(np.flatnonzero(~a["voxel_foundation"])[np.flatnonzero(loose)[0]])
        fail(path, f"array '{name('voxel_foundation_yield')}' holds "
                   f"{float(a['voxel_foundation_yield'][i])!r} at [{i}], a voxel that is not a "
                   f"foundation ('{name('voxel_foundation')}'); expected 0")


def _check_density(path: str | os.PathLike, label: str, mass: np.ndarray,
                   volume: np.ndarray) -> None:
    """Each voxel's mass (kg) over its volume (m^3) within the materials' density bound:
    a crafted 1e308 kg voxel passed as "finite and > 0" and overflowed the simulator."""
    from blastvox.materials import MAX_DENSITY

    over = np.flatnonzero(mass > MAX_DENSITY * volume * (1.0 + 1e-9))
    if over.size:
        i = int(over[0])
        with np.errstate(over="ignore"):
            density = float(mass[i] / volume[i])
        fail(path, f"array '{label}' holds {float(mass[i]):.4g} kg at [{i}], "
                   f"{density:.4g} kg/m^3 over its voxel's volume, more than "
                   f"the {MAX_DENSITY:g} kg/m^3 any material may be")


def _check_look(path: str | os.PathLike, a: Mapping[str, np.ndarray], meta: Mapping[str, Any],
                prefix: str) -> None:
    """The source look: all five arrays or none (and the optional normals), sized by
    meta textures, indices and byte ranges inside their tables, coordinates finite,
    normals of length 1 (or 0: none)."""
    present = [k for k in SURFACE_ARRAYS if k in a and k not in SURFACE_OPTIONAL]
    if not present:
        if meta.get("textures"):
            fail(path, f"meta {prefix}textures names textures but the file has no "
                       f"'{prefix}texture_data'")
        return
    check_layout(path, a, SURFACE_ARRAYS, prefix, "VoxelModel with a source look",
                 optional=SURFACE_OPTIONAL)
    textures = meta.get("textures")
    if not isinstance(textures, list) or not all(
            isinstance(t, dict) and isinstance(t.get("name"), str) for t in textures):
        fail(path, f"meta {prefix}textures is {textures!r}; expected a list of "
                   "{'name': ..., 'mime_type': ...}")
    dims = {"S": len(a["surface_triangles"]), "B": len(a["texture_data"]),
            "K1": len(textures) + 1}
    check_shapes(path, a, SURFACE_ARRAYS, dims, prefix, _MEANING)
    check_bound(path, prefix + "surface_triangles", a["surface_triangles"], COORD_LIMIT_M)
    check_finite(path, prefix + "surface_uv", a["surface_uv"])
    if "surface_normals" in a:
        _check_unit_or_zero(path, prefix + "surface_normals", a["surface_normals"])
    check_index(path, prefix + "surface_texture", a["surface_texture"], len(textures),
                "texture", none=-1)
    if "surface_part" in a:
        check_index(path, prefix + "surface_part", a["surface_part"],
                    _part_count(path, meta, prefix), "part")
    check_offsets(path, prefix + "texture_offsets", a["texture_offsets"], dims["B"],
                  "texture bytes")


def _check_unit_or_zero(path: str | os.PathLike, name: str, vectors: np.ndarray) -> None:
    """Every vector (..., 3) of ``vectors`` has length 1 (within 1e-3) or 0."""
    check_finite(path, name, vectors)
    length = np.linalg.norm(vectors.reshape(-1, 3).astype(np.float64), axis=1)
    bad = (np.abs(length - 1.0) > 1e-3) & (length > 1e-6)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        fail(path, f"array '{name}' holds a vector of length {length[i]:.6g} at "
                   f"[{i // 3}, {i % 3}]; expected unit normals (or 0: none)")


def _check_meta(path: str | os.PathLike, meta: Mapping[str, Any], prefix: str) -> list[str]:
    """up_axis, ground_height, objects, materials; returns the material names."""
    up = meta.get("up_axis")
    if up not in UP_AXES:
        fail(path, f"meta {prefix}up_axis is {up!r}; expected one of {', '.join(UP_AXES)}")
    ground = meta.get("ground_height")
    if ground is not None:
        check_meta_number(path, f"{prefix}ground_height", ground, limit=COORD_LIMIT_M)
    objects = meta.get("objects")
    if not isinstance(objects, list) or not all(
            isinstance(o, dict) and isinstance(o.get("name"), str) for o in objects):
        fail(path, f"meta {prefix}objects is not a list of objects with a 'name' "
                   f"(got {_clip(objects)})")
    names = meta.get("materials")
    if not isinstance(names, list) or not all(isinstance(m, str) for m in names):
        fail(path, f"meta {prefix}materials is not a list of material names "
                   f"(got {_clip(names)})")
    return names


def _part_count(path: str | os.PathLike, meta: Mapping[str, Any], prefix: str) -> int:
    """The number of input parts ``meta["parts"]`` names (each a dict with a 'name')."""
    parts = meta.get("parts")
    if not isinstance(parts, list) or not all(
            isinstance(p, dict) and isinstance(p.get("name"), str) for p in parts):
        fail(path, f"meta {prefix}parts is not a list of parts with a 'name' "
                   f"(got {_clip(parts)})")
    return len(parts)


def _clip(value: Any, width: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


#: Material array -> (lower bound, upper bound, finite): as blastvox.materials allows.
_MATERIAL_RANGES: dict[str, tuple[float, float | None, bool, bool]] = {
    # name: (lo, hi, lo_open, finite)
    "material_density": (0.0, None, True, True),
    "material_link_yield_mean": (0.0, None, False, False),
    "material_link_yield_var": (0.0, None, False, True),
    "material_voxel_yield_mean": (0.0, None, False, False),
    "material_voxel_yield_var": (0.0, None, False, True),
    "material_foundation_yield": (0.0, None, False, False),
    "material_restitution": (0.0, 1.0, False, True),
    "material_combustibility": (0.0, None, False, False),
    "material_link_impulse": (0.0, None, False, True),
    "material_voxel_impulse": (0.0, None, False, True),
    "material_pi_shape": (0.0, None, False, True),
    "material_compressive_strength": (0.0, None, True, False),
    "material_tensile_strength": (0.0, None, True, False),
    "material_shear_strength": (0.0, None, True, False),
    "material_youngs_modulus": (0.0, None, True, True),
    "material_crush_pressure": (0.0, None, False, False),
    "material_chunk_size": (0.0, None, False, True),
    "material_chunk_weibull": (0.0, None, True, True),
    "material_chunk_bond_scale": (1.0, None, False, True),
    "material_color": (0.0, 1.0, False, True),
    "material_damage_color": (0.0, 1.0, False, True),
}


def _check_materials(path: str | os.PathLike, arrays: Mapping[str, np.ndarray],
                     prefix: str) -> None:
    for key, (lo, hi, lo_open, finite) in _MATERIAL_RANGES.items():
        if key in arrays:
            check_range(path, prefix + key, arrays[key], lo, hi, lo_open=lo_open,
                        finite=finite)
    patterns = arrays.get("material_damage_pattern")
    if patterns is not None:
        for m, pattern in enumerate(patterns.tolist()):
            if pattern and pattern not in PATTERNS:
                fail(path, f"{prefix}material_damage_pattern[{m}] is {_clip(pattern)}; "
                           f"expected one of {', '.join(PATTERNS)} or ''")


def _check_points(path: str | os.PathLike, name: str, points: np.ndarray,
                  size: float) -> None:
    """Points (K, 3) m: finite, within :data:`COORD_LIMIT_M`, and spanning at most
    :data:`MAX_SPAN_VOXELS` times ``size`` (m) along each axis."""
    if not len(points):
        return
    lo, hi = points.min(), points.max()  # whole-array reductions are the fast ones
    if not (-COORD_LIMIT_M <= lo and hi <= COORD_LIMIT_M):
        check_bound(path, name, points, COORD_LIMIT_M)  # names the element
    if hi - lo <= MAX_SPAN_VOXELS * size:
        return
    span = np.array([points[:, k].max() - points[:, k].min() for k in range(3)])
    axis = int(np.argmax(span))
    if span[axis] > MAX_SPAN_VOXELS * size:
        fail(path, f"array '{name}' spans {span[axis]:.6g} m along {'xyz'[axis]}, more than "
                   f"{MAX_SPAN_VOXELS} times the median voxel size ({size:.6g} m), beyond "
                   "what the simulator's grids can hold")


def _check_solid_box(path: str | os.PathLike, name: str, box: np.ndarray, size: float) -> None:
    """Boxes (N, 2, 3) m, (lo, hi) per voxel: finite, within :data:`COORD_LIMIT_M`, lo <=
    hi on every axis, and spanning what the simulator's grids hold (as points); a bad
    box is named by its voxel."""
    bad = ~(np.abs(box) <= COORD_LIMIT_M).all(axis=(1, 2)) | (box[:, 1] < box[:, 0]).any(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        fail(path, f"array '{name}' holds the box {box[i].tolist()} at [{i}]; expected finite "
                   f"(lo, hi) within +-{COORD_LIMIT_M:g} m with lo <= hi on every axis")
    _check_points(path, name, box.reshape(-1, 3), size)


#: voxel_inertia must be symmetric to this fraction of the voxel's largest diagonal element
INERTIA_SYMMETRY = 1e-6


def _check_inertia(path: str | os.PathLike, name: str, inertia: np.ndarray) -> None:
    """Finite, positive diagonal, symmetric to :data:`INERTIA_SYMMETRY` of the largest
    diagonal element. Whole-column reductions only, unless something is wrong."""
    check_finite(path, name, inertia)
    if not inertia.size:
        return
    diagonal = [inertia[:, k, k] for k in range(3)]
    smallest = min(float(d.min()) for d in diagonal)
    if not smallest > 0.0:
        i, k = np.argwhere(~(np.diagonal(inertia, axis1=1, axis2=2) > 0.0))[0]
        fail(path, f"array '{name}' holds a diagonal element that is not > 0 "
                   f"({float(inertia[i, k, k])!r} at [{i}, {k}, {k}])")
    pairs = ((0, 1), (0, 2), (1, 2))
    differences = [inertia[:, j, k] - inertia[:, k, j] for j, k in pairs]
    worst = max(max(-float(d.min()), float(d.max())) for d in differences)
    if worst <= INERTIA_SYMMETRY * smallest:
        return  # symmetric even against the smallest diagonal element of all
    scale = np.maximum(np.maximum(diagonal[0], diagonal[1]), diagonal[2])
    asym = np.maximum(np.maximum(np.abs(differences[0]), np.abs(differences[1])),
                      np.abs(differences[2]))
    bad = asym > INERTIA_SYMMETRY * scale
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        fail(path, f"array '{name}' holds a tensor that is not symmetric at [{i}]")
