"""Cleaning and checking input surfaces before the inside test.

Repairs are the ones trimesh does well: merging split vertices (ignoring UV
and normal seams), dropping degenerate and duplicate triangles, making winding
consistent within each shell and filling small holes; then each closed shell
is turned to face the way its nesting says (outward, or inward for a sealed
cavity: :mod:`blastvox.voxelize.shells`), so the winding number keeps cavities
hollow. A surface still too open to have an inside (a triangle soup, a single
sheet) is refused with a one-line :class:`MeshError` naming the file and the
defect.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import trimesh

from blastvox.bounds import printable
from blastvox.errors import MeshError
from blastvox.voxelize.mesh_io import Part
from blastvox.voxelize.shells import orient_shells

#: Largest fraction of inside cells whose winding number is ambiguous (rays
#: through holes disagree) before a surface counts as too open to voxelize.
MAX_AMBIGUOUS_FRACTION = 0.15


@dataclass
class SurfaceReport:
    """What was found and done to one part's surface."""

    triangles_in: int
    triangles_out: int
    open_edges: int
    repairs: list[str] = field(default_factory=list)

    @property
    def watertight(self) -> bool:
        return self.open_edges == 0


def prepare_surface(part: Part) -> tuple[trimesh.Trimesh, SurfaceReport]:
    """Return a cleaned copy of ``part.mesh``, every shell oriented by its nesting
    (material on the inside of each shell's normals), and a report."""
    mesh = part.mesh.copy()
    report = SurfaceReport(triangles_in=len(mesh.faces), triangles_out=0, open_edges=0)
    where = printable(part.source) + (
        f" (part '{part.name}')" if part.name != printable(part.source.stem) else "")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mesh.merge_vertices(merge_tex=True, merge_norm=True)
        keep = mesh.nondegenerate_faces(height=1e-12 * max(float(mesh.scale), 1e-30))
        if not keep.all():
            report.repairs.append(f"dropped {int((~keep).sum())} degenerate triangles")
            mesh.update_faces(keep)
        unique = mesh.unique_faces()
        if len(unique) != len(mesh.faces):
            report.repairs.append(f"dropped {len(mesh.faces) - len(unique)} duplicate triangles")
            mesh.update_faces(unique)
        mesh.remove_unreferenced_vertices()
        if len(mesh.faces) == 0:
            raise MeshError(f"{where}: every triangle is degenerate (zero area)")
        if not mesh.is_winding_consistent or not mesh.is_watertight:
            trimesh.repair.fix_winding(mesh)
        open_before = _open_edges(mesh)
        if open_before and _is_soup(mesh):
            raise MeshError(f"{where}: is a triangle soup ({len(mesh.faces)} triangles, most "
                            f"sharing no edge), not a closed solid; inside is undefined")
        if open_before:
            trimesh.repair.fill_holes(mesh)
            filled = open_before - _open_edges(mesh)
            if filled > 0:
                report.repairs.append(f"closed {filled} open edges by filling holes")
        report.repairs.extend(orient_shells(mesh))
    report.open_edges = _open_edges(mesh)
    report.triangles_out = len(mesh.faces)
    if mesh.is_watertight:
        _check_volume(mesh, where)
    return mesh, report


#: Mean thickness (2 volume / area), as a fraction of the bounding box's diagonal, below
#: which a closed surface is a flattened shell: its two sides lie so close that winding
#: numbers at points between them are round-off, and cells come out at random.
MIN_THICKNESS_FRACTION = 1e-6


def _check_volume(mesh: trimesh.Trimesh, where: str) -> None:
    """Refuse a closed surface that encloses no volume, or too little to have a defined
    inside (a 1 x 1 m box 1 nm thick gave a quarter of its cells in a staircase)."""
    if mesh.volume <= 0:
        raise MeshError(f"{where}: encloses no volume (all triangles coplanar or inverted)")
    thickness = 2.0 * float(mesh.volume) / max(float(mesh.area), 1e-300)
    diagonal = float(np.linalg.norm(mesh.extents))
    if thickness < MIN_THICKNESS_FRACTION * diagonal:
        raise MeshError(f"{where}: encloses almost no volume ({thickness:.3g} m thick on "
                        f"average across {diagonal:.3g} m): a flattened shell has no inside "
                        "to voxelize; give it a thickness")


def check_inside_defined(where: str, winding: np.ndarray, report: SurfaceReport) -> np.ndarray:
    """Occupancy from a winding-number field, refusing surfaces too open to have an inside.

    winding: ray-averaged winding numbers at cell centres (any shape).
    Returns the boolean occupancy (winding > 1/2).
    """
    inside = winding > 0.5
    n_inside = int(np.count_nonzero(inside))
    ambiguous = int(np.count_nonzero((winding > 0.2) & (winding < 0.8)))
    if n_inside == 0 and max(winding.shape, default=0) <= 2:  # two cells across at most
        raise MeshError(f"{where}: no voxel centre lies inside it at this voxel size, two "
                        f"voxels across at most; use a smaller voxel size (or a higher resolution)")
    if report.open_edges and (n_inside == 0 or ambiguous > MAX_AMBIGUOUS_FRACTION * n_inside):
        raise MeshError(
            f"{where}: is an open surface, not a closed solid ({report.open_edges} open edges "
            f"after repair; inside/outside ambiguous for {ambiguous} cells vs {n_inside} inside)")
    return inside


def _open_edges(mesh: trimesh.Trimesh) -> int:
    """Number of edges used by exactly one triangle."""
    groups = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
    return int(len(groups))


def _is_soup(mesh: trimesh.Trimesh) -> bool:
    """True if most triangles share no edge with any other triangle."""
    adjacency = mesh.face_adjacency
    connected = np.zeros(len(mesh.faces), dtype=bool)
    connected[adjacency.ravel()] = True
    return connected.mean() < 0.5
