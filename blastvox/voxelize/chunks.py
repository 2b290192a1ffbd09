"""Chunks: irregular groups of voxels, so that debris breaks into rubble, not cubes.

voxelize groups the voxels of each *region* -- a set of voxels connected through
links whose two voxels share a material and a chunk size -- into chunks:

1. Seeds. A region of volume V (m^3), chunk size s (m) and largest extent L
   (m, its box's longest side) gets K = max(1, round(V / s^3), round(L / s))
   seeds (at most one per voxel), voxels drawn uniformly from the region. For a
   bulky region the first term rules, so the mean chunk's volume is s^3: s is
   the mean chunk's equivalent cube side. The second rules a slender one (a
   column, a rod, a beam: a cross-section under s^2), whose chunks are then
   about s long: by volume alone a 3 m column 0.2 m across was one chunk, which
   a crushing material never breaks.
2. Sizes. Each seed draws a relative volume x from a Weibull distribution of
   modulus ``chunk_weibull`` (Grady & Kipp 1985 fragment statistics: a small
   modulus spreads the sizes, a large one makes them even) and grows at speed
   x^(1/3), so a seed that is to become a large chunk claims space faster.
3. Cells. The seeds grow along the links at their speeds, through the link
   lengths (centroid to centroid, m): a multiplicatively weighted graph Voronoi
   by "crystal growth" (:mod:`blastvox.voxelize.chunks_nb`). Chunks follow the
   link graph, so they never jump across a gap or through a cavity, and every
   chunk is connected through its links.
4. Relaxation. :data:`LLOYD_STEPS` Lloyd steps move each seed to its chunk's
   voxel nearest the chunk's centroid and grow again: fewer slivers, rounder
   chunks, and the spread of the sizes comes mostly from the Weibull draw.

A chunk size of 0, or below one voxel (the cube root of the lattice cell's
volume), makes every voxel its own chunk. Links inside a chunk are
``chunk_bond_scale`` times stronger (see :func:`bond_factor`), so fracture runs
along chunk boundaries first.

The chunk size of a voxel is, in order: the last region rule containing it that
sets ``chunk_size``, the object's ``chunk_size``, the material's. Randomness comes
from the generator the caller passes (the model seed), never the global one.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from blastvox.bounds import printable
from blastvox.errors import BlastvoxError
from blastvox.voxelize.chunks_nb import grow, link_graph, recentre
from blastvox.voxelize.components import component_labels

#: Lloyd relaxation steps after the first growth (each one regrows every chunk).
LLOYD_STEPS = 2
#: Relative tolerance of the comparisons with one voxel and the object's extent.
_TOLERANCE = 1e-9


def requested_sizes(request: Any, centroid: np.ndarray) -> np.ndarray:
    """Chunk size (m) the scene or command line asks for, per voxel (N,) float64.

    ``request``: an :class:`~blastvox.voxelize.pipeline.ObjectRequest`; ``centroid``
    (N, 3) m: its voxels' centroids, which its rules test. NaN where neither the
    object nor a rule sets one (the material's ``chunk_size`` applies).
    """
    default = np.nan if request.chunk_size is None else float(request.chunk_size)
    sizes = np.full(len(centroid), default)
    for rule in request.rules:
        if rule.chunk_size is not None:
            sizes[rule.contains(centroid)] = float(rule.chunk_size)
    return sizes


def check_request(request: Any, spacing: np.ndarray, bounds: np.ndarray) -> None:
    """Refuse a requested chunk size below one voxel (other than 0) or above the
    object's largest extent: one-line :class:`BlastvoxError` naming the key or flag.

    spacing (3,) m: the lattice spacing; bounds (2, 3) m: the object's box.
    """
    side = float(np.cbrt(np.prod(spacing)))
    extent = float(np.max(bounds[1] - bounds[0]))
    mesh = printable(request.mesh)
    settings = [(f"{request.origin}.chunk_size" if request.origin else
                 f"{mesh}: --chunk-size", request.chunk_size)]
    for j, rule in enumerate(request.rules):
        key = f"rules[{j}].chunk_size"
        settings.append((f"{request.origin}.{key}" if request.origin else f"{mesh}: {key}",
                         rule.chunk_size))
    for where, size in settings:
        if size is None or size == 0:
            continue
        if size < side * (1.0 - _TOLERANCE):
            raise BlastvoxError(f"{where}: {size:g} m is below one voxel ({side:.4g} m); "
                                f"use 0 (no chunks) or at least one voxel")
        if size > extent * (1.0 + _TOLERANCE):
            raise BlastvoxError(f"{where}: {size:g} m is above the object's largest extent "
                                f"({extent:.4g} m)")


def group(material: np.ndarray, requested: np.ndarray, side: np.ndarray, volume: np.ndarray,
          centroid: np.ndarray, link_voxels: np.ndarray, table: Mapping[str, np.ndarray],
          rng: np.random.Generator) -> np.ndarray:
    """The chunk of every voxel (module doc): voxel_chunk (N,) int32 in [0, K).

    material (N,) material index; requested (N,) m, NaN for the material's
    ``chunk_size`` (:func:`requested_sizes`); side (N,) m, one voxel: the cube root
    of its lattice cell's volume; volume (N,) m^3; centroid (N, 3) m; link_voxels
    (L, 2); table: the material table (``material_chunk_size`` and
    ``material_chunk_weibull``, (M,)). Chunks are numbered in order of their lowest
    voxel. Deterministic for the same inputs and generator state.
    """
    n = len(material)
    mat = np.asarray(material, dtype=np.int64)
    size = np.where(np.isnan(requested), _column(table, "material_chunk_size", 0.0)[mat],
                    requested)
    active = (size > 0.0) & (size >= side * (1.0 - _TOLERANCE))
    lv = np.asarray(link_voxels, dtype=np.int64).reshape(-1, 2)
    a, b = lv[:, 0], lv[:, 1]
    inner = active[a] & active[b] & (mat[a] == mat[b]) & (size[a] == size[b])
    region = component_labels(lv[inner], n)  # numbered by lowest voxel
    seeds, speed = _seeds(region, active, size, volume, _extents(region, centroid, side),
                          mat, table, rng)
    label = np.full(n, -1, dtype=np.int64)
    if len(seeds):
        d = centroid[b[inner]] - centroid[a[inner]]
        graph = link_graph(n, a[inner], b[inner], np.sqrt(np.einsum("ij,ij->i", d, d)))
        label = grow(*graph, seeds, speed)
        for _ in range(LLOYD_STEPS):
            seeds = recentre(label, np.asarray(volume, dtype=np.float64),
                             np.ascontiguousarray(centroid, dtype=np.float64), len(seeds))
            label = grow(*graph, seeds, speed)
    alone = label < 0
    label[alone] = len(seeds) + np.arange(int(alone.sum()))
    return _by_lowest_voxel(label)


def _column(table: Mapping[str, np.ndarray], key: str, default: float) -> np.ndarray:
    """A material column, or ``default`` for every material if the table lacks it."""
    if key in table:
        return np.asarray(table[key], dtype=np.float64)
    return np.full(len(table["material_density"]), default)


def _extents(region: np.ndarray, centroid: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Largest extent (R,) m of each region's box: the longest side of the box of its
    voxels' centroids, plus one voxel (``side`` (N,) m) for the half voxel at each end."""
    regions = int(region.max()) + 1 if len(region) else 0
    low = np.full((regions, 3), np.inf)
    high = np.full((regions, 3), -np.inf)
    np.minimum.at(low, region, centroid)
    np.maximum.at(high, region, centroid)
    return (high - low).max(axis=1) + np.bincount(region, weights=side) / np.bincount(region)


def _seeds(region: np.ndarray, active: np.ndarray, size: np.ndarray, volume: np.ndarray,
           extent: np.ndarray, mat: np.ndarray, table: Mapping[str, np.ndarray],
           rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Seed voxels (K,) int64 of every active region and their growth speeds (K,);
    extent (R,) m: each region's largest extent (:func:`_extents`)."""
    n = len(region)
    if not active.any():
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    count = np.bincount(region)
    first = np.flatnonzero(np.r_[True, region[1:] > np.maximum.accumulate(region)[:-1]])
    total = np.bincount(region, weights=volume)
    edge = np.where(active[first], size[first], 1.0)
    wanted = np.floor(np.maximum(total / edge ** 3, extent / edge) + 0.5)
    k = np.where(active[first], np.clip(wanted, 1, count), 0).astype(np.int64)
    order = np.lexsort((rng.random(n), region))
    start = np.cumsum(count) - count
    rank = np.arange(n) - start[region[order]]
    seeds = order[rank < k[region[order]]]
    modulus = _column(table, "material_chunk_weibull", 2.0)[mat[seeds]]
    draw = rng.weibull(modulus) if len(seeds) else np.zeros(0)
    return seeds.astype(np.int64), np.cbrt(np.maximum(draw, 1e-12))


def _by_lowest_voxel(label: np.ndarray) -> np.ndarray:
    """Relabel (N,) labels 0..K-1 in order of each label's lowest voxel, as int32."""
    _, first, inverse = np.unique(label, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return rank[inverse.ravel()].astype(np.int32)


def bond_factor(voxel_chunk: np.ndarray, link_voxels: np.ndarray,
                scale: np.ndarray) -> np.ndarray:
    """Factor (L,) on each link's yield: ``scale`` (L,) (the chunk_bond_scale of the
    link's weaker material) inside a chunk, 1 between chunks."""
    lv = np.asarray(link_voxels, dtype=np.int64).reshape(-1, 2)
    inside = voxel_chunk[lv[:, 0]] == voxel_chunk[lv[:, 1]]
    return np.where(inside, np.asarray(scale, dtype=np.float64), 1.0)


def statistics(voxel_chunk: np.ndarray, volume: np.ndarray) -> dict[str, float]:
    """Chunk count, mean voxels per chunk, mean chunk volume (m^3), its equivalent
    cube side (m) and the coefficient of variation of the chunk volumes."""
    volumes = np.bincount(voxel_chunk, weights=volume)
    mean = float(volumes.mean())
    return {"chunks": len(volumes), "voxels_per_chunk": len(voxel_chunk) / len(volumes),
            "mean_volume_m3": mean, "mean_side_m": float(np.cbrt(mean)),
            "volume_cv": float(volumes.std() / mean) if mean > 0 else 0.0}
