"""The stress solver's springs: each link's stiffness and strength limits.

A link takes the limits of its weaker material (as the voxelizer chose it for
the link yield: the lower link_yield_mean), scaled by the link's yield over
that material's mean yield, so the random spread, the scene's strength_scale
and chunk bonds scale the stress limits as they scale the blast yield. Its
modulus is Young's modulus of its two halves (centroid to shared face) in
series.

A run keeps no per-link column of them: :class:`SpringTable` works them out
from the VoxelModel's arrays for the links a solve asks for (an interface's, a
body's), with the same arithmetic, so the values are the same to the bit. At a
million voxels the five float64 columns took 113 MiB, and building them another
200 MiB at the run's start.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from blastvox.simulate.model import link_strength_factor


class LinkSprings(NamedTuple):
    """What the stress solver needs of a set of links, one row each.

    midpoint (L, 3) m; direction (L, 3) unit, first voxel to second; area (L,) m^2;
    modulus (L,) Pa: Young's modulus of the link (its two halves in series);
    tensile, compressive, shear (L,) Pa: the limits (inf: never).
    """

    midpoint: np.ndarray
    direction: np.ndarray
    area: np.ndarray
    modulus: np.ndarray
    tensile: np.ndarray
    compressive: np.ndarray
    shear: np.ndarray

    def rows(self, links) -> LinkSprings:
        """The springs of ``links`` (ids or a slice of these rows)."""
        return LinkSprings(*(column[links] for column in self))


class Column:
    """One per-link column of a :class:`SpringTable`, worked out for the links it is
    indexed with (``table.tensile[links]``), like an array's rows."""

    __slots__ = ("_rows",)

    def __init__(self, rows: Callable[[np.ndarray | slice], np.ndarray]) -> None:
        self._rows = rows

    def __getitem__(self, links) -> np.ndarray:
        return self._rows(links)


def _column(arrays: dict, name: str, default: float, count: int) -> np.ndarray:
    values = arrays.get(f"material_{name}")
    if values is None:
        return np.full(count, default)
    return np.asarray(values, dtype=np.float64)


class SpringTable:
    """The springs of a VoxelModel's L links (``arrays``), worked out on demand:
    ``midpoint`` and ``direction`` are the model's arrays, ``area``, ``modulus``,
    ``tensile``, ``compressive`` and ``shear`` :class:`Column` s, and ``rows(links)``
    the :class:`LinkSprings` of ``links``."""

    def __init__(self, arrays: dict) -> None:
        self.arrays = arrays
        self.link_voxels = np.asarray(arrays["link_voxels"]).reshape(-1, 2)
        self.material = np.asarray(arrays["voxel_material"])
        self.centroid = np.asarray(arrays["voxel_centroid"], dtype=np.float64)
        self.midpoint = np.ascontiguousarray(np.asarray(
            arrays["link_midpoint"], dtype=np.float64).reshape(-1, 3))
        self.direction = np.ascontiguousarray(np.asarray(
            arrays["link_direction"], dtype=np.float64).reshape(-1, 3))
        self.link_area = np.asarray(arrays["link_area"], dtype=np.float64)
        self.mean = np.asarray(arrays["material_link_yield_mean"], dtype=np.float64)
        count = len(self.mean)
        self.youngs = _column(arrays, "youngs_modulus", 30e9, count)
        self.limits = {name: _column(arrays, f"{name}_strength", math.inf, count)
                       for name in ("tensile", "compressive", "shear")}
        self.fill = fill_fractions(arrays)
        self.area = Column(self._area)
        self.modulus = Column(self._modulus)
        self.tensile = Column(lambda links: self._limit("tensile", links))
        self.compressive = Column(lambda links: self._limit("compressive", links))
        self.shear = Column(lambda links: self._limit("shear", links))

    def rows(self, links) -> LinkSprings:
        """The springs of ``links`` (ids, or a slice: ``slice(None)`` for all)."""
        return LinkSprings(self.midpoint[links], self.direction[links], self.area[links],
                           self.modulus[links], self.tensile[links], self.compressive[links],
                           self.shear[links])

    def _area(self, links) -> np.ndarray:
        """The links' areas of solid: the lattice face's, times the fuller of its two
        voxels' fill fractions (:func:`fill_fractions`)."""
        ends = self.link_voxels[links]
        return np.maximum(self.link_area[links] * np.maximum(self.fill[ends[:, 0]],
                                                             self.fill[ends[:, 1]]), 1e-12)

    def _materials(self, links) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The links' voxels (K, 2) and their two materials (K,) each."""
        ends = self.link_voxels[links]
        return ends, self.material[ends[:, 0]], self.material[ends[:, 1]]

    def _limit(self, name: str, links) -> np.ndarray:
        """The links' limit ``name``: the weaker material's, times the link's factor
        (:func:`~blastvox.simulate.model.link_strength_factor`)."""
        factor, weaker = link_strength_factor(self.arrays, links)
        return self.limits[name][weaker] * factor

    def _modulus(self, links) -> np.ndarray:
        """The links' modulus: their two halves, centroid to shared face, in series."""
        ends, la, lb = self._materials(links)
        midpoint, direction = self.midpoint[links], self.direction[links]
        half_a = np.abs(np.einsum("ij,ij->i", midpoint - self.centroid[ends[:, 0]], direction))
        half_b = np.abs(np.einsum("ij,ij->i", self.centroid[ends[:, 1]] - midpoint, direction))
        length = np.maximum(half_a + half_b, 1e-12)
        return length / (np.maximum(half_a, 0.0) / self.youngs[la] + np.maximum(half_b, 0.0)
                         / self.youngs[lb] + 1e-300)


def fill_fractions(arrays: dict) -> np.ndarray:
    """(N,) each voxel's solid over its lattice cell: its mass over its material's
    density times its polyhedron's volume (1 where the model has no volumes).

    A cube voxel keeps its cell's shape but weighs the solid inside it
    (:mod:`blastvox.voxelize.fill`): the top row of a 0.5 m beam in 0.2 m cubes holds
    half its cell, and a row that took a dropped cell's solid more than its own. A
    link's area of solid is the lattice face's times the fuller of its two voxels'
    fractions: along a cut layer both ends hold the same fraction of their faces, and
    across it the full voxel's face is solid. So a member's section (its area and
    second moment) is its mesh's at any voxel size, not the lattice's: the beam's root
    read 0.58 x beam theory at 0.2 m (a 0.6 m section of full faces), 1.0 at 0.25 m."""
    volume = arrays.get("voxel_volume")
    n = len(arrays["voxel_mass"])
    if volume is None:
        return np.ones(n)
    density = np.asarray(arrays["material_density"], dtype=np.float64)[
        np.asarray(arrays["voxel_material"])]
    cell = np.asarray(volume, dtype=np.float64) * density
    mass = np.asarray(arrays["voxel_mass"], dtype=np.float64)
    return np.where(cell > 0.0, mass / np.where(cell > 0.0, cell, 1.0), 1.0)


def link_springs(arrays: dict) -> LinkSprings:
    """Every link's springs from VoxelModel ``arrays``, as arrays (L rows)."""
    return SpringTable(arrays).rows(slice(None))


def has_limits(springs: LinkSprings | SpringTable) -> bool:
    """Can any link break under stress (a finite limit)?"""
    return any(bool(np.isfinite(column[:]).any())
               for column in (springs.tensile, springs.compressive, springs.shear))
