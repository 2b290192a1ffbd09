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
conform_voxels            (C,) i4         voxels with exact cell-and-mesh geometry
conform_offsets           (C+1,) i8       triangle ranges per conform voxel
conform_triangles         (T, 3, 3) f8    m, outward triangles of cell and mesh
conform_tag               (T,) u1         0..5: on cell face f; 6: on the original surface
material_*                (M, ...)        material table (see materials.material_table)
========================  ==============  ==========================================
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blastvox import __version__
from blastvox.errors import ContractError
from blastvox.geometry.frames import AXES, up_index
from blastvox.geometry.voxel_faces import SURFACE_BIT as SURFACE_BIT  # voxel_boundary's bit 6
from blastvox.io.npz import read_npz, write_npz

SCHEMA = "blastvox.VoxelModel"
SCHEMA_VERSION = 1
UNITS = {"length": "m", "mass": "kg", "pressure": "Pa", "inertia": "kg m^2",
         "density": "kg m^-3"}

_REQUIRED = {
    "vertices": (2, np.float64), "voxel_vertices": (2, np.int32), "voxel_ijk": (2, np.int32),
    "voxel_object": (1, np.int32), "voxel_material": (1, np.int32),
    "voxel_volume": (1, np.float64), "voxel_mass": (1, np.float64),
    "voxel_centroid": (2, np.float64), "voxel_inertia": (3, np.float64),
    "voxel_boundary": (1, np.uint8), "voxel_yield": (1, np.float64),
    "voxel_foundation": (1, np.bool_), "voxel_foundation_yield": (1, np.float64),
    "voxel_combustibility": (1, np.float64),
    "link_voxels": (2, np.int32), "link_face": (1, np.uint8), "link_midpoint": (2, np.float64),
    "link_direction": (2, np.float64), "link_area": (1, np.float64),
    "link_yield": (1, np.float64),
    "conform_voxels": (1, np.int32), "conform_offsets": (1, np.int64),
    "conform_triangles": (3, np.float64), "conform_tag": (1, np.uint8),
}


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
        meta, arrays = read_npz(path, SCHEMA, SCHEMA_VERSION, what="VoxelModel")
        _check_arrays(Path(path), arrays)
        if meta.get("up_axis") not in AXES:
            raise ContractError(f"{path}: up_axis is {meta.get('up_axis')!r}; expected one of "
                                f"{', '.join(AXES)}")
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
            "total_volume_m3": float(a["voxel_volume"].sum()),
            "total_mass_kg": float(a["voxel_mass"].sum()),
            "bounds_m": bounds,
            "materials_used": [names[i] for i in used.tolist() if i < len(names)],
            "seed": self.meta.get("seed"),
        }


def _check_arrays(path: Path, arrays: dict[str, np.ndarray]) -> None:
    for name, (ndim, dtype) in _REQUIRED.items():
        if name not in arrays:
            raise ContractError(f"{path}: VoxelModel is missing array '{name}'")
        arr = arrays[name]
        if arr.ndim != ndim or arr.dtype != dtype:
            raise ContractError(f"{path}: array '{name}' has shape {arr.shape} and dtype "
                                f"{arr.dtype}; expected {ndim}-D {np.dtype(dtype)}")
    n = len(arrays["voxel_mass"])
    for name in _REQUIRED:
        if name.startswith("voxel_") and len(arrays[name]) != n:
            raise ContractError(f"{path}: array '{name}' has {len(arrays[name])} rows; "
                                f"expected {n} (one per voxel)")
    if arrays["link_voxels"].size and (arrays["link_voxels"].min() < 0
                                       or arrays["link_voxels"].max() >= n):
        raise ContractError(f"{path}: link_voxels refers to voxels that do not exist")
    if arrays["voxel_object"].size and arrays["voxel_object"].min() < 0:
        raise ContractError(f"{path}: voxel_object holds a negative object index")
    _check_strength(path, arrays)


#: optional material arrays of the pressure-impulse strength (absent in older models)
_STRENGTH = ("material_link_impulse", "material_voxel_impulse", "material_pi_shape")


def _check_strength(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Each optional strength array, when present: one finite value >= 0 per material."""
    materials = int(arrays["voxel_material"].max()) + 1 if arrays["voxel_material"].size else 0
    for name in _STRENGTH:
        if name not in arrays:
            continue
        arr = arrays[name]
        if arr.ndim != 1 or arr.dtype.kind != "f" or len(arr) < materials:
            raise ContractError(f"{path}: array '{name}' has shape {arr.shape} and dtype "
                                f"{arr.dtype}; expected 1-D float, one value per material")
        if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
            raise ContractError(f"{path}: array '{name}' holds a value that is not a finite "
                                "number >= 0")
