"""Merging conform slivers into their neighbours.

Clipping lattice cells by the mesh (``--shape conform``) leaves, where the
surface just grazes a cell, pieces of almost no volume (10⁻⁹ m³ in a 0.5 m
lattice). As voxels they would be nearly massless bodies that a blast throws
at hundreds of m/s and whose links demand microsecond time steps. Every conform
piece keeping less than :data:`MIN_CONFORM_FRACTION` of its cell's volume is
therefore merged into the face-adjacent voxel it shares the largest contact
with (of the same part, so of the same material); merged pieces that are still
too small merge again, smallest first. A piece touching no such neighbour (an
isolated crumb) is dropped, and the caller reports it.

A merged voxel keeps the lattice cell (``voxel_ijk``, ``voxel_vertices``) of
its *anchor*, the larger side of each merge, and becomes a conform voxel whose triangles
are its members' triangles (a hexahedral anchor contributes its 12 face
triangles) minus those on the faces between members. Cell-face triangles keep
their face number 0..5, which is their outward direction: a merged voxel's face
``f`` is everything of it that faces ``f``. Volume, centroid and inertia are
the exact sums (parallel-axis theorem), so volume and mass are conserved.

Links follow the members: a link between cells of two different voxels becomes
a link between the voxels across the same face direction, and contacts of one
pair across one direction add up (area summed, midpoint area-weighted). A
merged voxel may so have two links across one face (to two neighbours): the
face is exposed once both are broken. The contract wants link ``(a, b)`` to
cross face 1, 3 or 5 of ``a`` with ``a < b``, so merged lattices are renumbered
(:func:`_ordered`); a contact that still runs the wrong way (a cycle of links
around odd-shaped groups, a handful per thousand merges) is left unlinked and
counted in :attr:`MergeResult.unlinked`.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from blastvox.geometry.voxel_faces import FACE_OFFSETS, hex_triangles

#: Conform voxels keeping less than this fraction of their lattice cell's volume
#: are merged into a neighbour (:mod:`blastvox.voxelize.slivers`).
MIN_CONFORM_FRACTION = 0.1


@dataclass
class Cells:
    """One lattice's voxels before merging (indices local to the lattice).

    ijk: (N, 3) lattice cells, ascending C order; part: (N,) solid part;
    positions: (V, 3) m lattice vertices; voxel_vertices: (N, 8) corners into
    positions; cell_volume: (N,) m³ volume of each cell's hexahedron; volume:
    (N,) m³, centroid: (N, 3) m, inertia: (N, 3, 3) m⁵ (unit density, about the
    centroid) of each voxel's actual shape; conform_local: (C,) ascending voxel
    indices with triangles; conform_offsets: (C+1,); conform_triangles: (T, 3, 3)
    m; conform_tags: (T,) 0..5 cell face, 6 surface; links: link_voxels (L, 2)
    a < b, link_face (L,) 1/3/5 face of a, link_midpoint (L, 3) m, link_area (L,) m².
    """

    ijk: np.ndarray
    part: np.ndarray
    positions: np.ndarray
    voxel_vertices: np.ndarray
    cell_volume: np.ndarray
    volume: np.ndarray
    centroid: np.ndarray
    inertia: np.ndarray
    conform_local: np.ndarray
    conform_offsets: np.ndarray
    conform_triangles: np.ndarray
    conform_tags: np.ndarray
    link_voxels: np.ndarray
    link_face: np.ndarray
    link_midpoint: np.ndarray
    link_area: np.ndarray


@dataclass
class MergeResult:
    """The merged voxels: ``cells`` (fields as :class:`Cells`, voxels renumbered), which
    old voxel each new one is anchored at (anchor (N',)), and what happened.

    merged: slivers merged into a neighbour; dropped: slivers dropped for want of
    one, with dropped_volume m³ (unit density); unlinked: contacts between merged
    voxels left without a link (see the module docstring).
    """

    cells: Cells
    anchor: np.ndarray
    merged: int = 0
    dropped: int = 0
    dropped_volume: float = 0.0
    unlinked: int = 0


def merge_slivers(cells: Cells, fraction: float = MIN_CONFORM_FRACTION) -> MergeResult:
    """Merge conform voxels below ``fraction`` of their cell's volume into neighbours.

    Returns ``cells`` itself (and the identity anchor) when there is no sliver.
    """
    n = len(cells.volume)
    is_sliver = np.zeros(n, dtype=bool)
    conform = cells.conform_local.astype(np.int64)
    is_sliver[conform] = cells.volume[conform] < fraction * cells.cell_volume[conform]
    if not is_sliver.any() or fraction <= 0:
        return MergeResult(cells=cells, anchor=np.arange(n))
    group, dropped = _group(cells, is_sliver, fraction)
    alive = ~dropped
    anchors = _ordered(cells, group, alive)
    new_index = np.full(n, -1, dtype=np.int64)
    new_index[anchors] = np.arange(len(anchors))
    voxel_of = np.where(alive, new_index[group], -1)  # (n,) new voxel of each old one
    volume, centroid, inertia = _mass(cells, voxel_of, len(anchors))
    offsets, triangles, tags, conform_new = _triangles(cells, voxel_of, anchors)
    link_voxels, link_face, link_mid, link_area, unlinked = _links(cells, voxel_of)
    merged_cells = Cells(
        ijk=cells.ijk[anchors], part=cells.part[anchors], positions=cells.positions,
        voxel_vertices=cells.voxel_vertices[anchors], cell_volume=cells.cell_volume[anchors],
        volume=volume, centroid=centroid, inertia=inertia, conform_local=conform_new,
        conform_offsets=offsets, conform_triangles=triangles, conform_tags=tags,
        link_voxels=link_voxels, link_face=link_face, link_midpoint=link_mid,
        link_area=link_area)
    return MergeResult(cells=merged_cells, anchor=anchors,
                       merged=int(np.count_nonzero(alive & (group != np.arange(n)))),
                       dropped=int(np.count_nonzero(dropped)),
                       dropped_volume=float(cells.volume[dropped].sum()), unlinked=unlinked)


def _group(cells: Cells, is_sliver: np.ndarray, fraction: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """Anchor voxel of every voxel's group (n,) and which voxels are dropped (n,).

    Smallest group first: a group below ``fraction`` of its anchor's cell merges
    into the neighbouring group of the same part it touches with the largest
    contact area (ties: the larger group, then the lower anchor); with none, it is
    dropped. Contact maps are complete only for slivers and their neighbours: a
    group below the threshold consists of those.
    """
    n = len(cells.volume)
    lv = cells.link_voxels.astype(np.int64)
    close = is_sliver.copy()  # slivers and their neighbours
    close[lv[is_sliver[lv[:, 0]], 1]] = True
    close[lv[is_sliver[lv[:, 1]], 0]] = True
    involved = close[lv[:, 0]] | close[lv[:, 1]]
    near: dict[int, dict[int, float]] = {v: {} for v in np.flatnonzero(close).tolist()}
    for (a, b), area in zip(lv[involved].tolist(), cells.link_area[involved].tolist(),
                            strict=True):
        near.setdefault(a, {})[b] = area
        near.setdefault(b, {})[a] = area
    parent = np.arange(n)
    volume = cells.volume.astype(np.float64).copy()
    members: dict[int, list[int]] = {}
    dropped = np.zeros(n, dtype=bool)
    part = cells.part
    heap = [(volume[v], v) for v in np.flatnonzero(is_sliver).tolist()]
    heapq.heapify(heap)
    while heap:
        vol, g = heapq.heappop(heap)
        if parent[g] != g or dropped[g] or vol != volume[g]:
            continue  # merged, dropped or grown since it was queued
        if volume[g] >= fraction * cells.cell_volume[g]:
            continue
        touching = [(area, volume[h], -h) for h, area in near[g].items() if part[h] == part[g]]
        if not touching:
            dropped[g] = True
            for m in members.pop(g, [g]):
                dropped[m] = True
            for h in near.pop(g):
                near[h].pop(g, None)
            continue
        _, _, minus_h = max(touching)
        h = -minus_h
        keep, gone = (h, g) if volume[h] >= volume[g] else (g, h)
        parent[gone] = keep
        members[keep] = members.pop(keep, [keep]) + members.pop(gone, [gone])
        volume[keep] += volume[gone]
        contacts = near.pop(gone)
        contacts.pop(keep, None)
        near[keep].pop(gone, None)
        for k, area in contacts.items():
            near.setdefault(k, {}).pop(gone, None)
            near[k][keep] = near[k].get(keep, 0.0) + area
            near[keep][k] = near[keep].get(k, 0.0) + area
        if volume[keep] < fraction * cells.cell_volume[keep]:
            heapq.heappush(heap, (volume[keep], keep))
    group = np.arange(n)
    for anchor, group_members in members.items():
        group[group_members] = anchor
    return group, dropped


def _ordered(cells: Cells, group: np.ndarray, alive: np.ndarray) -> np.ndarray:
    """Anchors (N',) of the kept groups in their new voxel order.

    A link must run from the voxel on the minus side of a face to the one on the
    plus side and from a lower to a higher voxel index. Along every link the sum
    i + j + k of the lattice indices grows by one, so ordering single cells by it
    satisfies every link; a merged voxel is placed by its members' mean sum,
    which keeps a link between two voxels in order unless their means are equal.
    Such ties are ordered by their longest chain of links within the tie (then the
    old index); a cycle of links (possible only between odd-shaped groups) stays
    out of order, and :func:`_links` leaves it unlinked.
    """
    n = len(group)
    members = np.flatnonzero(alive)
    count = np.bincount(group[members], minlength=n)
    total = np.bincount(group[members], weights=cells.ijk[members].sum(axis=1).astype(np.float64),
                        minlength=n)
    anchors = np.flatnonzero(count > 0)
    mean = np.zeros(n)
    mean[anchors] = total[anchors] / count[anchors]
    lv = cells.link_voxels.astype(np.int64)
    lv = lv[alive[lv[:, 0]] & alive[lv[:, 1]]]
    ga, gb = group[lv[:, 0]], group[lv[:, 1]]
    tied = (ga != gb) & (mean[ga] == mean[gb])
    ga, gb = ga[tied], gb[tied]
    level = np.zeros(n, dtype=np.int64)
    for _ in range(len(ga) + 1):  # longest path; more rounds than edges only on a cycle
        before = level[gb].copy()
        np.maximum.at(level, gb, level[ga] + 1)
        if np.array_equal(level[gb], before):
            break
    return anchors[np.lexsort((anchors, level[anchors], mean[anchors]))]


def _mass(cells: Cells, voxel_of: np.ndarray, count: int
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Summed volume (count,), centroid (count, 3), inertia (count, 3, 3) of the groups;
    a group of one keeps its values bit for bit."""
    ok = np.flatnonzero(voxel_of >= 0)
    owner = voxel_of[ok]
    v = cells.volume[ok]
    c = cells.centroid[ok]
    volume = np.bincount(owner, weights=v, minlength=count)
    moment = np.stack([np.bincount(owner, weights=v * c[:, i], minlength=count)
                       for i in range(3)], axis=1)
    centroid = moment / np.where(volume > 0, volume, 1.0)[:, None]
    d = c - centroid[owner]
    shift = (np.einsum("ij,ij->i", d, d)[:, None, None] * np.eye(3)
             - d[:, :, None] * d[:, None, :]) * v[:, None, None]
    inertia = np.zeros((count, 3, 3))
    np.add.at(inertia, owner, cells.inertia[ok] + shift)
    single = np.bincount(owner, minlength=count) == 1
    first = np.full(count, -1, dtype=np.int64)
    first[owner[::-1]] = ok[::-1]
    volume[single] = cells.volume[first[single]]
    centroid[single] = cells.centroid[first[single]]
    inertia[single] = cells.inertia[first[single]]
    return volume, centroid, inertia


def _triangles(cells: Cells, voxel_of: np.ndarray, anchors: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Conform triangles of the merged voxels: offsets (C'+1,), triangles (T', 3, 3),
    tags (T',), and the conform voxels (C',) (new indices, ascending).

    A merged voxel's members bring their triangles (a hexahedral member its 12 face
    triangles), except those on a face between two members."""
    n = len(cells.volume)
    count = len(anchors)
    size = np.bincount(voxel_of[voxel_of >= 0], minlength=count)
    is_conform = np.zeros(n, dtype=bool)
    is_conform[cells.conform_local] = True
    in_merged = (voxel_of >= 0) & (size[np.maximum(voxel_of, 0)] > 1)
    conform_new = np.flatnonzero(is_conform[anchors] | (size > 1))
    # triangles: every conform voxel's, then the faces of hexahedral members of merged voxels
    counts = np.diff(cells.conform_offsets)
    tri_cell = np.repeat(cells.conform_local.astype(np.int64), counts)
    hex_members = np.flatnonzero(in_merged & ~is_conform)
    hex_tris = cells.positions[hex_triangles(cells.voxel_vertices[hex_members])].reshape(-1, 3, 3)
    triangles = np.concatenate([cells.conform_triangles, hex_tris])
    tags = np.concatenate([cells.conform_tags.astype(np.int64), np.tile(np.arange(12) // 2,
                                                                        len(hex_members))])
    tri_cell = np.concatenate([tri_cell, np.repeat(hex_members, 12)])
    # faces between members of one merged voxel are inside it
    members = np.flatnonzero(in_merged)
    inside = np.zeros((n, 7), dtype=bool)
    if members.size:
        span = cells.ijk.max(axis=0) + 3
        key = _cell_keys(cells.ijk, span)
        across = cells.ijk[members][:, None, :] + FACE_OFFSETS[None, :, :]  # (M, 6, 3)
        where = np.minimum(np.searchsorted(key, _cell_keys(across, span)), n - 1)
        found = key[where] == _cell_keys(across, span)
        inside[members, :6] = found & (voxel_of[where] == voxel_of[members][:, None])
    voxel = voxel_of[tri_cell]
    keep = (voxel >= 0) & ~inside[tri_cell, tags]
    order = np.argsort(voxel[keep], kind="stable")
    triangles = triangles[keep][order]
    tags = tags[keep][order].astype(np.uint8)
    per_voxel = np.bincount(voxel[keep], minlength=count)[conform_new]
    offsets = np.concatenate([[0], np.cumsum(per_voxel)]).astype(np.int64)
    return offsets, triangles, tags, conform_new


def _cell_keys(ijk: np.ndarray, span: np.ndarray) -> np.ndarray:
    """Integer keys (...) of lattice cells (..., 3), ascending in C order, for cells
    from -1 to span - 2 along each axis."""
    ijk = np.asarray(ijk, dtype=np.int64) + 1
    return (ijk[..., 0] * span[1] + ijk[..., 1]) * span[2] + ijk[..., 2]


def _links(cells: Cells, voxel_of: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Links between the merged voxels (see the module docstring) and how many
    contacts were left unlinked."""
    lv = cells.link_voxels.astype(np.int64)
    a, b = voxel_of[lv[:, 0]], voxel_of[lv[:, 1]]
    face = cells.link_face.astype(np.int64)
    ok = (a >= 0) & (b >= 0) & (a != b)
    a, b, face = a[ok], b[ok], face[ok]
    area, mid = cells.link_area[ok], cells.link_midpoint[ok]
    # add up the contacts of one pair across one face direction
    key = np.stack([a, b, face], axis=1)
    unique, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    total = np.bincount(inverse, weights=area, minlength=len(unique))
    midpoint = np.stack([np.bincount(inverse, weights=area * mid[:, i], minlength=len(unique))
                         for i in range(3)], axis=1) / total[:, None]
    single = np.bincount(inverse, minlength=len(unique)) == 1
    first = np.full(len(unique), -1, dtype=np.int64)
    first[inverse[::-1]] = np.arange(len(inverse))[::-1]
    midpoint[single] = mid[first[single]]
    ua, ub, uf = unique[:, 0], unique[:, 1], unique[:, 2]
    keep = ua < ub  # the voxel on the minus side first (see _ordered)
    order = np.lexsort((ub[keep], ua[keep]))
    voxels = np.stack([ua[keep], ub[keep]], axis=1)[order]
    return (voxels, uf[keep][order].astype(np.uint8), midpoint[keep][order],
            total[keep][order], int(len(unique) - keep.sum()))
