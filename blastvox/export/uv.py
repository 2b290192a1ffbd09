"""Texture coordinates and normals of the pieces' faces: the source look outside, box UVs inside.

Every triangle of :func:`blastvox.export.pieces.piece_meshes` gets UVs and normals
at its three corners, computed in rest space (the intact model's frame), so they
stay put as the pieces move:

* an exterior face of an input that had a texture (the VoxelModel's source look,
  :mod:`blastvox.voxelize.look`) takes the UVs of the source triangle nearest to
  its centroid (the exact nearest, whatever the triangles' shapes, among the
  triangles of the face's own input part where the model records parts), by
  barycentric coordinates of each corner in that triangle's plane: exact for
  conform faces (they are pieces of the source triangles), a projection for
  jittered and cube cells. Its texture index is that triangle's;
* every other face (fracture faces, untextured inputs, faces farther from the
  source surface than ``REACH`` voxel edges) gets box UVs: the two rest
  coordinates (m) across the axis its normal points along most, 1 UV unit per
  metre, continuous across a piece's faces that share that axis; texture -1;
* an exterior face near the source surface takes the source's smooth corner
  normals the same way (barycentric, renormalized), so a curved input shades
  smoothly and a jittered or cube cell shades like the surface it stands for;
  every other face, and one that would face away from its own normal, keeps its
  flat face normal.

UVs use the OpenGL convention (origin bottom left, v up), as USD's ``st``;
glTF writers flip v.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from trimesh.triangles import area, closest_point, points_to_barycentric

from blastvox.cache import SimCache
from blastvox.export.names import identifier, unique
from blastvox.export.pieces import PieceMeshes
from blastvox.geometry import exact, fixed

#: How far (in voxel edges) a face's centroid may lie from the source surface and still
#: take its texture. A cube cell is kept when its centre is inside, so the steps of a
#: staircase along a slanted surface put outside faces up to about sqrt(3) edges from
#: it; with less, those steps showed the flat material colour in stripes.
REACH = 2.0
#: A source triangle whose height is under this fraction of its longest edge (a sliver, or
#: collinear corners) maps no texture: barycentric coordinates off it blow up.
SLIVER = 1e-3
#: Texture coordinates at or beyond this magnitude are taken as a failed mapping (box
#: UVs instead): a real UV layout is within a few hundred tiles of 0.
MAX_UV = 1e6
#: Triangles with the nearest centroids measured first: the nearest of them bounds the
#: exact search (:func:`nearest_triangles`).
CANDIDATES = 8


def texture_names(cache: SimCache) -> list[str]:
    """File-name and identifier safe, unique names of the model's textures (by index)."""
    taken: set[str] = set()
    return [unique(identifier(str(texture.get("name", "")), f"texture_{k}"), taken)
            for k, texture in enumerate(cache.model.textures)]


@dataclass(frozen=True)
class FaceUVs:
    """uv (T, 3, 2) float32 per triangle corner; texture (T,) int32 (-1: none);
    normal (T, 3, 3) float32 unit corner normals, export frame (a zero-area
    triangle's are 0)."""

    uv: np.ndarray
    texture: np.ndarray
    normal: np.ndarray


def face_uvs(cache: SimCache, meshes: PieceMeshes) -> FaceUVs:
    """UVs, texture index and corner normals of every triangle of ``meshes`` (see the
    module doc)."""
    rest = meshes.rest
    uv = box_uvs(rest)
    texture = np.full(len(rest), -1, dtype=np.int32)
    normal = np.repeat(meshes.normals[:, None, :], 3, axis=1)
    a = cache.model.arrays
    outside = np.flatnonzero(~meshes.damage)
    usable = _usable(a["surface_triangles"]) if "surface_triangles" in a else np.zeros(0, int)
    if usable.size and outside.size:
        edge = fixed.cbrt(a["voxel_volume"][meshes.voxel[outside]])
        parts = "voxel_part" in a and "surface_part" in a  # a face maps onto its own part
        nearest, _ = nearest_triangles(
            a["surface_triangles"][usable], rest[outside].mean(axis=1), REACH * edge,
            a["surface_part"][usable] if parts else None,
            a["voxel_part"][meshes.voxel[outside]] if parts else None)
        near = nearest >= 0
        faces, source = outside[near], usable[nearest[near]]
        bary = _barycentric(a["surface_triangles"][source], rest[faces])
        mapped = exact.mix(bary, a["surface_uv"][source])
        # a texture coordinate a float32 holds (the source's own UVs may be anything)
        textured = (a["surface_texture"][source] >= 0) & (
            np.abs(mapped) < MAX_UV).all(axis=(1, 2))
        texture[faces[textured]] = a["surface_texture"][source[textured]]
        uv[faces[textured]] = mapped[textured].astype(np.float32)
        if "surface_normals" in a:
            normal[faces] = _smooth_normals(bary, a["surface_normals"][source],
                                            meshes.change, normal[faces])
    return FaceUVs(uv=uv, texture=texture, normal=normal.astype(np.float32))


def box_uvs(triangles: np.ndarray) -> np.ndarray:
    """(T, 3, 2) float32 box UVs of (T, 3, 3) rest triangles: the coordinates across the
    axis of largest |normal| component, in metres."""
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    axis = np.argmax(np.abs(normal), axis=1)
    across = np.array([[1, 2], [0, 2], [0, 1]])[axis]                       # (T, 2)
    picked = np.take_along_axis(triangles, across[:, None, :].repeat(3, axis=1), axis=2)
    return picked.astype(np.float32)


def nearest_triangles(triangles: np.ndarray, points: np.ndarray, reach: np.ndarray,
                      triangle_group: np.ndarray | None = None,
                      point_group: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """For each point (n, 3), the index of the nearest of ``triangles`` (S, 3, 3) no
    farther than its ``reach`` (n,) m, and the distance (m); -1 and inf where none is.
    With groups (S,) and (n,) given, a point takes only a triangle of its own group.
    Ties go to the lower index.

    Exact for any triangle shapes (a long triangle's centroid can lie far from the
    part of it that a point is near): the nearest of the triangles with the nearest
    centroids bounds the search; then every triangle whose box, grown by that bound,
    holds the point is measured. Boxes are found through their centroids: a triangle
    whose corners lie within R of its centroid, in a class of R by powers of two, is
    looked for within bound + R."""
    n = len(points)
    if n == 0 or len(triangles) == 0:
        return np.full(n, -1, dtype=np.int64), np.full(n, np.inf)
    groups = point_group is not None and triangle_group is not None
    centroid = triangles.mean(axis=1)
    low, high = triangles.min(axis=1), triangles.max(axis=1)
    bound = np.minimum(reach, _nearest_candidate(triangles, centroid, points,
                                                 triangle_group if groups else None,
                                                 point_group if groups else None))
    bound = bound * (1.0 + 1e-9) + 1e-12  # keep the candidate that set it (rounding)
    radius = exact.length(triangles - centroid[:, None, :]).max(axis=1)
    size_class = np.ceil(fixed.log2(np.maximum(radius, 1e-9))).astype(np.int64)
    point_tree = cKDTree(points)
    pairs = []
    for k in np.unique(size_class):
        members = np.flatnonzero(size_class == k)
        found = cKDTree(centroid[members]).sparse_distance_matrix(
            point_tree, float(bound.max()) + 2.0 ** k, output_type="ndarray")
        point, triangle = found["j"], members[found["i"]]
        grown = bound[point][:, None]
        inside = ((points[point] >= low[triangle] - grown)
                  & (points[point] <= high[triangle] + grown)).all(axis=1)
        pairs.append(np.stack((point[inside], triangle[inside]), axis=1))
    point, triangle = np.concatenate(pairs).T
    if groups:
        same = point_group[point] == triangle_group[triangle]
        point, triangle = point[same], triangle[same]
    gap = exact.length(closest_point(triangles[triangle], points[point]) - points[point])
    within = gap <= reach[point]
    point, triangle, gap = point[within], triangle[within], gap[within]
    order = np.lexsort((triangle, gap, point))
    first = order[np.r_[True, point[order][1:] != point[order][:-1]]] if order.size else order
    best = np.full(n, -1, dtype=np.int64)
    distance = np.full(n, np.inf)
    best[point[first]] = triangle[first]
    distance[point[first]] = gap[first]
    return best, distance


def _nearest_candidate(triangles: np.ndarray, centroid: np.ndarray, points: np.ndarray,
                       triangle_group: np.ndarray | None, point_group: np.ndarray | None
                       ) -> np.ndarray:
    """(n,) m: the distance from each point to the nearest of the CANDIDATES triangles
    (of its group) whose centroids are nearest: an upper bound of the nearest
    triangle's distance (inf where a point's group has no triangle)."""
    bound = np.full(len(points), np.inf)
    if triangle_group is None or point_group is None:
        triangle_group = np.zeros(len(triangles), dtype=np.int64)
        point_group = np.zeros(len(points), dtype=np.int64)
    for group in np.unique(point_group):
        own, mine = np.flatnonzero(triangle_group == group), np.flatnonzero(point_group == group)
        if own.size == 0:
            continue
        k = min(CANDIDATES, own.size)
        _, nearest = cKDTree(centroid[own]).query(points[mine], k=k)
        candidates = own[np.asarray(nearest).reshape(len(mine), k)].ravel()
        at = np.repeat(points[mine], k, axis=0)
        gap = exact.length(closest_point(triangles[candidates], at) - at)
        bound[mine] = gap.reshape(-1, k).min(axis=1)
    return bound


def _usable(triangles: np.ndarray) -> np.ndarray:
    """Indices of the (S, 3, 3) source triangles that are not slivers (see SLIVER) and
    have finite corners."""
    edges = exact.length(triangles - np.roll(triangles, 1, axis=1))
    longest = edges.max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):  # height = 2 area / base
        ok = 2.0 * area(triangles) / longest > SLIVER * longest
    return np.flatnonzero(ok & np.isfinite(triangles).all(axis=(1, 2)))


def _barycentric(source: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (T, 3, 3) of ``corners`` (T, 3, 3) in the planes of the
    ``source`` triangles (T, 3, 3): [t, c] weighs source t's three corners for corner c."""
    t = len(source)
    if t == 0:
        return np.zeros((0, 3, 3))
    with np.errstate(divide="ignore", invalid="ignore"):  # zero-area source triangles
        bary = points_to_barycentric(np.repeat(source, 3, axis=0), corners.reshape(-1, 3))
    return np.nan_to_num(bary.reshape(t, 3, 3))  # degenerate source: all zero


def _smooth_normals(bary: np.ndarray, source_normals: np.ndarray, change: np.ndarray,
                    flat: np.ndarray) -> np.ndarray:
    """Corner normals (T, 3, 3), export frame: the source's corner normals (T, 3, 3),
    model frame, weighed by ``bary`` (T, 3, 3) clamped at 0, renormalized and turned by
    ``change`` (3, 3); ``flat`` (T, 3, 3) where that is not a unit vector or faces away
    from it."""
    # clamped to the source triangle: a corner just past its edge (a face of a cell that
    # straddles two source triangles) takes the edge's normal, not an extrapolation
    inside = np.maximum(bary, 0.0)
    mixed = exact.turn(change, exact.mix(inside, source_normals))
    length = exact.length(mixed, keepdims=True)
    unit = np.divide(mixed, length, out=np.zeros_like(mixed), where=length > 1e-6)
    keep = (length[..., 0] > 1e-6) & (exact.lane_dot(unit, flat) > 0.0)
    return np.where(keep[..., None], unit, flat)
