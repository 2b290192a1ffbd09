"""Open parts voxelized as sheets: a window pane, a sign, a fence panel.

A part of a multi-part input whose surface is too open to have an inside (the
Cesium Milk Truck's glass and window trim: single-sided panes) cannot be filled
by the winding number. It becomes a *sheet*: every lattice cell its triangles
pass through (the exact separating-axis test of :func:`cells.mark_touched`) is
one of its voxels, one voxel thick, and takes the part's material. A sheet owns
its cells even where they lie inside another part (the pane is what shows
there), and its voxels are whole cells, never conform-clipped.

What a sheet weighs and how strongly it holds follow the real pane, not the
cells: ``thickness`` t (m, :attr:`ObjectRequest.sheet_thickness`) times the
part's area A (m²) is its volume, spread evenly over its n cells (each voxel's
volume A t / n, at most a whole cell; its inertia the cell's scaled by the same
ratio), and a link that touches a sheet voxel has the cross-section of the pane
through a cell face, t times the face's side (sqrt of its area), instead of
the whole face. So a pane's mass and the force that breaks it do not depend on
the voxel size (a 0.1 m lattice would otherwise make 6 mm glass 17 times too
heavy and 17 times too strong).
"""

from __future__ import annotations

import numpy as np

from blastvox.bounds import DEFAULT_SHEET_THICKNESS_M

__all__ = ["DEFAULT_SHEET_THICKNESS_M", "sheet_volumes", "thin_links"]


def sheet_volumes(cell_volume: np.ndarray, part: np.ndarray, sheet_area: dict[int, float],
                  thickness: float) -> np.ndarray:
    """Volume of every voxel (m³), (N,): a sheet part's voxels share its area x thickness.

    cell_volume: (N,) m³ of each voxel's cell; part: (N,) each voxel's part index;
    sheet_area: m² of each sheet part's surface, by part index; thickness: m.
    Voxels of other parts keep ``cell_volume``.
    """
    volume = np.asarray(cell_volume, dtype=np.float64).copy()
    for index, area in sheet_area.items():
        mine = part == index
        count = int(np.count_nonzero(mine))
        if count:
            volume[mine] = np.minimum(area * thickness / count, cell_volume[mine])
    return volume


def thin_links(link_voxels: np.ndarray, link_area: np.ndarray, is_sheet: np.ndarray,
               thickness: float) -> np.ndarray:
    """Link areas (m²), (L,): a link with a sheet voxel at either end carries the pane's
    section through the face, ``thickness`` x sqrt(face area), if that is smaller.

    link_voxels: (L, 2) voxel indices; link_area: (L,) m²; is_sheet: (N,) bool.
    """
    area = np.asarray(link_area, dtype=np.float64).copy()
    thin = is_sheet[link_voxels[:, 0]] | is_sheet[link_voxels[:, 1]]
    area[thin] = np.minimum(area[thin], thickness * np.sqrt(area[thin]))
    return area
