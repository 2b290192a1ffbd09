"""Region rules: let an artist change material or strength inside a box, sphere or half-space.

Martins 2001 §4.2: "a game designer may want a specific building wall to be
easily destroyed"; a rule assigns a material and/or scales the yield limits
of every voxel whose centroid lies in its region. Rules apply in order; later
rules win for the material and the chunk size, strength scales multiply.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RegionRule:
    """One rule. ``kind`` is "box" (lo, hi), "sphere" (centre, radius) or
    "halfspace" (point, normal; inside where (x - point) . normal >= 0).
    Coordinates in metres in the model frame. chunk_size: m, the mean chunk size
    inside (0: no chunks; None: unchanged), see :mod:`blastvox.voxelize.chunks`."""

    kind: str
    a: tuple[float, float, float]
    b: tuple[float, float, float] | float
    material: str | None = None
    strength_scale: float = 1.0
    chunk_size: float | None = None

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Boolean mask (N,) of the points (N, 3) inside the region."""
        p = np.asarray(points, dtype=np.float64)
        a = np.asarray(self.a, dtype=np.float64)
        if self.kind == "box":
            b = np.asarray(self.b, dtype=np.float64)
            return np.all((p >= np.minimum(a, b)) & (p <= np.maximum(a, b)), axis=1)
        if self.kind == "sphere":
            return np.sum((p - a) ** 2, axis=1) <= float(self.b) ** 2
        if self.kind == "halfspace":
            return (p - a) @ np.asarray(self.b, dtype=np.float64) >= 0.0
        raise ValueError(f"unknown region kind {self.kind!r}")
