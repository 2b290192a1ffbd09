"""Reading input meshes into solid parts.

Surface formats (OBJ, STL, PLY, OFF, glTF/GLB, ...) go through trimesh; scene
graphs are flattened with their node transforms, one part per node. Volume
formats that meshio reads (.vtu, .vtk, .msh, ... with tetrahedra or hexahedra)
become their boundary surface. Every failure is a :class:`MeshError` naming the
file and the problem.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from blastvox.errors import MeshError
from blastvox.geometry.voxel_faces import VTK_CELL_FACES

#: Suffixes read through meshio as volume meshes rather than through trimesh.
VOLUME_SUFFIXES = {".vtu", ".vtk", ".msh", ".mesh", ".xdmf", ".med", ".inp", ".vol"}


@dataclass
class Part:
    """One surface of an input file, in the file's coordinates (metres).

    mesh: the triangle surface after the node transform.
    name: node or geometry name, for messages and object names.
    material: the mesh's own material or group name, or None.
    source: the file it came from.
    """

    mesh: trimesh.Trimesh
    name: str
    material: str | None
    source: Path


def load_parts(path: Path) -> list[Part]:
    """Read ``path`` into a list of :class:`Part` (at least one, each non-empty)."""
    path = Path(path)
    if not path.exists():
        raise MeshError(f"{path}: no such file")
    if not path.is_file():
        raise MeshError(f"{path}: not a file")
    if path.stat().st_size == 0:
        raise MeshError(f"{path}: file is empty")
    suffix = path.suffix.lower()
    parts = _load_volume(path) if suffix in VOLUME_SUFFIXES else _load_surface(path)
    parts = [p for p in parts if len(p.mesh.faces) > 0]
    if not parts:
        raise MeshError(f"{path}: contains no triangles")
    for part in parts:
        if not np.all(np.isfinite(part.mesh.vertices)):
            raise MeshError(f"{path}: part '{part.name}' has NaN or infinite vertex coordinates")
    return parts


def _load_surface(path: Path) -> list[Part]:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(path, force="scene", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise MeshError(f"{path}: cannot read mesh ({reason})") from None
    parts: list[Part] = []
    for node in sorted(loaded.graph.nodes_geometry):
        transform, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh):
            continue  # point clouds and paths carry no volume
        mesh = trimesh.Trimesh(vertices=np.asarray(geom.vertices, dtype=np.float64),
                               faces=np.asarray(geom.faces), process=False)
        mesh.apply_transform(transform)
        material = getattr(getattr(geom.visual, "material", None), "name", None)
        name = node if node != path.name else path.stem
        parts.append(Part(mesh=mesh, name=str(name), material=material, source=path))
    return parts


def _load_volume(path: Path) -> list[Part]:
    import meshio

    try:
        vol = meshio.read(path)
    except Exception as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise MeshError(f"{path}: cannot read volume mesh ({reason})") from None
    faces = []
    for block in vol.cells:
        local = VTK_CELL_FACES.get(block.type)  # the cell's outward boundary triangles
        if local is None:
            continue
        faces.append(block.data[:, local].reshape(-1, 3))
    if not faces:
        kinds = ", ".join(sorted({b.type for b in vol.cells})) or "none"
        raise MeshError(f"{path}: no tetrahedra or hexahedra in volume mesh (cell types: {kinds})")
    all_faces = np.concatenate(faces)
    # A face shared by two cells is interior; boundary faces occur once.
    key = np.sort(all_faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = all_faces[counts[inverse.ravel()] == 1]
    points = np.asarray(vol.points, dtype=np.float64)
    if points.shape[1] == 2:
        raise MeshError(f"{path}: volume mesh is 2-D; need 3-D cells")
    mesh = trimesh.Trimesh(vertices=points, faces=boundary, process=False)
    mesh.remove_unreferenced_vertices()
    return [Part(mesh=mesh, name=path.stem, material=None, source=path)]
