"""Conform voxels: the exact intersection of a voxel cell with the input solid.

For every lattice cell the surface passes through, manifold3d intersects the
cell's hexahedron (jittered corners included) with the object's solid, so the
voxel's render geometry and mass properties follow the original surface rather
than stair-steps. Each output triangle is tagged with where it lies: on cell
face 0..5 (an interior face, exposed only when the object breaks there) or on
the original surface (tag 6). Manifold tracks this through the boolean
(``run_original_id`` and ``face_id``), so no tolerance guessing is involved.

Cells are clipped against a pre-clipped block of the solid (a few cells wide),
not the whole solid, so each boolean touches only nearby triangles.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import manifold3d as m3d
import numpy as np
import trimesh

from blastvox.errors import MeshError
from blastvox.geometry.boxes import corner_boxes
from blastvox.geometry.voxel_faces import FACE_CORNERS, SURFACE_TAG

_BLOCK = 8  # cells per block edge for the two-level clip
#: (12, 3) uint64: each cell triangle's face id (triangle 2f and 2f+1 on face f)
_FACE_IDS = np.arange(12, dtype=np.uint64)


@dataclass
class ConformCells:
    """Clipped geometry of the candidate cells that keep some volume.

    cells: (C,) indices into the candidate list; offsets: (C+1,) triangle
    ranges; triangles: (T, 3, 3) metres; tags: (T,) uint8.
    """

    cells: np.ndarray
    offsets: np.ndarray
    triangles: np.ndarray
    tags: np.ndarray


def solid_manifold(mesh: trimesh.Trimesh, where: str, origin: str | None = None
                   ) -> m3d.Manifold:
    """The mesh as a manifold3d solid; :class:`MeshError` if it is not a valid manifold,
    naming the setting that asked for conform voxels: the scene's key (``origin``, e.g.
    ``scene.toml: objects[0]``) or else the ``--shape`` flag."""
    mesh64 = m3d.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, dtype=np.float64),
                        tri_verts=np.ascontiguousarray(mesh.faces, dtype=np.uint64))
    mesh64.merge()
    solid = m3d.Manifold(mesh64)
    if solid.status() != m3d.Error.NoError:
        asked, fix = ((f"{origin}.shape = \"conform\"", 'shape = "cube"') if origin
                      else ("--shape conform", "--shape cube"))
        raise MeshError(f"{where}: {asked} needs a closed manifold surface "
                        f"(manifold3d: {solid.status().name}); use {fix} for this mesh")
    return solid.as_original()


def _hex_manifold(corners: np.ndarray, tris: np.ndarray) -> m3d.Manifold:
    """The cell of ``corners`` (8, 3) float64 and ``tris`` (12, 3) uint64, both C-contiguous
    (rows of the arrays :func:`clipped_cells` takes)."""
    return m3d.Manifold(m3d.Mesh64(vert_properties=corners, tri_verts=tris, face_id=_FACE_IDS))


def clipped_cells(solid: m3d.Manifold, positions: np.ndarray, cells: np.ndarray,
                  block_keys: np.ndarray, advance: Callable[[int], None] | None = None
                  ) -> Iterator[tuple[int, m3d.Manifold]]:
    """Each candidate cell k intersected with ``solid``, (k, clipped), skipping the empty
    ones, block by block (the cells of a block are clipped against the same pre-clipped
    piece of the solid, which keeps each clip small; their corners and triangles are
    gathered a block at a time, not for all cells at once); arguments as for
    :func:`clip_cells`."""
    order = np.argsort(block_keys, kind="stable")
    bounds = np.sort(np.unique(block_keys[order], return_index=True)[1])
    for group in np.split(order, bounds[1:]):
        corners = np.ascontiguousarray(positions[cells[group]], dtype=np.float64)
        lo = corners.reshape(-1, 3).min(axis=0)
        hi = corners.reshape(-1, 3).max(axis=0)
        pad = 1e-6 * float(np.max(hi - lo))
        box = m3d.Manifold.cube(tuple(hi - lo + 2 * pad)).translate(tuple(lo - pad))
        piece = solid ^ box
        if advance is not None:
            advance(len(group))
        if piece.is_empty():
            continue
        tris = local_hex_triangles(cells[group])
        for i, k in enumerate(group.tolist()):
            clipped = _hex_manifold(corners[i], tris[i]) ^ piece
            if not clipped.is_empty():
                yield k, clipped


def clip_volumes(solid: m3d.Manifold, positions: np.ndarray, cells: np.ndarray,
                 block_keys: np.ndarray, advance: Callable[[int], None] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The volume (m^3) of each candidate cell inside ``solid``, (K,), and the bounds of
    that solid, (K, 2, 3) m (lo, hi; the cell's own corners' where nothing is inside):
    arguments as for :func:`clip_cells`, which this measures without keeping the
    clipped surfaces."""
    volume = np.zeros(len(cells))
    bounds = np.stack(corner_boxes(positions, cells), axis=1)
    for k, clipped in clipped_cells(solid, positions, cells, block_keys, advance):
        volume[k] = clipped.volume()
        box = clipped.bounding_box()
        bounds[k, 0], bounds[k, 1] = box[:3], box[3:]
    return volume, bounds


def clip_cells(solid: m3d.Manifold, positions: np.ndarray, cells: np.ndarray,
               block_keys: np.ndarray, min_volume: np.ndarray,
               advance: Callable[[int], None] | None = None) -> ConformCells:
    """Intersect each candidate cell with ``solid``.

    positions: (V, 3) lattice vertices in metres; cells: (K, 8) the candidate cells'
    corners, rows of positions (distinct in a cell; its triangles split each face as
    :func:`local_hex_triangles` does, triangle ``2f``/``2f+1`` on face ``f``);
    block_keys: (K,) integer block id per cell (cells of a block are clipped against the
    same pre-clipped piece of the solid); min_volume: (K,) m^3, cells whose clipped
    volume is at or below it are dropped; ``advance(n)`` is called as cells are done
    (progress).
    """
    kept, offsets, tri_chunks, tag_chunks = [], [0], [], []
    surface_ids = np.asarray(_original_ids(solid), dtype=np.int64)
    for k, clipped in clipped_cells(solid, positions, cells, block_keys, advance):
        if clipped.volume() <= min_volume[k]:
            continue
        tris, tags = _tagged_triangles(clipped.to_mesh64(), surface_ids)
        kept.append(k)
        tri_chunks.append(tris)
        tag_chunks.append(tags)
        offsets.append(offsets[-1] + len(tris))
    if not kept:
        return ConformCells(np.zeros(0, np.int64), np.zeros(1, np.int64),
                            np.zeros((0, 3, 3)), np.zeros(0, np.uint8))
    return ConformCells(cells=np.asarray(kept, dtype=np.int64),
                        offsets=np.asarray(offsets, dtype=np.int64),
                        triangles=np.concatenate(tri_chunks),
                        tags=np.concatenate(tag_chunks).astype(np.uint8))


def _original_ids(solid: m3d.Manifold) -> list[int]:
    """Original ids of the runs that make up ``solid`` (one per input solid)."""
    return sorted(set(np.asarray(solid.to_mesh64().run_original_id).tolist()))


def _tagged_triangles(mesh: m3d.Mesh64, surface_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    positions = np.asarray(mesh.vert_properties)[:, :3]
    tri_verts = np.asarray(mesh.tri_verts, dtype=np.int64)
    triangles = positions[tri_verts]
    run_index = np.asarray(mesh.run_index, dtype=np.int64)
    run_ids = np.asarray(mesh.run_original_id, dtype=np.int64)
    run_of_tri = np.searchsorted(run_index, np.arange(len(tri_verts)) * 3, side="right") - 1
    from_cell = ~np.isin(run_ids[run_of_tri], surface_ids)
    face_id = np.asarray(mesh.face_id, dtype=np.int64)
    tags = np.where(from_cell, face_id // 2, SURFACE_TAG)
    return triangles, tags


def block_keys_for(ijk: np.ndarray) -> np.ndarray:
    """Block id (K,) of cells at lattice indices ``ijk`` (K, 3) for :func:`clip_cells`."""
    b = ijk // _BLOCK
    return (b[:, 0] * 1_000_003 + b[:, 1]) * 1_000_003 + b[:, 2]


#: (2, 6, 2, 3) corner numbers of each face's two triangles, split through the face's
#: corners 0 and 2 ([0]) or 1 and 3 ([1]): :func:`~blastvox.geometry.voxel_faces.face_triangles`
#: of the corner numbers
_SPLITS = np.stack([
    np.stack([FACE_CORNERS[:, [0, 1, 2]], FACE_CORNERS[:, [0, 2, 3]]], axis=1),
    np.stack([FACE_CORNERS[:, [1, 2, 3]], FACE_CORNERS[:, [1, 3, 0]]], axis=1)])


def local_hex_triangles(voxel_vertices: np.ndarray) -> np.ndarray:
    """(K, 12, 3) uint64 corner numbers 0..7 of each hexahedron's triangles (voxel_vertices
    (K, 8) distinct global vertex ids): the split rule of
    :func:`~blastvox.geometry.voxel_faces.hex_triangles` (each face split through its
    smallest vertex id), in the cell's own corner numbers."""
    first = np.argmin(voxel_vertices[:, FACE_CORNERS], axis=-1)  # (K, 6)
    return _SPLITS[(first % 2).astype(np.int8), np.arange(6)].astype(np.uint64).reshape(
        len(voxel_vertices), 12, 3)
