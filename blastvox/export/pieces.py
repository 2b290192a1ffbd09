"""Static piece meshes and their animation, in the frame an export asks for.

Pieces never merge, so each final piece is one static mesh in piece-local
space (origin at its pivot, the rest centre of mass) plus one rigid transform
per frame: ``x_world = position[f] + R(orientation[f]) x_local``.

A piece's mesh is the faces of its voxels that do not touch another voxel of
the same piece: hexahedron faces (jittered as voxelized, split along the same
diagonal) or, for conform voxels, the exact cell-and-mesh triangles. A face
on the intact object's surface is a *surface* face and takes the voxel's
material colour; a face that was inside the object (it had a link) is a
*damage* face, shown with the damage material once fracture exposes it
(Martins 2001 §6); unless asked for as voxel faces, damage faces are reshaped
into rubble surfaces (:mod:`blastvox.export.rubble`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from blastvox.cache import ORIGIN_GRID_M, SimCache, position_origin
from blastvox.export.rubble import roughen
from blastvox.geometry import exact, fixed, quaternion
from blastvox.geometry.frames import frame_change
from blastvox.geometry.transforms import change_frame
from blastvox.geometry.voxel_faces import FACE_CORNERS, SURFACE_TAG, face_triangles

__all__ = ["FRACTURE_FACES", "ORIGIN_GRID_M", "Animation", "PieceMeshes", "animation",
           "export_origin", "frame_change", "piece_meshes"]

#: How an export draws the fracture faces: rubble surfaces, or the voxels' cell faces.
FRACTURE_FACES = ("rough", "voxel")


@dataclass(frozen=True)
class PieceMeshes:
    """Triangles of all pieces, grouped by piece (T triangles, P pieces).

    offsets (P+1,): piece p owns triangles offsets[p]:offsets[p+1].
    vertices (T, 3, 3): piece-local positions (m), in the export frame.
    normals (T, 3): unit face normals, export frame.
    voxel (T,): voxel each triangle belongs to; damage (T,): inside face.
    material (T,): material index (cache.model.meta["materials"]).
    rest (T, 3, 3): the same triangles where they sit in the intact model, model frame (m).
    change (3, 3): the rotation from the model frame to the export frame.
    """

    offsets: np.ndarray
    vertices: np.ndarray
    normals: np.ndarray
    voxel: np.ndarray
    damage: np.ndarray
    material: np.ndarray
    rest: np.ndarray
    change: np.ndarray


@dataclass(frozen=True)
class Animation:
    """Piece transforms in the export frame: position (F, P, 3) m, orientation (F, P, 4)
    unit quaternions (w, x, y, z), end_frame (P,) first frame a piece is gone, times (F,) s."""

    position: np.ndarray
    orientation: np.ndarray
    end_frame: np.ndarray
    times: np.ndarray


def animation(cache: SimCache, export_up: str) -> Animation:
    """Piece transforms of ``cache`` re-expressed in the export frame.

    With C the frame change, x' = C x: position' = C position and
    orientation' = q_C q q_C^-1 (the piece-local frame is changed by C too).
    """
    c = frame_change(cache.model.meta.get("up_axis", "Y"), export_up)
    pos, ori = change_frame(cache.piece_position, cache.piece_orientation, c)
    return Animation(position=pos, orientation=ori, end_frame=cache.piece_end_frame.copy(),
                     times=cache.frame_time.copy())


def export_origin(anim: Animation) -> np.ndarray:
    """(3,) float64 m, export frame: the multiple of :data:`ORIGIN_GRID_M` (1024 m)
    nearest the centre of the box round the pieces' first positions, as a SimCache's
    ``position_origin`` (:func:`blastvox.cache.position_origin`) in the export's axes;
    zero for a scene within 512 m of the origin, which exports as before.

    Formats whose coordinates are float32 (glTF's translations, USD's point arrays)
    store the scene relative to it, and a transform above them carries it (a glTF root
    node's translation; a USD ``xformOp:translate``, double3): float32 is 2^-24 of the
    value, 7.8 mm at 100 km from the origin but under 0.1 mm within a scene's own
    kilometre of it."""
    return position_origin(anim.position)


def velocities(anim: Animation) -> tuple[np.ndarray, np.ndarray]:
    """Each piece's linear velocity (F, P, 3) m/s and angular velocity (F, P, 3) rad/s
    (world axes, export frame) at the frame times, from its transforms: central
    differences inside the shot (exact for uniformly accelerated motion and for a
    steady spin), one-sided at the first and last frame; zero for a single frame."""
    pos = anim.position.astype(np.float64)
    ori = quaternion.normalize(anim.orientation.astype(np.float64))
    f_count = len(pos)
    if f_count < 2:
        return np.zeros_like(pos), np.zeros_like(pos)
    t = anim.times.astype(np.float64)
    ahead = np.minimum(np.arange(f_count) + 1, f_count - 1)
    behind = np.maximum(np.arange(f_count) - 1, 0)
    span = (t[ahead] - t[behind])[:, None, None]
    span = np.where(span > 0, span, np.inf)
    linear = (pos[ahead] - pos[behind]) / span
    turn = quaternion.multiply(ori[ahead], quaternion.conjugate(ori[behind]))
    angular = quaternion.rotation_vector(turn) / span
    return linear, angular


def piece_objects(cache: SimCache) -> list[str]:
    """The name of the object each piece was cut from (P,) (its first voxel's object)."""
    names = [o.get("name", f"object_{i}")
             for i, o in enumerate(cache.model.meta.get("objects", []))]
    voxel_object = np.asarray(cache.model.arrays["voxel_object"], dtype=np.int64)
    return [names[voxel_object[v]] if 0 <= v and voxel_object[v] < len(names) else ""
            for v in _first_voxels(cache).tolist()]


def piece_parts(cache: SimCache) -> list[str]:
    """The input part (a node or group of its mesh file) each piece was cut from (P,),
    where that file held more than one part and all the piece's voxels are of that
    part; "" elsewhere (a piece that still joins two parts) and in models that do not
    record parts."""
    parts = cache.model.meta.get("parts") or []
    if "voxel_part" not in cache.model.arrays or not parts:
        return [""] * cache.piece_count
    per_object = Counter(str(p.get("object", "")) for p in parts)
    names = [str(p.get("name", "")) if per_object[str(p.get("object", ""))] > 1 else ""
             for p in parts]
    voxel_part = np.asarray(cache.model.arrays["voxel_part"], dtype=np.int64)
    piece = np.asarray(cache.voxel_piece, dtype=np.int64)
    held = (piece >= 0) & (piece < cache.piece_count)
    low = np.full(cache.piece_count, len(names), dtype=np.int64)
    high = np.full(cache.piece_count, -1, dtype=np.int64)
    np.minimum.at(low, piece[held], voxel_part[held])
    np.maximum.at(high, piece[held], voxel_part[held])
    return [names[lo] if lo == hi and 0 <= lo < len(names) else ""
            for lo, hi in zip(low.tolist(), high.tolist(), strict=True)]


def _first_voxels(cache: SimCache) -> np.ndarray:
    """(P,) int64: each piece's lowest voxel, -1 for a piece with none."""
    piece = np.asarray(cache.voxel_piece, dtype=np.int64)
    first = np.full(cache.piece_count, -1, dtype=np.int64)
    present, first_voxel = np.unique(piece, return_index=True)
    inside = (present >= 0) & (present < cache.piece_count)
    first[present[inside]] = first_voxel[inside]
    return first


def object_groups(objects: list[str]) -> dict[str, list[int]]:
    """The pieces of each object name (index order), objects in order of first piece."""
    groups: dict[str, list[int]] = {}
    for p, name in enumerate(objects):
        groups.setdefault(name, []).append(p)
    return groups


def piece_meshes(cache: SimCache, export_up: str, fracture_faces: str = "rough") -> PieceMeshes:
    """Boundary triangles of every final piece, piece-local, in the export frame.

    fracture_faces: "rough" reshapes the fracture faces into rubble surfaces
    (:func:`blastvox.export.rubble.roughen`: steps smoothed, corners roughened, the
    pieces still fitting at rest); "voxel" keeps them the voxels' cell faces."""
    if fracture_faces not in FRACTURE_FACES:
        raise ValueError(f"fracture_faces must be one of {FRACTURE_FACES}, not {fracture_faces!r}")
    a = cache.model.arrays
    n = len(a["voxel_mass"])
    piece = cache.voxel_piece.astype(np.int64)
    neighbour = np.full((n, 6), -1, dtype=np.int64)
    links = a["link_voxels"].astype(np.int64)
    face = a["link_face"].astype(np.int64)
    neighbour[links[:, 0], face] = links[:, 1]
    neighbour[links[:, 1], face - 1] = links[:, 0]
    has_neighbour = neighbour >= 0
    same_piece = has_neighbour & (piece[np.maximum(neighbour, 0)] == piece[:, None])
    exposed = ~same_piece  # (N, 6)

    conform = np.zeros(n, dtype=bool)
    conform[a["conform_voxels"]] = True
    verts = a["vertices"]

    # hexahedral faces of non-conform voxels
    v_idx, f_idx = np.nonzero(exposed & ~conform[:, None])
    quads = a["voxel_vertices"][v_idx][np.arange(len(v_idx))[:, None], FACE_CORNERS[f_idx]]
    hex_tris = verts[face_triangles(quads)].reshape(-1, 3, 3)
    hex_voxel = np.repeat(v_idx, 2)
    hex_damage = np.repeat(has_neighbour[v_idx, f_idx], 2)

    # conform voxels: their surface triangles always, cell-face triangles where exposed
    tri = a["conform_triangles"]
    tags = a["conform_tag"].astype(np.int64)
    owner = np.repeat(a["conform_voxels"].astype(np.int64), np.diff(a["conform_offsets"]))
    on_surface = tags == SURFACE_TAG
    cell_face = np.where(on_surface, 0, tags)
    keep = on_surface | exposed[owner, cell_face]
    con_damage = ~on_surface & has_neighbour[owner, cell_face]

    all_tris = np.concatenate([hex_tris, tri[keep]])
    all_voxel = np.concatenate([hex_voxel, owner[keep]])
    all_damage = np.concatenate([hex_damage, con_damage[keep]])

    if fracture_faces == "rough":
        edge = float(np.median(fixed.cbrt(a["voxel_volume"]))) if n else 0.0
        as_meshed = np.concatenate([np.zeros(len(hex_tris), dtype=bool), on_surface[keep]])
        all_tris = roughen(all_tris, all_damage, edge, int(cache.model.meta.get("seed") or 0),
                           as_meshed)
    tri_piece = piece[all_voxel]
    order = np.lexsort((np.arange(len(tri_piece)), tri_piece))  # stable by piece
    all_tris, all_voxel, all_damage, tri_piece = (all_tris[order], all_voxel[order],
                                                  all_damage[order], tri_piece[order])
    pivot = cache.piece_pivot[tri_piece]
    change = frame_change(cache.model.meta.get("up_axis", "Y"), export_up)
    local = exact.turn(change, all_tris - pivot[:, None, :])
    normal = np.cross(local[:, 1] - local[:, 0], local[:, 2] - local[:, 0])
    length = exact.length(normal, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    # a triangle whose corners meet in the files' float32 draws nothing, and importers
    # drop it (Blender's USD import does), which would shift every per-corner value
    # (normals, UVs) after it onto the wrong corners
    keep = _drawable(local, length[:, 0])
    all_tris, all_voxel, all_damage, tri_piece, local, normal = (
        all_tris[keep], all_voxel[keep], all_damage[keep], tri_piece[keep], local[keep],
        normal[keep])
    offsets = np.searchsorted(tri_piece, np.arange(cache.piece_count + 1))
    return PieceMeshes(offsets=offsets.astype(np.int64), vertices=local, normals=normal,
                       voxel=all_voxel, damage=all_damage,
                       material=a["voxel_material"][all_voxel].astype(np.int64),
                       rest=all_tris, change=change)


def _drawable(local: np.ndarray, doubled_area: np.ndarray) -> np.ndarray:
    """Triangles (T,) with a non-zero area and three distinct corners in float32 (the
    precision the exports store): ``local`` (T, 3, 3) m, ``doubled_area`` (T,) m^2."""
    f32 = local.astype(np.float32) + np.float32(0.0)
    distinct = (np.any(f32[:, 0] != f32[:, 1], axis=1) & np.any(f32[:, 1] != f32[:, 2], axis=1)
                & np.any(f32[:, 0] != f32[:, 2], axis=1))
    return distinct & (doubled_area > 0.0)
