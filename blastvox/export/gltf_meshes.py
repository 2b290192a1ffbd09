"""The pieces' meshes of the glTF writer: a mesh per piece, or skinned meshes.

:func:`_piece_meshes` groups the pieces' triangles into primitives (per piece and
material, or per skin and material in the skinned layout), shares vertices where
position, normal and UV agree, and writes POSITION, NORMAL, TEXCOORD_0 (and
JOINTS_0, WEIGHTS_0 when skinned) and 16- or 32-bit indices into the buffer.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from blastvox.cache import SimCache
from blastvox.export.gltf_buffer import (
    ARRAY_BUFFER,
    ELEMENT_ARRAY_BUFFER,
    FLOAT,
    UINT8,
    UINT16,
    UINT32,
    _Builder,
    _f32,
    _floats,
)
from blastvox.export.pieces import PieceMeshes, object_groups
from blastvox.export.uv import face_uvs

TRIANGLES = 4
SKIN_JOINTS = 512  # pieces per skin: Blender imports 512 to 1,024 fastest (docs/benchmarks.md)
U16_VERTEX_LIMIT = 65535  # a primitive with fewer vertices uses 16-bit indices (65535 = restart)


def _skin_groups(objects: list[str]) -> list[list[int]]:
    """The joints (piece indices) of each skin: each object's pieces in runs of at most
    SKIN_JOINTS. Blender's importer gives each skin an armature and an action. Adding an
    F-curve to an action costs time in proportion to those it already holds, so big
    skins are slow; each armature's mode switches re-evaluate every bone already in the
    scene, so many small skins are slow too."""
    out = []
    for pieces in object_groups(objects).values():
        out += [pieces[i:i + SKIN_JOINTS] for i in range(0, len(pieces), SKIN_JOINTS)]
    return out


def _piece_meshes(cache: SimCache, b: _Builder, mat_index: dict[tuple[int, bool], int],
                  texture_material: list[int], pm: PieceMeshes,
                  skin_of: np.ndarray | None = None
                  ) -> tuple[list[dict[str, Any]], np.ndarray]:
    """One mesh per piece with triangles (mesh dicts, mesh index per piece or -1); with
    ``skin_of`` (P,) each piece's skin, one mesh per skin (primitives per material)
    whose vertices are bound to their piece's joint (JOINTS_0 = the piece's place in
    its skin, WEIGHTS_0 = 1), mesh index = skin.

    Primitives are groups of (piece, glTF material): the model material and damage,
    or the source look's texture. A mesh's primitives share its POSITION, NORMAL and
    TEXCOORD_0 accessors (one set per mesh, each primitive its own indices: three
    accessors a mesh fewer per extra primitive); within a mesh (and piece), corners
    with the same float32 position, normal and UV share a vertex (first-use order,
    primitive by primitive). TEXCOORD_0 holds the
    UVs of :mod:`blastvox.export.uv` with v flipped (glTF's origin is the image's top
    left).
    """
    uvs = face_uvs(cache, pm)
    n_pieces = cache.piece_count
    piece_mesh = np.full(n_pieces, -1, dtype=np.int64)
    tri_piece = np.repeat(np.arange(n_pieces), np.diff(pm.offsets))
    damage = np.asarray(pm.damage, dtype=bool)
    material = np.asarray(pm.material, dtype=np.int64)
    lookup = np.zeros((int(material.max(initial=0)) + 1, 2), dtype=np.int64)
    for (m, d), i in mat_index.items():
        if m < len(lookup):
            lookup[m, int(d)] = i
    textured = np.asarray(texture_material + [0], dtype=np.int64)[uvs.texture]
    gmat = np.where(uvs.texture >= 0, textured, lookup[material, damage.astype(np.int64)])
    # piece_meshes left out the zero-area triangles (a zero NORMAL is invalid glTF)
    n_tri = len(pm.normals)
    if n_tri == 0:
        return [], piece_mesh
    skinned = skin_of is not None
    owner = skin_of[tri_piece] if skinned else tri_piece  # a mesh per skin or per piece
    order = np.lexsort((np.arange(n_tri), tri_piece, gmat, owner))
    tri_piece, gmat, owner = tri_piece[order], gmat[order], owner[order]
    key = np.stack([owner, gmat], axis=1)
    change = np.r_[True, np.any(key[1:] != key[:-1], axis=1)]
    starts = np.flatnonzero(change)  # first triangle of each primitive
    group = np.cumsum(change) - 1  # primitive of each triangle

    corners = np.ascontiguousarray(pm.vertices[order], dtype=np.float32).reshape(-1, 3)
    normals = np.ascontiguousarray(uvs.normal[order], dtype=np.float32).reshape(-1, 3)
    texcoords = np.ascontiguousarray(uvs.uv[order].reshape(-1, 2), dtype=np.float32)
    texcoords[:, 1] = np.float32(1.0) - texcoords[:, 1]
    texcoords += np.float32(0.0)  # no -0
    corner_group = np.repeat(group, 3)
    mesh_change = np.r_[True, owner[1:] != owner[:-1]]
    tri_mesh = np.cumsum(mesh_change) - 1  # the mesh of each triangle
    corner_mesh = np.repeat(tri_mesh, 3)
    # shared vertices: equal (mesh, piece, position, normal and UV bits), one vertex set
    # per mesh that its primitives share; stable sort keeps first use
    corner_piece = np.repeat(tri_piece, 3).astype(np.int32)  # skinned: no sharing across
    cols = np.concatenate([corner_mesh[:, None].astype(np.int32), corner_piece[:, None],
                           corners.view(np.int32), normals.view(np.int32),
                           texcoords.view(np.int32)], axis=1)
    srt = np.lexsort(cols.T[::-1])
    s = cols[srt]
    new = np.r_[True, np.any(s[1:] != s[:-1], axis=1)]
    uid = np.cumsum(new) - 1
    first = srt[new]  # first corner of each distinct vertex (lexsort is stable)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    inverse = np.empty(len(cols), dtype=np.int64)
    inverse[srt] = rank[uid]
    keep = np.sort(first)
    vpos, vnrm, vuv, vmesh = corners[keep], normals[keep], texcoords[keep], corner_mesh[keep]
    if skinned:
        by_skin = np.argsort(skin_of, kind="stable")  # each piece's place in its skin:
        first = np.searchsorted(skin_of[by_skin], skin_of[by_skin])  # its rank there
        joint = np.empty(n_pieces, dtype=np.int64)
        joint[by_skin] = np.arange(n_pieces) - first
        skin = _skin_views(b, joint[corner_piece[keep]])
    else:
        skin = None

    n_groups = len(starts)
    n_meshes = int(tri_mesh[-1]) + 1
    vstart = np.searchsorted(vmesh, np.arange(n_meshes + 1))
    local_index = inverse - vstart[corner_mesh]
    lo = np.minimum.reduceat(vpos, vstart[:-1], axis=0)
    hi = np.maximum.reduceat(vpos, vstart[:-1], axis=0)
    group_mesh = tri_mesh[starts]

    pos_view = b.view(_f32(vpos), ARRAY_BUFFER, 12)
    nrm_view = b.view(_f32(vnrm), ARRAY_BUFFER, 12)
    uv_view = b.view(_f32(vuv), ARRAY_BUFFER, 8)

    # indices: u16 where the primitive has few enough vertices, else u32; each primitive's
    # run starts on a 4-byte boundary
    counts = np.diff(vstart)
    cstart = np.r_[starts, n_tri] * 3
    wide = counts[group_mesh] >= U16_VERTEX_LIMIT
    item = np.where(wide, 4, 2)
    padded = (np.diff(cstart) * item + 3) // 4 * 4
    idx_offsets = np.r_[0, np.cumsum(padded)[:-1]]
    idx = np.zeros(int(padded.sum()), dtype=np.uint8)
    within = np.arange(len(local_index)) - cstart[corner_group]
    wide_c = wide[corner_group]
    narrow_c = ~wide_c
    idx.view("<u2")[(idx_offsets[corner_group] // 2 + within)[narrow_c]] = local_index[narrow_c]
    idx.view("<u4")[(idx_offsets[corner_group] // 4 + within)[wide_c]] = local_index[wide_c]
    idx_view = b.view(idx.tobytes(), ELEMENT_ARRAY_BUFFER)

    meshes: list[dict[str, Any]] = []
    g_owner = owner[starts].tolist()
    g_mat = gmat[starts].tolist()
    lo_l, hi_l = _floats(lo), _floats(hi)
    vstart_l, counts_l, wide_l = vstart.tolist(), counts.tolist(), wide.tolist()
    n_idx, idx_off = np.diff(cstart).tolist(), idx_offsets.tolist()
    owner_mesh = np.full(n_pieces, -1, dtype=np.int64)  # mesh of each piece (or skin)
    attributes: dict[str, int] = {}
    for g in range(n_groups):
        if g == 0 or g_owner[g] != g_owner[g - 1]:
            k = len(meshes)
            owner_mesh[g_owner[g]] = k
            meshes.append({"name": f"{'pieces' if skinned else 'piece'}_"
                                   f"{g_owner[g]:{'03' if skinned else '05'}d}",
                           "primitives": []})
            n_v = counts_l[k]
            attributes = {
                "POSITION": b.accessor(pos_view, vstart_l[k] * 12, FLOAT, n_v, "VEC3",
                                       lo_l[k], hi_l[k]),
                "NORMAL": b.accessor(nrm_view, vstart_l[k] * 12, FLOAT, n_v, "VEC3"),
                "TEXCOORD_0": b.accessor(uv_view, vstart_l[k] * 8, FLOAT, n_v, "VEC2"),
            }
            if skin is not None:
                attributes["JOINTS_0"] = b.accessor(skin[0], vstart_l[k] * 8, UINT16,
                                                    n_v, "VEC4")
                attributes["WEIGHTS_0"] = b.accessor(skin[1], vstart_l[k] * 4, UINT8,
                                                     n_v, "VEC4", normalized=True)
        prim = {
            "attributes": dict(attributes),
            "indices": b.accessor(idx_view, idx_off[g], UINT32 if wide_l[g] else UINT16,
                                  n_idx[g], "SCALAR"),
            "material": g_mat[g],
            "mode": TRIANGLES,
        }
        meshes[-1]["primitives"].append(prim)
    piece_mesh = owner_mesh[skin_of] if skinned else owner_mesh
    return meshes, piece_mesh


def _skin_views(b: _Builder, vertex_piece: np.ndarray) -> tuple[int, int]:
    """Buffer views of JOINTS_0 (u16 VEC4: the vertex's piece, then three zero-weight
    0s) and WEIGHTS_0 (normalized u8 VEC4: 255, 0, 0, 0, that is 1, 0, 0, 0; 4 bytes a
    vertex where float32 took 16) for vertices of pieces (V,)."""
    joints = np.zeros((len(vertex_piece), 4), dtype="<u2")
    joints[:, 0] = vertex_piece
    weights = np.zeros((len(vertex_piece), 4), dtype=np.uint8)
    weights[:, 0] = 255
    return (b.view(joints.tobytes(), ARRAY_BUFFER, 8),
            b.view(weights.tobytes(), ARRAY_BUFFER, 4))
