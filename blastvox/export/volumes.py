"""Particles as volumes: each frame's live particles of a system splatted into sparse
density (and, for fire, temperature) grids and written as OpenVDB files.

Units. ``density`` is an extinction coefficient in 1/m: a ray through it loses
exp(-integral of density ds) of its light, which is what Blender's and Houdini's
volume shaders read with a density scale of 1 (Blender's default volume material,
a Principled Volume of density 1 reading the ``density`` grid). Each particle
carries an extinction cross-section A (m^2): the grid's integral, the sum of
density x cell volume, is the sum of the live particles' A, whatever the cell size
(the kernel's weights are normalised over the cells they touch; a particle smaller
than a cell lands whole in its nearest cell). A is chosen per system
(:data:`VOLUME_LOOKS`) as the optical depth ``tau`` a ray through an isolated
particle's centre sees: A = tau r^2 / 1.432 for the kernel below.

The kernel: a particle of size (diameter) d spreads over a sphere of radius r = d
with weight (1 - |x - c|^2 / r^2)^3 at cell centre c: smooth, compact, and its
half maximum width is 0.91 r, about the particle's diameter, so a lone particle
looks its size and neighbours merge into one cloud.

``temperature`` (K, only fire and fireball) is the density-weighted mean of the
particles' temperatures in each cell; a particle cools linearly over its life from
the system's ``hot_k`` to ``cool_k``. A Principled Volume's Blackbody Intensity reads
it (Blender's default volume material does not: see docs/file-formats.md).

A system's grids sit on one lattice for every frame: voxel (i, j, k)'s centre is at
``h * (i, j, k)`` in the export frame (metres, the stage's up axis), with h the
export's ``volume_voxel_m`` or, for systems of large particles (the fireball's),
a quarter of their median diameter (:func:`system_voxel`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from blastvox.jit import kernel

#: the kernel's central optical depth per unit A / r^2: 2 r (16/35) / (4 pi r^3 16/315)
KERNEL_TAU = (2 * 16 / 35) / (4 * math.pi * 16 / 315)
#: the most kernel cells one frame's splat may touch: 24 bytes each, about 1.2 GB
MAX_SPLAT_CELLS = 50_000_000
#: packed cell keys: 21 bits per axis, offset so that negative indices pack
_BITS, _OFFSET = 21, 1 << 20


@dataclass(frozen=True)
class VolumeLook:
    """How a system's particles become a volume: ``tau``, the optical depth through
    one isolated particle's centre (-); ``hot_k``/``cool_k`` the temperature (K) at
    birth and at the end of life, or None for no temperature grid."""

    tau: float
    hot_k: float | None = None
    cool_k: float | None = None


VOLUME_LOOKS: dict[str, VolumeLook] = {
    "dust": VolumeLook(tau=2.0),
    "smoke": VolumeLook(tau=0.6),
    "fire": VolumeLook(tau=0.4, hot_k=1600.0, cool_k=900.0),
    "fireball": VolumeLook(tau=0.05, hot_k=2200.0, cool_k=700.0),
}


def cross_section(size: np.ndarray, tau: float) -> np.ndarray:
    """A (m^2) of particles of diameter ``size`` (m): tau r^2 / KERNEL_TAU with r = size."""
    return tau * np.asarray(size, dtype=np.float64) ** 2 / KERNEL_TAU


@kernel
def _box_counts(pos, radius, h):  # pragma: no cover - compiled
    """Cells each particle's kernel box spans (1 when it falls between cell centres)."""
    n = pos.shape[0]
    out = np.empty(n, dtype=np.int64)
    for p in range(n):
        count = 1
        for a in range(3):
            lo = math.ceil((pos[p, a] - radius[p]) / h)
            hi = math.floor((pos[p, a] + radius[p]) / h)
            count *= max(hi - lo + 1, 1)
        out[p] = count
    return out


@kernel
def _splat_fill(pos, radius, amount, temp, h, starts, keys, mass, heat):  # pragma: no cover
    """Each particle's normalised kernel weights x its amount / h^3 into
    keys[starts[p]:starts[p + 1]] (packed cells), mass (density) and heat (density x
    temperature); cells outside the kernel get 0."""
    inv_cell = 1.0 / (h * h * h)
    for p in range(pos.shape[0]):
        r = radius[p]
        lo = np.empty(3, dtype=np.int64)
        dim = np.empty(3, dtype=np.int64)
        for a in range(3):
            lo[a] = math.ceil((pos[p, a] - r) / h)
            dim[a] = max(math.floor((pos[p, a] + r) / h) - lo[a] + 1, 0)
        s = starts[p]
        total = 0.0
        if dim[0] > 0 and dim[1] > 0 and dim[2] > 0:
            n = 0
            for i in range(dim[0]):
                dx = (lo[0] + i) * h - pos[p, 0]
                for j in range(dim[1]):
                    dy = (lo[1] + j) * h - pos[p, 1]
                    for k in range(dim[2]):
                        dz = (lo[2] + k) * h - pos[p, 2]
                        q = (dx * dx + dy * dy + dz * dz) / (r * r)
                        w = (1.0 - q) ** 3 if q < 1.0 else 0.0
                        keys[s + n] = (((lo[0] + i + _OFFSET) << (2 * _BITS))
                                       | ((lo[1] + j + _OFFSET) << _BITS) | (lo[2] + k + _OFFSET))
                        mass[s + n] = w
                        total += w
                        n += 1
        if total > 0.0:
            scale = amount[p] * inv_cell / total
            for m in range(s, starts[p + 1]):
                mass[m] *= scale
                heat[m] = mass[m] * temp[p]
        else:  # the kernel holds no cell centre: all of it in the nearest cell
            c = np.empty(3, dtype=np.int64)
            for a in range(3):
                c[a] = int(math.floor(pos[p, a] / h + 0.5))
            keys[s] = ((c[0] + _OFFSET) << (2 * _BITS)) | ((c[1] + _OFFSET) << _BITS) | (
                c[2] + _OFFSET)
            mass[s] = amount[p] * inv_cell
            heat[s] = mass[s] * temp[p]
            for m in range(s + 1, starts[p + 1]):
                keys[m] = keys[s]
                mass[m] = 0.0
                heat[m] = 0.0


def splat(positions: np.ndarray, radius: np.ndarray, amount: np.ndarray, voxel_m: float,
          temperature: np.ndarray | None = None
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Splat K particles into a sparse grid of cubic cells of edge ``voxel_m`` (m),
    cell (i, j, k) centred at ``voxel_m * (i, j, k)``.

    positions (K, 3) m; radius (K,) m the kernel's support radius; amount (K,) m^2 the
    extinction cross-section each particle brings; temperature (K,) K or None.
    Returns (ijk (M, 3) int32 sorted, density (M,) float32 1/m, > 0, temperature (M,)
    float32 K, the density-weighted mean, or None): sum(density) * voxel_m^3 equals
    sum(amount) (to float32 rounding)."""
    pos = np.ascontiguousarray(positions, dtype=np.float64).reshape(-1, 3)
    r = np.ascontiguousarray(radius, dtype=np.float64).reshape(-1)
    a = np.ascontiguousarray(amount, dtype=np.float64).reshape(-1)
    h = float(voxel_m)
    if not (math.isfinite(h) and h > 0):
        raise ValueError(f"voxel size must be > 0 (got {voxel_m})")
    temp = (np.zeros(len(pos)) if temperature is None else
            np.ascontiguousarray(temperature, dtype=np.float64).reshape(-1))
    if not len(pos):
        return np.zeros((0, 3), np.int32), np.zeros(0, np.float32), (
            None if temperature is None else np.zeros(0, np.float32))
    base = _grid_base(pos, r, h)
    if base.any():  # far from the origin: splat about a whole cell near the particles
        pos = pos - base * h
    counts = _box_counts(pos, r, h)
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    total = int(starts[-1])
    if total > MAX_SPLAT_CELLS:
        raise ValueError(f"{len(pos):,} particles reach {total:,} cells of {h} m in one "
                         f"frame (at most {MAX_SPLAT_CELLS:,})")
    keys = np.empty(total, dtype=np.int64)
    mass = np.zeros(total, dtype=np.float64)
    heat = np.zeros(total, dtype=np.float64)
    _splat_fill(pos, r, a, temp, h, starts, keys, mass, heat)
    cells, inverse = np.unique(keys, return_inverse=True)
    density = np.bincount(inverse, weights=mass, minlength=len(cells))
    keep = density > 0
    cells, density = cells[keep], density[keep]
    mask = (1 << _BITS) - 1
    ijk = np.stack([(cells >> (2 * _BITS)) & mask, (cells >> _BITS) & mask, cells & mask],
                   axis=1) - _OFFSET
    temp_out = None
    if temperature is not None:
        heat_sum = np.bincount(inverse, weights=heat, minlength=len(keep))[keep]
        temp_out = (heat_sum / density).astype(np.float32)
    return (ijk + base).astype(np.int32), density.astype(np.float32), temp_out


def _grid_base(pos: np.ndarray, radius: np.ndarray, h: float) -> np.ndarray:
    """(3,) int64: the cell the splat of particles at ``pos`` (K, 3) m with kernel radii
    ``radius`` (K,) m on ``h`` m cells is done about, so that its packed keys reach them:
    zeros while they lie within the keys' reach of the origin (2^20 cells each way),
    else the cell at the middle of their box. Raises ValueError if their box is wider
    than the keys reach or the cells lie beyond a .vdb file's int32 indices."""
    pad = float(radius.max()) / h + 2
    if float(np.abs(pos).max()) / h + pad < _OFFSET:
        return np.zeros(3, dtype=np.int64)
    lo, hi = pos.min(axis=0) / h, pos.max(axis=0) / h
    if float((hi - lo).max()) / 2 + pad >= _OFFSET:
        raise ValueError(f"particles spread over {float((hi - lo).max()) * h:.3g} m, beyond "
                         f"the volume grid's reach of {2 * _OFFSET:,} cells at {h} m cells")
    if float(np.abs(pos).max()) / h + pad >= (1 << 31) - 1:
        raise ValueError(f"particles {np.abs(pos).max():.3g} m from the origin are beyond "
                         f"the volume grid's int32 cell indices at {h} m cells")
    return np.floor((lo + hi) / 2).astype(np.int64)


def frame_grids(name: str, x: np.ndarray, size: np.ndarray, age_fraction: np.ndarray,
                voxel_m: float) -> list:
    """The grids (:class:`blastvox.export.vdb.FloatGrid`) of one frame of system ``name``:
    its live particles at ``x`` (K, 3) m with diameters ``size`` (K,) m and ages as a
    fraction of their lifetime ``age_fraction`` (K,): ``density``, and for fire and
    fireball ``temperature``."""
    from blastvox.export.vdb import FloatGrid

    look = VOLUME_LOOKS[name]
    hot = look.hot_k is not None and look.cool_k is not None
    temp = (look.hot_k + (look.cool_k - look.hot_k) * np.clip(age_fraction, 0.0, 1.0)
            if hot else None)
    size = np.asarray(size, dtype=np.float64)
    ijk, density, temperature = splat(x, size, cross_section(size, look.tau), voxel_m, temp)
    grids = [FloatGrid("density", ijk, density, voxel_m)]
    if temperature is not None:
        grids.append(FloatGrid("temperature", ijk, temperature, voxel_m, grid_class="unknown"))
    return grids


#: a system's cells are at least its median particle diameter / this (and at least the
#: export's ``volume_voxel_m``): the fireball's 3 m particles need no 0.1 m cells
CELLS_PER_DIAMETER = 4.0


def system_voxel(size: np.ndarray, voxel_m: float) -> float:
    """The cell size (m) of a system whose particles have diameters ``size`` (m):
    max(``voxel_m``, median diameter / CELLS_PER_DIAMETER), rounded to 1 mm."""
    median = float(np.median(size)) if len(size) else 0.0
    return max(float(voxel_m), round(median / CELLS_PER_DIAMETER, 3))


def grid_fields(name: str) -> tuple[str, ...]:
    """The grids a system's volume files hold."""
    look = VOLUME_LOOKS[name]
    return ("density", "temperature") if look.hot_k is not None else ("density",)


def volume_file(directory: str | Path, system: str, frame: int) -> Path:
    """``<directory>/<system>.<frame:04d>.vdb``: the frame number where Blender's volume
    sequences look for it."""
    return Path(directory) / f"{system}.{frame:04d}.vdb"
