"""Fracture faces that read as broken material, not as voxel steps.

A piece's fracture faces are the cell faces it shares with the pieces (or dust)
around it: squares on the lattice, so a crack is a staircase and a one-voxel
piece a cube. For the export (and the preview) :func:`roughen` moves their
corners; the simulation and the pieces' collision stay voxel-based:

1. **Smoothing.** Taubin's lambda|mu smoothing (Taubin 1995, "A signal
   processing approach to fair surface design") of the fracture surface's
   corners: the staircase of a slanted crack becomes a slope, a step's edge a
   chamfer, and, unlike plain Laplacian smoothing, a piece keeps its volume.
2. **Roughness.** Every corner is moved by a smooth random vector field (value
   noise, two octaves, wavelengths of two voxels and one; half a voxel edge
   at most, :data:`ROUGHNESS`), so a face is a broken surface, not a plane, and a
   long straight edge bends.

Corners on the outside (where a crack meets the source surface) only slide in
the surface's plane, and stay where the surface is not flat there (an edge, a
corner, a curve, a T-junction of its triangles): the source surface keeps its
shape, and its texture, which export maps from rest positions, stays in place,
(cube and jittered cells' faces, which only stand for the surface, let a corner
slide in their mean plane where they are within 25 degrees of it),
while a crack's outline on a wall becomes a broken line, not a staircase. Where
the two cells on either side of a face triangulate it differently (conform cells
may), that face stays in place, or the pieces would part there. A corner whose
move would fold a triangle over (turn it by more than 60 degrees) takes half of
it, then a quarter, ...

The fracture surface is one surface shared by the two pieces on either side of
each crack: each corner is moved once per distinct point (by its rest
coordinates), so both faces of a crack move together, the pieces still fit at
rest and each stays closed. The triangles are the same ones (no more are made),
so the files grow only by what a face's own normals and UVs add. Every step is
elementwise IEEE arithmetic or a sparse product in a fixed order: the same bytes
on any machine.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
from scipy.spatial import cKDTree

from blastvox.geometry import exact as products

__all__ = ["ROUGHNESS", "SMOOTHING_PASSES", "roughen"]

#: Largest displacement of a fracture corner by the noise field (voxel edges): enough to
#: bend a slab's straight edge by a quarter of its thickness. A corner whose move would
#: fold a triangle over takes less (:func:`_unfolded`).
ROUGHNESS = 0.5
#: Taubin lambda|mu pass pairs over the fracture corners: two round a one-voxel step into
#: a slope without shrinking the piece (each pair keeps the low frequencies).
SMOOTHING_PASSES = 2
#: Taubin's shrink and inflate factors (Taubin 1995, pass band k_PB = 1/lambda + 1/mu = 0.1).
TAUBIN_LAMBDA = 0.5
TAUBIN_MU = -0.5263

#: Points of the fracture faces closer than this (voxel edges) are one point.
MERGE = 1e-5
#: A triangle folds over when its normal turns so far that its cosine to the rest normal
#: falls below this (about 60 degrees): its points then take less of their move.
FOLD = 0.5
#: A triangle whose height is under this share of its longest side is a sliver: its
#: normal is rounding noise, so it folds only when it also grows (:func:`_folded`).
SLIVER = 1e-2
#: How many times the move of a folding triangle's points is halved before they stay put.
HALVINGS = 6
#: Cube and jittered cells' faces round a point are one rough plane when each normal is
#: within this of their mean in 1 - cos (about 25 degrees: a jittered wall, not its edge).
ROUGH_PLANE = 0.094
#: Outside triangles around a point are one plane when their unit normals differ by less
#: than this in 1 - cos (about 0.003 degrees: a plane's triangles stored in float32).
FLAT = 1e-9

_OCTAVES = ((0.5, 0.7), (1.0, 0.3))  # (frequency per voxel edge, share of ROUGHNESS)


def roughen(triangles: np.ndarray, fracture: np.ndarray, edge: float, seed: int = 0,
            exact: np.ndarray | None = None) -> np.ndarray:
    """Reshape the fracture triangles of a set of piece meshes into rubble surfaces.

    triangles (T, 3, 3) float64: every piece's triangles at rest (m, the model frame);
    fracture (T,) bool: the fracture (inside) faces; edge: the voxel edge (m) that
    scales the roughness; seed: the noise field's seed; exact (T,) bool: the outside
    triangles that are the input's own surface (conform cells' surface triangles),
    which a point leaves only where they are flat; the others (cube and jittered
    cells' faces, which stand for the surface) let it slide where they are nearly so
    (default: all exact).

    Returns the triangles (T, 3, 3), in their order, with their points moved: the
    fracture triangles' points, and the outside triangles' points where a crack meets
    the outside (in their plane).
    """
    triangles = np.asarray(triangles, dtype=np.float64)
    fracture = np.asarray(fracture, dtype=bool)
    exact = np.ones(len(triangles), dtype=bool) if exact is None else np.asarray(exact, bool)
    broken, whole = np.flatnonzero(fracture), np.flatnonzero(~fracture)
    if len(broken) == 0 or not edge > 0:
        return triangles.copy()
    tolerance = MERGE * edge
    points, corner, index = _distinct_points(triangles[broken].reshape(-1, 3), tolerance)
    corner = corner.reshape(-1, 3)
    outside = triangles[whole]
    outside_corner = _lookup(index, outside.reshape(-1, 3), tolerance).reshape(-1, 3)
    normal, limit = _sliding(points, outside, outside_corner, exact[whole])
    limit[corner[_unpaired(corner)].ravel()] = 0.0
    smoothed = _taubin(points, corner, normal, limit)
    offset = smoothed - points + _constrained(_noise(smoothed / edge, seed) * (ROUGHNESS * edge),
                                              normal, limit)
    moved = _unfolded(points, offset, corner, triangles[broken], outside, outside_corner)
    out = triangles.copy()
    out[broken] = moved[corner]
    shell = out[whole]
    has = outside_corner >= 0
    shell[has] = moved[outside_corner[has]]
    out[whole] = shell
    return out


def _unpaired(corner: np.ndarray) -> np.ndarray:
    """(F,) bool: fracture triangles (F, 3) of point ids that are not one of a pair.

    A cell face is drawn by the voxels on both sides of it; two conform cells may
    triangulate it each their own way. Such a face must stay in place (its points do
    not move), or the two triangulations, moved apart, would open a gap between the
    pieces."""
    key = np.sort(corner, axis=1)
    _, which, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return count[which.ravel()] != 2


def _distinct_points(points: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray,
                                                                     cKDTree]:
    """The distinct points of ``points`` (P, 3), those closer than ``tolerance`` (m) taken
    as one (a mesh's conform cells can meet at points a few float32 ulps apart).

    Returns (distinct (D, 3): for each, the lowest of its points in sorted order;
    label (P,): each input row's distinct point; (tree, labels) to look more up with
    :func:`_lookup`)."""
    exact, inverse = np.unique(np.ascontiguousarray(points + 0.0), axis=0, return_inverse=True)
    tree = cKDTree(exact)
    pairs = tree.query_pairs(tolerance, output_type="ndarray")
    graph = scipy.sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                                    shape=(len(exact), len(exact)))
    _, labels = scipy.sparse.csgraph.connected_components(graph, directed=False)
    first = np.full(labels.max() + 1, len(exact))
    np.minimum.at(first, labels, np.arange(len(exact)))
    return exact[first], labels[inverse.ravel()], (tree, labels)


def _lookup(index: tuple, others: np.ndarray, tolerance: float) -> np.ndarray:
    """(Q,) int64: the distinct point (of :func:`_distinct_points`' ``index``) within
    ``tolerance`` of each row of ``others`` (Q, 3), -1 where there is none."""
    tree, labels = index
    if len(others) == 0:
        return np.zeros(0, dtype=np.int64)
    _, at = tree.query(others, k=1, distance_upper_bound=tolerance)
    found = at < len(labels)
    return np.where(found, labels[np.minimum(at, len(labels) - 1)], -1).astype(np.int64)


def _sliding(points: np.ndarray, outside: np.ndarray, outside_corner: np.ndarray,
             exact: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How each fracture point (P, 3) may move: (normal (P, 3), limit (P,) m).

    A point inside the solid moves freely (normal 0, limit inf). A point on the
    outside (a corner of outside triangles ``outside`` (Q, 3, 3) whose corners are
    fracture points ``outside_corner`` (Q, 3), -1 for none) slides in the plane of
    those triangles where they close a fan round it and are all one plane (normal:
    that plane's), or, where none of them is ``exact`` (Q,) (the input's own
    surface; cube and jittered cells' faces stand for it), all within
    :data:`ROUGH_PLANE` of their mean plane; where they do not (an edge or a corner
    of the solid, a curved surface, a T-junction, a crack whose other side is dust)
    it stays (limit 0)."""
    count = len(points)
    normal = np.zeros((count, 3))
    limit = np.full(count, np.inf)
    tri, at = np.nonzero(outside_corner >= 0)
    if len(tri) == 0:
        return normal, limit
    point = outside_corner[tri, at]
    unit = _unit_normals(outside)
    order = np.lexsort((unit[tri, 2], unit[tri, 1], unit[tri, 0], point))  # by value: any order
    point, tri = point[order], tri[order]
    head = np.ones(len(point), dtype=bool)
    head[1:] = point[1:] != point[:-1]
    mean = np.zeros((count, 3))
    for axis in range(3):  # sums in that order: the same bytes whatever the input's order
        mean[:, axis] = np.bincount(point, weights=unit[tri, axis], minlength=count)
    length = products.length(mean, keepdims=True)
    mean = np.divide(mean, length, out=np.zeros_like(mean), where=length > 0)
    first = np.zeros((count, 3))
    first[point[head]] = unit[tri[head]]
    spread = np.zeros(count)
    np.maximum.at(spread, point, 1.0 - products.lane_dot(unit[tri], first[point]))
    tilt = np.zeros(count)
    np.maximum.at(tilt, point, 1.0 - products.lane_dot(unit[tri], mean[point]))
    any_exact = np.zeros(count, dtype=bool)
    any_exact[point[exact[tri]]] = True
    on = np.zeros(count, dtype=bool)
    on[point] = True
    closed = _closed_fans(outside, outside_corner, count)
    flat = on & closed & (spread <= FLAT)
    rough = on & closed & ~flat & ~any_exact & (tilt <= ROUGH_PLANE)
    limit[on & ~(flat | rough)] = 0.0
    normal[flat] = first[flat]
    normal[rough] = mean[rough]
    return normal, limit


def _closed_fans(outside: np.ndarray, outside_corner: np.ndarray, count: int) -> np.ndarray:
    """(count,) bool: the fracture points round which the outside triangles (Q, 3, 3),
    their fracture corners ``outside_corner`` (Q, 3) (-1 for none), close a fan: every
    side from the point is run once each way, so moving it in their plane opens no gap."""
    ids = outside_corner.copy()
    other = ids < 0
    if other.any():  # outside corners on no crack: their own ids, after the P fracture points
        _, own = np.unique(np.ascontiguousarray(outside[other] + 0.0), axis=0,
                           return_inverse=True)
        ids[other] = count + own.ravel()
    tri, at = np.nonzero(outside_corner >= 0)
    point = ids[tri, at]
    width = int(ids.max()) + 1
    leaving = np.sort(point * width + ids[tri, (at + 1) % 3])
    arriving = np.sort(point * width + ids[tri, (at + 2) % 3])
    closed = np.ones(count, dtype=bool)
    closed[leaving[leaving != arriving] // width] = False
    closed[arriving[leaving != arriving] // width] = False
    return closed


def _folded(triangles: np.ndarray, rest: np.ndarray, sliver: np.ndarray) -> np.ndarray:
    """(T,) bool: which triangles (T, 3, 3) fold over against their rest triangles'
    area-weighted normals ``rest`` (T, 3): a triangle whose normal turns until its cosine
    is under :data:`FOLD`; a sliver (``sliver`` (T,)), whose side is rounding noise, only
    when it turns over and grows to more than twice its rest area (when it would show)."""
    now = _doubled_normals(triangles)
    dot = products.lane_dot(now, rest)
    size_now, size_rest = products.length(now), products.length(rest)
    turned = dot < FOLD * size_now * size_rest
    return np.where(sliver, (dot < 0.0) & (size_now > 2.0 * size_rest), turned & (size_rest > 0))


def _doubled_normals(triangles: np.ndarray) -> np.ndarray:
    """Normals (T, 3) of triangles (T, 3, 3), their length twice the area."""
    return np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])


def _slivers(triangles: np.ndarray) -> np.ndarray:
    """(T,) bool: triangles (T, 3, 3) whose height is under :data:`SLIVER` of their
    longest side (degenerate ones included)."""
    doubled = products.length(np.cross(triangles[:, 1] - triangles[:, 0],
                                       triangles[:, 2] - triangles[:, 0]))
    longest = np.max(products.length(triangles - np.roll(triangles, 1, axis=1)), axis=1)
    return ~(doubled > SLIVER * longest * longest)


def _unit_normals(triangles: np.ndarray) -> np.ndarray:
    """Unit normals (T, 3) of triangles (T, 3, 3); 0 for a degenerate one."""
    face = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = products.length(face, keepdims=True)
    return np.divide(face, length, out=np.zeros_like(face), where=length > 0)


def _unfolded(points: np.ndarray, offset: np.ndarray, corner: np.ndarray,
              fracture: np.ndarray, outside: np.ndarray,
              outside_corner: np.ndarray) -> np.ndarray:
    """The moved points (P, 3): each point (P, 3) plus as much of its ``offset`` (P, 3) as
    folds no triangle over.

    ``corner`` (F, 3): the fracture triangles' point ids (``fracture`` (F, 3, 3) at
    rest); ``outside`` (Q, 3, 3): the outside triangles, their fracture corners
    ``outside_corner`` (Q, 3) (-1 for none). A triangle that folds (:func:`_folded`)
    halves what its points take, up to :data:`HALVINGS` times, and then they take
    nothing."""
    scale = np.ones(len(points))
    touched = np.flatnonzero((outside_corner >= 0).any(axis=1))
    outside, outside_corner = outside[touched], outside_corner[touched]
    has = outside_corner >= 0
    rest_fracture, rest_outside = _doubled_normals(fracture), _doubled_normals(outside)
    fracture_sliver, outside_sliver = _slivers(fracture), _slivers(outside)
    halving = 0
    while True:
        moved = points + offset * scale[:, None]
        shell = outside.copy()
        shell[has] = moved[outside_corner[has]]
        culprits = np.concatenate([
            corner[_folded(moved[corner], rest_fracture, fracture_sliver)].ravel(),
            outside_corner[_folded(shell, rest_outside, outside_sliver)].ravel()])
        culprits = np.unique(culprits[culprits >= 0])
        culprits = culprits[scale[culprits] > 0]
        if len(culprits) == 0:  # none folds, or what folds is back at rest and cannot
            return moved
        scale[culprits] = 0.0 if halving >= HALVINGS else 0.5 * scale[culprits]
        halving += 1


def _constrained(offset: np.ndarray, normal: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """``offset`` (P, 3) with its component along ``normal`` (P, 3) removed and its
    length cut to ``limit`` (P,)."""
    offset = offset - normal * products.lane_dot(offset, normal)[:, None]
    length = products.length(offset)
    scale = np.minimum(1.0, np.divide(limit, length, out=np.ones_like(length),
                                      where=length > limit))
    return offset * scale[:, None]


def _adjacency(corner: np.ndarray, count: int) -> scipy.sparse.csr_matrix:
    """Row-normalised adjacency (count, count) of the triangles' (F, 3) point graph:
    row i averages the points that share an edge with point i."""
    edges = np.unique(np.sort(corner[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    degree = np.bincount(rows, minlength=count).astype(np.float64)
    return scipy.sparse.csr_matrix((1.0 / degree[rows], (rows, cols)), shape=(count, count))


def _taubin(points: np.ndarray, corner: np.ndarray, normal: np.ndarray,
            limit: np.ndarray) -> np.ndarray:
    """Taubin-smoothed ``points`` (P, 3) over the triangles ``corner`` (F, 3), each
    point's move constrained as :func:`_sliding` allows (normal (P, 3), limit (P,))."""
    mean = _adjacency(corner, len(points))
    moved = points
    for _ in range(SMOOTHING_PASSES):
        for factor in (TAUBIN_LAMBDA, TAUBIN_MU):
            moved = moved + factor * (mean @ moved - moved)  # sparse: rows in order
            moved = points + _constrained(moved - points, normal, limit)
    return moved


def _noise(x: np.ndarray, seed: int) -> np.ndarray:
    """A smooth random vector field (P, 3), each component in [-1, 1], at points ``x``
    (P, 3) in voxel edges: value noise (C1 Hermite-blended lattice values), two octaves."""
    field = np.zeros_like(x)
    for octave, (frequency, share) in enumerate(_OCTAVES):
        field += share * _value_noise(x * frequency, seed * 2 + octave)
    return field


def _value_noise(x: np.ndarray, seed: int) -> np.ndarray:
    """Value noise (P, 3) in [-1, 1] at ``x`` (P, 3) (lattice units): random values at
    the integer lattice points (one per component), blended by a C1 Hermite weight."""
    cell = np.floor(x)
    f = x - cell
    w = f * f * (3.0 - 2.0 * f)
    cell = cell.astype(np.int64)
    out = np.zeros_like(x)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                weight = (np.where(dx, w[:, 0], 1.0 - w[:, 0])
                          * np.where(dy, w[:, 1], 1.0 - w[:, 1])
                          * np.where(dz, w[:, 2], 1.0 - w[:, 2]))
                value = _lattice_values(cell + np.array([dx, dy, dz]), seed)
                out += weight[:, None] * value
    return out


def _lattice_values(cell: np.ndarray, seed: int) -> np.ndarray:
    """Random values (P, 3) in [-1, 1] of integer lattice points (P, 3): a SplitMix64
    hash of the point, the component and the seed."""
    c = cell.astype(np.uint64)
    base = (c[:, 0] * np.uint64(0x9E3779B97F4A7C15) ^ c[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F)
            ^ c[:, 2] * np.uint64(0x165667B19E3779F9) ^ np.uint64(seed & 0xFFFFFFFF))
    out = np.empty((len(c), 3))
    for axis in range(3):
        z = base + np.uint64((axis + 1) * 0x9E3779B97F4A7C15 % 2**64)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
        out[:, axis] = (z >> np.uint64(11)).astype(np.float64) * (2.0 / 2.0**53) - 1.0
    return out
