"""Which lattice cells of one input become voxels, and of which part.

One input file gives one lattice. Each solid part of the file gets a
ray-averaged winding number per cell; a cell whose centre is inside some part
is occupied and takes that part (the later part wins where parts overlap). In
conform mode every cell the surface passes through is a candidate as well; the
conform clip decides later whether it keeps any volume. A part too open to have an
inside, beside parts that have one, becomes a sheet (:mod:`blastvox.voxelize.sheets`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from blastvox.bounds import printable
from blastvox.errors import MeshError
from blastvox.jit import kernel
from blastvox.voxelize.lattice import Grid
from blastvox.voxelize.mesh_io import Part
from blastvox.voxelize.occupancy import winding_numbers
from blastvox.voxelize.surface import SurfaceReport, check_inside_defined, prepare_surface


@dataclass
class Solid:
    """A cleaned part ready for the inside test."""

    part: Part
    mesh: trimesh.Trimesh
    report: SurfaceReport

    @property
    def label(self) -> str:
        return part_label(self.part)


@dataclass
class CellSet:
    """Cells chosen on one lattice.

    ijk: (K, 3) int64 lattice indices in C order; part: (K,) index into the
    solids; inside: (K,) centre inside a solid; touched: (K,) the surface passes
    through the cell (conform candidates; never a sheet's cell, which is whole);
    sheet_parts: indices of the solids that are sheets.
    """

    ijk: np.ndarray
    part: np.ndarray
    inside: np.ndarray
    touched: np.ndarray
    sheet_parts: list[int]


def part_label(part: Part) -> str:
    """How messages name a part: the file, plus the node when the file has several."""
    source = printable(part.source)
    if part.name in (printable(part.source.stem), printable(part.source.name)):
        return source
    return f"{source} (part '{part.name}')"


def prepare_solids(parts: list[Part], warn) -> list[Solid]:
    """Clean every part; skip broken parts with a warning if others survive."""
    solids: list[Solid] = []
    errors: list[MeshError] = []
    for part in parts:
        try:
            mesh, report = prepare_surface(part)
        except MeshError as exc:
            errors.append(exc)
            continue
        solids.append(Solid(part, mesh, report))
    if not solids:
        raise errors[0]
    for exc in errors:
        warn(f"skipped {exc}")
    return solids


def choose_cells(solids: list[Solid], grid: Grid, conform: bool, warn) -> CellSet:
    """Occupied (and, in conform mode, surface-touched) cells of ``grid``."""
    best = np.zeros(grid.shape, dtype=np.float32)
    owner = np.full(grid.shape, -1, dtype=np.int32)
    occupied = np.zeros(grid.shape, dtype=bool)
    touched = np.zeros(grid.shape, dtype=bool)
    sheets: list[tuple[int, np.ndarray]] = []
    kept = 0
    for index, solid in enumerate(solids):
        winding = winding_numbers(solid.mesh.triangles, grid.origin, grid.spacing, grid.shape)
        try:
            inside = check_inside_defined(solid.label, winding, solid.report)
        except MeshError:
            if len(solids) == 1:
                raise
            sheets.append((index, _touched_cells(solid, grid, sheet=True)))
            continue
        kept += 1
        occupied |= inside
        owner[inside] = index
        if conform:
            mark = _touched_cells(solid, grid)
            touched |= mark
            closer = mark & ~inside & (winding > best)
            owner[closer & (owner < 0)] = index
        best = np.maximum(best, winding)
    if kept == 0:
        raise _nothing_inside(solids, grid)
    for index, mark in sheets:
        warn(f"{solids[index].label}: an open surface ({solids[index].report.open_edges} open "
             f"edges): voxelized as a sheet one voxel deep ({int(mark.sum()):,} cells)")
    sheet = np.zeros(grid.shape, dtype=bool)
    for index, mark in sheets:  # a pane owns its cells, inside another part or not
        sheet |= mark
        owner[mark] = index
    occupied |= sheet
    touched &= ~sheet
    chosen = occupied | touched
    ijk = np.argwhere(chosen)
    part = owner[chosen]
    # a touched cell outside every part: give it the part whose surface touched it first
    part = np.where(part < 0, 0, part)
    return CellSet(ijk=ijk.astype(np.int64), part=part.astype(np.int64),
                   inside=occupied[chosen], touched=touched[chosen],
                   sheet_parts=[index for index, _ in sheets])


def _nothing_inside(solids: list[Solid], grid: Grid) -> MeshError:
    """The error when no part of a multi-part input kept a cell: the voxels are too
    large for it if a part is closed (a closed part has an inside, so none of its cells'
    centres lay in it) or the grid is two cells across at most, else the parts are open
    surfaces with no closed part for them to be sheets beside."""
    source = printable(solids[0].part.source)
    if max(grid.shape) <= 2 or any(solid.report.open_edges == 0 for solid in solids):
        sizes = [f"{float(x):.4g}" for x in grid.spacing]
        size = sizes[0] if len(set(sizes)) == 1 else ",".join(sizes)
        return MeshError(f"{source}: no voxel centre lies inside any of its parts at voxel "
                         f"size {size} m; use a smaller voxel size (or a higher resolution)")
    return MeshError(f"{source}: no part encloses a volume (open surfaces become sheets "
                     f"only beside a closed part)")


def _touched_cells(solid: Solid, grid: Grid, sheet: bool = False) -> np.ndarray:
    """Boolean grid of the cells ``solid``'s triangles pass through. For a ``sheet``
    only cells it passes through with some area count: each triangle is moved by
    1e-5 of a cell along its normal and tested against cells shrunk by 1e-6, so a
    pane lying in a cell face takes the cells on one side (one voxel deep, not two)
    and an edge lying in a face takes no cell."""
    triangles = np.asarray(solid.mesh.triangles, dtype=np.float64)
    grow = 1e-9
    if sheet:
        normals = np.asarray(solid.mesh.face_normals, dtype=np.float64)
        triangles = triangles + 1e-5 * float(grid.spacing.min()) * normals[:, None, :]
        grow = -1e-6
    mark = np.zeros(grid.shape, dtype=bool)
    _mark_touched(np.ascontiguousarray(triangles), grid.origin, grid.spacing,
                  np.asarray(grid.shape, dtype=np.int64), mark, grow)
    return mark


@kernel
def _tri_box_overlap(v0, v1, v2, half) -> bool:
    """Separating-axis test of a triangle (vertices relative to the box centre) and a box.

    T. Akenine-Moller, "Fast 3D triangle-box overlap testing", JGT 2001; the
    box is grown by a relative 1e-9 so faces lying exactly on a cell face count.
    """
    e0 = v1 - v0
    e1 = v2 - v1
    e2 = v0 - v2
    edges = (e0, e1, e2)
    for a in range(3):  # 9 axes: box axis a x triangle edge
        for e in edges:
            ax = np.zeros(3)
            ax[(a + 1) % 3] = -e[(a + 2) % 3]
            ax[(a + 2) % 3] = e[(a + 1) % 3]
            p0 = ax[0] * v0[0] + ax[1] * v0[1] + ax[2] * v0[2]
            p1 = ax[0] * v1[0] + ax[1] * v1[1] + ax[2] * v1[2]
            p2 = ax[0] * v2[0] + ax[1] * v2[1] + ax[2] * v2[2]
            r = half[0] * abs(ax[0]) + half[1] * abs(ax[1]) + half[2] * abs(ax[2])
            if min(p0, p1, p2) > r or max(p0, p1, p2) < -r:
                return False
    n = np.cross(e0, e1)
    d = n[0] * v0[0] + n[1] * v0[1] + n[2] * v0[2]
    r = half[0] * abs(n[0]) + half[1] * abs(n[1]) + half[2] * abs(n[2])
    return abs(d) <= r


@kernel
def _mark_touched(tri, origin, spacing, shape, mark, grow):
    """Mark cells that a triangle overlaps (exact separating-axis test per cell, each
    cell grown by the relative ``grow``: > 0 counts a triangle lying in a cell face,
    < 0 does not)."""
    half = 0.5 * spacing * (1.0 + grow)
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    centre = np.empty(3)
    for t in range(tri.shape[0]):
        for a in range(3):
            mn = min(tri[t, 0, a], tri[t, 1, a], tri[t, 2, a])
            mx = max(tri[t, 0, a], tri[t, 1, a], tri[t, 2, a])
            lo[a] = max(0, int(np.floor((mn - origin[a]) / spacing[a] - 1e-9)))
            hi[a] = min(shape[a] - 1, int(np.floor((mx - origin[a]) / spacing[a] + 1e-9)))
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                for k in range(lo[2], hi[2] + 1):
                    if mark[i, j, k]:
                        continue
                    centre[0] = origin[0] + (i + 0.5) * spacing[0]
                    centre[1] = origin[1] + (j + 0.5) * spacing[1]
                    centre[2] = origin[2] + (k + 0.5) * spacing[2]
                    if _tri_box_overlap(tri[t, 0] - centre, tri[t, 1] - centre,
                                        tri[t, 2] - centre, half):
                        mark[i, j, k] = True
