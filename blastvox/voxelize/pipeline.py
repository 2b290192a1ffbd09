"""``voxelize(requests, settings) -> VoxelModel``: the whole first stage.

Per input (one lattice each): read parts, clean them, pick cells by winding
number, place (jittered) lattice vertices, clip conform cells, measure mass
properties, link face neighbours. Then across inputs: split into objects
(connected components), assign materials and region rules, perturb yield
limits from the seed, tag foundation voxels, and pack the flat arrays.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blastvox import __version__
from blastvox.bounds import DEFAULT_MAX_VOXELS, MAX_COORDINATE_M, printable
from blastvox.errors import MeshError
from blastvox.geometry.frames import up_index
from blastvox.geometry.voxel_faces import CORNER_OFFSETS, SURFACE_BIT, SURFACE_TAG
from blastvox.io.references import ReferencePolicy
from blastvox.materials import MaterialLibrary, material_table, perturbed
from blastvox.model import VoxelModel
from blastvox.voxelize import budget, chunks
from blastvox.voxelize import cells as cellsel
from blastvox.voxelize.components import component_labels
from blastvox.voxelize.conform import (
    block_keys_for,
    clip_cells,
    local_hex_triangles,
    solid_manifold,
)
from blastvox.voxelize.diagnostics import warn_islands, warn_overlaps
from blastvox.voxelize.fill import corner_bounds, cube_fill, solid_mass_frame, triangle_bounds
from blastvox.voxelize.hashing import uniform_by_key
from blastvox.voxelize.lattice import Grid, fit_grid, spacing_for
from blastvox.voxelize.look import LookBuilder
from blastvox.voxelize.mass import hex_mass_properties, soup_mass_properties
from blastvox.voxelize.mesh_io import check_readable, load_parts, missing_textures
from blastvox.voxelize.regions import RegionRule
from blastvox.voxelize.sheets import DEFAULT_SHEET_THICKNESS_M, sheet_volumes, thin_links
from blastvox.voxelize.slivers import MIN_CONFORM_FRACTION, Cells, merge_slivers
from blastvox.voxelize.topology import (
    face_neighbours,
    hex_face_area_centroid,
    index_grid,
    tagged_area_centroid,
)

#: Triangles one voxelize reads (all objects): a 1.3 M-triangle sphere at resolution 8
#: took 47 s and 1.5 GB, 5.2 M triangles 65 s and 4 GB (issue 36)
DEFAULT_MAX_TRIANGLES = 2_000_000
#: Objects one voxelize takes: 1,000 take about 5 s, 10,000 ran past 300 s (issue 36)
DEFAULT_MAX_OBJECTS = 2_000
#: Conform cells keeping no more than this fraction of the cell volume (numerical
#: noise of the clip) are dropped; larger slivers are merged (MIN_CONFORM_FRACTION).
MIN_CLIP_FRACTION = 1e-9
#: Links whose contact area is below this fraction of the face area are not made.
MIN_LINK_FRACTION = 1e-6


@dataclass
class ObjectRequest:
    """One input mesh file and how to voxelize it.

    voxel_size: metres, (sx, sy, sz); or resolution: voxels along the longest axis.
    shape: "cube" or "conform"; jitter: fraction of the voxel size, [0, 0.5).
    material: default library material; material_map: mesh material name -> library name.
    transform: (4, 4) applied to the mesh before voxelizing.
    chunk_size: m, mean chunk size overriding the materials' (0: no chunks; None: the
    material's), see :mod:`blastvox.voxelize.chunks`.
    """

    mesh: Path
    name: str | None = None
    voxel_size: tuple[float, float, float] | None = None
    resolution: int | None = None
    shape: str = "cube"
    jitter: float = 0.0
    material: str = "concrete"
    material_map: dict[str, str] = field(default_factory=dict)
    transform: np.ndarray | None = None
    rules: list[RegionRule] = field(default_factory=list)
    chunk_size: float | None = None
    #: factor on the yields of links between voxels of two different parts of the input
    #: (1: welded like one solid)
    part_bond: float = 1.0
    #: voxels touching the ground are foundations (False: a free body standing on it)
    anchored: bool = True
    #: m, thickness of the parts too open to fill, voxelized as sheets (a window pane)
    sheet_thickness: float = DEFAULT_SHEET_THICKNESS_M
    #: how the model's metadata names the mesh (objects[i].source): the path as written
    #: in the scene file, relative to it; default ``mesh`` as given.
    source: str | None = None
    #: where the request was set, for messages: ``"scene.toml: objects[0]"``; None: the
    #: command line (messages name the flags).
    origin: str | None = None

    def recorded_source(self) -> str:
        """The mesh's name as the model records it (no absolute path from a scene)."""
        return printable(self.source if self.source is not None else self.mesh)


@dataclass
class VoxelizeSettings:
    """Settings shared by all inputs. ground: "auto", a height in metres, or None.

    min_conform_fraction: conform voxels keeping less than this fraction of their
    lattice cell's volume are merged into a neighbour (0: keep them as they are);
    see :mod:`blastvox.voxelize.slivers`.
    """

    up_axis: str = "Y"
    ground: str | float | None = "auto"
    seed: int = 0
    max_voxels: int = DEFAULT_MAX_VOXELS
    library: MaterialLibrary = field(default_factory=MaterialLibrary.builtin)
    recorded: dict = field(default_factory=dict)  # settings to record in the file
    budget_hint: str = budget.HINT  # how a refusal says to raise the budget
    min_conform_fraction: float = MIN_CONFORM_FRACTION
    references_anywhere: bool = False  # may a mesh's side files lie outside its folder?
    max_triangles: int = DEFAULT_MAX_TRIANGLES  # triangles read, all objects together
    max_objects: int = DEFAULT_MAX_OBJECTS
    #: the scene a refusal says to voxelize first with a larger budget (``blastvox run``,
    #: which has no budget flags); None: say the flag (``blastvox voxelize``)
    budget_scene: str | None = None


class Progress:
    """Progress sink; the CLI passes one that draws bars. Methods are no-ops here."""

    def start(self, description: str, total: int) -> None: ...
    def advance(self, amount: int = 1) -> None: ...
    def stop(self) -> None: ...


@dataclass
class _Lattice:
    """Voxels of one input before they are merged with the others."""

    request: ObjectRequest
    name: str
    grid: Grid
    solids: list
    ijk: np.ndarray
    part: np.ndarray
    vertex_ids: np.ndarray      # (V,) lattice vertex ids used
    positions: np.ndarray       # (V, 3)
    voxel_vertices: np.ndarray  # (N, 8) into positions
    volume: np.ndarray
    centroid: np.ndarray
    inertia: np.ndarray
    conform_local: np.ndarray   # (C,) local voxel indices
    conform_offsets: np.ndarray
    conform_triangles: np.ndarray
    conform_tags: np.ndarray
    link_voxels: np.ndarray
    link_face: np.ndarray
    link_midpoint: np.ndarray
    link_area: np.ndarray
    boundary: np.ndarray
    parts: list = field(default_factory=list)  # the input surfaces, for the look
    fill: np.ndarray | None = None  # (N,) m^3 of solid per cube voxel (fill.py), None: volume
    solid_box: np.ndarray | None = None  # (N, 2, 3) m, the bounds of each voxel's solid


def voxelize(requests: list[ObjectRequest], settings: VoxelizeSettings,
             progress: Progress | None = None,
             warn: Callable[[str], None] | None = None) -> VoxelModel:
    """Turn the requested meshes into one connected-voxel model."""
    progress = progress or Progress()
    warn = warn or (lambda message: None)
    up = up_index(settings.up_axis)
    budget.check_objects(requests, settings)
    for request in requests:  # an unreadable input fails before any work
        check_readable(Path(request.mesh))
    lattices: list[_Lattice] = []
    budget_left = settings.max_voxels
    triangles_left = [settings.max_triangles]
    for index, request in enumerate(requests):
        lattice = _voxelize_one(index, request, settings, up, budget_left, progress, warn,
                                triangles_left)
        budget_left -= len(lattice.ijk)
        lattices.append(lattice)
    warn_overlaps([(lat.name, lat.grid, lat.ijk, lat.centroid, lat.volume)
                   for lat in lattices], warn)
    return _assemble(lattices, settings, up)


def _size_label(request: ObjectRequest) -> str:
    """The setting that sizes the voxels of ``request``, for messages: the flag and its
    value (``wall.obj: --voxel-size 0.1 m``) or the scene key (``scene.toml:
    objects[0].voxel_size: 0.1 m for wall.obj``)."""
    mesh = printable(request.mesh)
    if request.voxel_size is not None:
        size = np.asarray(request.voxel_size, dtype=np.float64).reshape(-1)
        key, value = "voxel_size", f"{_fmt_size(np.broadcast_to(size, (3,)))} m"
    else:
        key, value = "resolution", f"{request.resolution}"
    if request.origin:
        return f"{request.origin}.{key}: {value} for {mesh}"
    return f"{mesh}: --{key.replace('_', '-')} {value}"


def _check_coordinates(request: ObjectRequest, parts: list) -> None:
    """Refuse vertices beyond MAX_COORDINATE_M of the origin (after the transform)."""
    reach = max(float(np.max(np.abs(p.mesh.vertices), initial=0.0)) for p in parts)
    if np.isfinite(reach) and reach <= MAX_COORDINATE_M:
        return
    moved = " after its transform" if request.transform is not None else ""
    where = f"{request.origin}.transform: " if request.origin and moved else ""
    fix = ("lower its scale or translation" if where else
           "scale it with transform.scale in a scene file")
    raise MeshError(
        f"{where}{printable(request.mesh)}: vertex coordinates reach {reach:.3g} m{moved}; "
        f"they must lie within {MAX_COORDINATE_M:g} m of the origin ({fix})")


def _voxelize_one(index: int, request: ObjectRequest, settings: VoxelizeSettings, up: int,
                  budget_left: int, progress: Progress, warn,
                  triangles_left: list[int] | None = None) -> _Lattice:
    source = printable(request.mesh)
    progress.start(f"reading {Path(source).name}", 1)
    policy = ReferencePolicy(anywhere=settings.references_anywhere)
    parts = load_parts(Path(request.mesh), policy,
                       budget.triangle_budget(request, settings, triangles_left
                                              if triangles_left is not None
                                              else [settings.max_triangles]))
    for message in missing_textures(Path(request.mesh), policy):
        warn(message)
    if request.transform is not None:
        with np.errstate(all="ignore"):  # overflow is refused just below
            for part in parts:
                part.mesh.apply_transform(request.transform)
    _check_coordinates(request, parts)
    solids = cellsel.prepare_solids(parts, warn)
    progress.advance()
    bounds = np.array([np.min([s.mesh.bounds[0] for s in solids], axis=0),
                       np.max([s.mesh.bounds[1] for s in solids], axis=0)])
    spacing = spacing_for(bounds, request.voxel_size, request.resolution)
    label = _size_label(request)
    if np.any(spacing <= 0) or not np.all(np.isfinite(spacing)):
        raise MeshError(f"{label} gives voxels of {_fmt_size(spacing)} m: the mesh is flat "
                        f"or a point")
    chunks.check_request(request, spacing, bounds)
    with np.errstate(all="ignore"):  # an open part (a sheet) has no volume
        volume = float(sum(abs(float(s.mesh.volume)) for s in solids))
    budget.check_lattice(label, bounds, spacing, volume if np.isfinite(volume) else 0.0,
                         budget_left, settings.max_voxels, settings.budget_hint)
    grid = fit_grid(bounds, spacing, up)
    progress.start(f"inside test {Path(source).name}", 1)
    conform = request.shape == "conform"
    # the cells the surface crosses: conform voxels, or what cube voxels weigh (fill.py)
    chosen = cellsel.choose_cells(solids, grid, True, warn)
    progress.advance()
    voxels = chosen.inside | chosen.touched if conform else chosen.inside
    budget.check_count(label, int(np.count_nonzero(voxels)),
                       budget_left, settings.max_voxels, settings.budget_hint)
    vertex_ids, positions, voxel_vertices = _place_vertices(
        chosen.ijk, grid, request.jitter, settings.seed, index, up)
    volume, centroid, inertia = hex_mass_properties(positions, voxel_vertices)
    cell_volume = volume.copy()
    if chosen.sheet_parts:
        volume = sheet_volumes(cell_volume, chosen.part, {
            i: float(solids[i].mesh.area) for i in chosen.sheet_parts},
            request.sheet_thickness)
        inertia *= (volume / cell_volume)[:, None, None]
    keep = chosen.inside.copy()
    conform_data = (np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros((0, 3, 3)),
                    np.zeros(0, np.uint8))
    closed = [s for i, s in enumerate(solids) if i not in chosen.sheet_parts]
    if conform:
        keep, conform_data = _clip_conform(closed, chosen, positions, voxel_vertices, volume,
                                           progress, request.origin)
        if conform_data[0].size:
            cv, cc, ci = soup_mass_properties(conform_data[2], conform_data[1])
            volume[conform_data[0]], centroid[conform_data[0]] = cv, cc
            inertia[conform_data[0]] = ci
        fill = None
    solid_box = corner_bounds(positions, voxel_vertices)
    if conform:
        solid_box[conform_data[0]] = triangle_bounds(conform_data[2], conform_data[1])
    else:
        cell_box = solid_box.copy()
        fill = cube_fill(closed, chosen, grid.shape, (positions, voxel_vertices), volume, keep,
                         centroid, solid_box, progress, request.origin)
        solid_mass_frame(volume, solid_box, cell_box, centroid, inertia)
        fill = fill[keep]
    if not keep.any():
        larger = " (a larger resolution)" if request.voxel_size is None else ""
        raise MeshError(f"{source}: no voxel lies inside the mesh at voxel size "
                        f"{_fmt_size(spacing)} m; use a smaller voxel size{larger}")
    _check_material_map(request, parts, [solids[i] for i in np.unique(chosen.part[keep])],
                        source, warn)
    # renumber to the kept voxels
    new_index = np.cumsum(keep) - 1
    conform_local = new_index[conform_data[0]]
    ijk, part = chosen.ijk[keep], chosen.part[keep]
    voxel_vertices = voxel_vertices[keep]
    used, voxel_vertices = np.unique(voxel_vertices, return_inverse=True)
    voxel_vertices = voxel_vertices.reshape(-1, 8)
    vertex_ids, positions = vertex_ids[used], positions[used]
    lat = _Lattice(request=request, name=request.name or Path(source).stem, grid=grid,
                   solids=solids, ijk=ijk, part=part, vertex_ids=vertex_ids,
                   positions=positions, voxel_vertices=voxel_vertices, volume=volume[keep],
                   centroid=centroid[keep], inertia=inertia[keep], conform_local=conform_local,
                   conform_offsets=conform_data[1], conform_triangles=conform_data[2],
                   conform_tags=conform_data[3], link_voxels=None, link_face=None,
                   link_midpoint=None, link_area=None, boundary=None, parts=parts, fill=fill,
                   solid_box=solid_box[keep])
    _link(lat)
    if conform:
        _merge_slivers(lat, cell_volume[keep], settings.min_conform_fraction, source, warn)
    if chosen.sheet_parts:
        lat.link_area = thin_links(lat.link_voxels, lat.link_area,
                                   np.isin(lat.part, chosen.sheet_parts),
                                   request.sheet_thickness)
    _boundary(lat)
    warn_islands(lat.name, lat.link_voxels, len(lat.ijk), _size_label(request), warn)
    for j, rule in enumerate(request.rules):  # a typo in a region changes nothing, silently
        if len(lat.centroid) and not rule.contains(lat.centroid).any():
            warn(f"object '{lat.name}' ({source}): its rules[{j}] ({rule.kind}) contains no "
                 f"voxel centre, so it changes nothing; check its coordinates (m, the "
                 f"scene's frame)")
    return lat


def _check_material_map(request: ObjectRequest, parts: list, used: list, source: str,
                        warn) -> None:
    """Warn about each ``material_map`` entry that gives no voxel its material: it names
    no part's material (a typo), or only parts that were skipped or hold no voxel
    (``used``: the solids that hold voxels)."""
    def materials(items) -> set[str]:
        return {(item.material or "").lower() for item in items}

    read, kept = materials(parts), materials([s.part for s in used])
    for key in request.material_map:
        if key.lower() in kept:
            continue
        if key.lower() in read:
            warn(f"{source}: material_map entry '{key}' matches only parts that were "
                 "skipped or hold no voxel; it sets no voxel's material")
        else:
            known = ", ".join(sorted(repr(m) for m in read if m)) or "none"
            warn(f"{source}: material_map entry '{key}' matches no part's material "
                 f"(the file's materials: {known})")


def _fmt_size(spacing: np.ndarray) -> str:
    if np.allclose(spacing, spacing[0]):
        return f"{spacing[0]:g}"
    return ",".join(f"{s:g}" for s in spacing)


def _place_vertices(ijk: np.ndarray, grid: Grid, jitter: float, seed: int, stream: int,
                    up: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lattice vertices of the cells: ids (V,), positions (V, 3), voxel corners (K, 8).

    Jitter moves every vertex by a uniform random fraction in [-jitter, jitter)
    of the spacing per axis, keyed by the vertex's lattice id so neighbours
    share it; vertices on the bottom layer keep their height so the object
    still rests on the ground.
    """
    nx, ny, _ = grid.shape
    corner_ijk = ijk[:, None, :] + CORNER_OFFSETS[None, :, :]  # (K, 8, 3)
    ids = corner_ijk[..., 0] + (nx + 1) * (corner_ijk[..., 1] + (ny + 1) * corner_ijk[..., 2])
    vertex_ids, inverse = np.unique(ids, return_inverse=True)
    lattice = np.stack([vertex_ids % (nx + 1), (vertex_ids // (nx + 1)) % (ny + 1),
                        vertex_ids // ((nx + 1) * (ny + 1))], axis=1)
    positions = grid.origin + lattice * grid.spacing
    if jitter > 0:
        keys = vertex_ids[:, None] * 3 + np.arange(3)[None, :]
        offset = (2.0 * uniform_by_key(seed, stream, keys) - 1.0) * jitter * grid.spacing
        offset[lattice[:, up] == 0, up] = 0.0
        positions = positions + offset
    return vertex_ids, positions, inverse.reshape(-1, 8)


def _clip_conform(solids, chosen, positions, voxel_vertices, hex_volume, progress, origin):
    label = solids[0].label
    solid = solid_manifold(solids[0].mesh, label, origin)
    for other in solids[1:]:
        solid = solid + solid_manifold(other.mesh, other.label, origin)
    candidates = np.flatnonzero(chosen.touched)
    progress.start(f"conform clip ({len(candidates):,} cells)", len(candidates))
    corners = positions[voxel_vertices[candidates]]
    local_tris = local_hex_triangles(voxel_vertices[candidates])
    clipped = clip_cells(solid, corners, local_tris, block_keys_for(chosen.ijk[candidates]),
                         MIN_CLIP_FRACTION * hex_volume[candidates], progress.advance)
    keep = chosen.inside & ~chosen.touched
    keep[candidates[clipped.cells]] = True
    return keep, (candidates[clipped.cells], clipped.offsets, clipped.triangles, clipped.tags)


def _link(lat: _Lattice) -> None:
    """Fill in the links of one lattice's voxels (one per shared face)."""
    grid = index_grid(lat.ijk, lat.grid.shape)
    neighbours = face_neighbours(lat.ijk, grid)
    is_conform = np.zeros(len(lat.ijk), dtype=bool)
    is_conform[lat.conform_local] = True
    slot = np.full(len(lat.ijk), -1, dtype=np.int64)
    slot[lat.conform_local] = np.arange(len(lat.conform_local))
    a_list, f_list, mid_list, area_list = [], [], [], []
    for f in (1, 3, 5):
        a = np.flatnonzero(neighbours[:, f] >= 0)
        b = neighbours[a, f]
        area, mid = hex_face_area_centroid(lat.positions, lat.voxel_vertices[a],
                                           np.full(len(a), f))
        full_area = area.copy()
        for side, face in ((a, f), (b, f - 1)):
            conf = is_conform[side]
            if conf.any():
                ca, cm = tagged_area_centroid(lat.conform_triangles, lat.conform_tags,
                                              lat.conform_offsets, slot[side[conf]],
                                              np.full(int(conf.sum()), face))
                smaller = ca < area[conf]
                idx = np.flatnonzero(conf)[smaller]
                area[idx], mid[idx] = ca[smaller], cm[smaller]
        ok = area > MIN_LINK_FRACTION * full_area
        a_list.append(a[ok])
        f_list.append(np.full(int(ok.sum()), f, dtype=np.uint8))
        mid_list.append(mid[ok])
        area_list.append(area[ok])
    voxels = np.stack([np.concatenate(a_list), neighbours[np.concatenate(a_list),
                                                          np.concatenate(f_list)]], axis=1)
    face = np.concatenate(f_list)
    order = np.lexsort((voxels[:, 1], voxels[:, 0]))
    lat.link_voxels, lat.link_face = voxels[order], face[order]
    lat.link_midpoint = np.concatenate(mid_list)[order]
    lat.link_area = np.concatenate(area_list)[order]


def _merge_slivers(lat: _Lattice, cell_volume: np.ndarray, fraction: float, source: str,
                   warn) -> None:
    """Merge the lattice's conform slivers into neighbours (see :mod:`.slivers`)."""
    cells = Cells(ijk=lat.ijk, part=lat.part, positions=lat.positions,
                  voxel_vertices=lat.voxel_vertices, cell_volume=cell_volume,
                  volume=lat.volume, centroid=lat.centroid, inertia=lat.inertia,
                  conform_local=lat.conform_local, conform_offsets=lat.conform_offsets,
                  conform_triangles=lat.conform_triangles, conform_tags=lat.conform_tags,
                  link_voxels=lat.link_voxels, link_face=lat.link_face,
                  link_midpoint=lat.link_midpoint, link_area=lat.link_area)
    result = merge_slivers(cells, fraction)
    if result.dropped:
        warn(f"{source}: dropped {result.dropped} conform sliver(s) below {fraction:g} of a "
             f"cell ({result.dropped_volume:.3g} m³ in all) touching no voxel to merge into")
    if result.cells is cells:
        return
    if len(result.anchor) == 0:
        raise MeshError(f"{source}: every voxel is a conform sliver below {fraction:g} of a "
                        f"cell; use a smaller voxel size")
    c = result.cells
    used, corners = np.unique(c.voxel_vertices, return_inverse=True)
    lat.vertex_ids, lat.positions = lat.vertex_ids[used], lat.positions[used]
    lat.voxel_vertices = corners.reshape(-1, 8)
    lat.ijk, lat.part = c.ijk, c.part
    lat.volume, lat.centroid, lat.inertia = c.volume, c.centroid, c.inertia
    lat.conform_local, lat.conform_offsets = c.conform_local, c.conform_offsets
    lat.conform_triangles, lat.conform_tags = c.conform_triangles, c.conform_tags
    lat.link_voxels, lat.link_face = c.link_voxels, c.link_face
    lat.link_midpoint, lat.link_area = c.link_midpoint, c.link_area
    lat.solid_box = corner_bounds(lat.positions, lat.voxel_vertices)
    lat.solid_box[lat.conform_local] = triangle_bounds(lat.conform_triangles,
                                                       lat.conform_offsets)


def _boundary(lat: _Lattice) -> None:
    """Fill in the exposed faces (and the surface bit) of one lattice's voxels."""
    linked = np.zeros((len(lat.ijk), 6), dtype=bool)
    linked[lat.link_voxels[:, 0], lat.link_face] = True
    linked[lat.link_voxels[:, 1], lat.link_face - 1] = True
    bits = (~linked).astype(np.uint8) << np.arange(6, dtype=np.uint8)
    boundary = bits.sum(axis=1).astype(np.uint8)
    # conform voxels with at least one triangle on the original surface
    owner = np.repeat(lat.conform_local, np.diff(lat.conform_offsets))
    has_surface = np.zeros(len(lat.ijk), dtype=bool)
    has_surface[owner[lat.conform_tags == SURFACE_TAG]] = True
    boundary[has_surface] |= np.uint8(1 << SURFACE_BIT)
    lat.boundary = boundary


def _assemble(lattices: list[_Lattice], settings: VoxelizeSettings, up: int) -> VoxelModel:
    library = settings.library
    objects: list[dict] = []
    material_names: list[str] = []
    per: dict[str, list[np.ndarray]] = {k: [] for k in (
        "vertices", "voxel_vertices", "voxel_ijk", "voxel_object", "material_name_idx",
        "voxel_volume", "voxel_centroid", "voxel_inertia", "voxel_boundary", "strength",
        "link_voxels", "link_face", "link_midpoint", "link_area", "conform_voxels",
        "conform_offsets", "conform_triangles", "conform_tag", "chunk_size", "voxel_side",
        "link_bond", "anchored", "voxel_fill", "voxel_part", "voxel_solid_box")}
    parts: list[dict] = []  # meta["parts"]: every input part (node) of every object
    voxel_base = vertex_base = tri_base = 0
    look = LookBuilder()

    def material_index(name: str) -> int:
        key = library[name].name
        if key not in material_names:
            material_names.append(key)
        return material_names.index(key)

    for lat in lattices:
        n = len(lat.ijk)
        labels = component_labels(lat.link_voxels, n)  # numbered by lowest voxel
        count = int(labels.max()) + 1
        for c in range(count):
            objects.append({"name": lat.name if count == 1 else f"{lat.name}.{c:03d}",
                            "source": lat.request.recorded_source(),
                            "shape": lat.request.shape,
                            "voxel_size_m": lat.grid.spacing.tolist(),
                            "jitter": lat.request.jitter, "lattice_origin_m":
                            lat.grid.origin.tolist(), "voxel_count": int((labels == c).sum())})
        object_ids = len(objects) - count + labels
        look.add_object(lat.name, lat.parts, len(parts))
        per["voxel_part"].append(len(parts) + _part_indices(lat)[lat.part])
        parts.extend({"object": lat.name, "name": part.name, "material": part.material}
                     for part in lat.parts)
        names = _voxel_materials(lat)
        scale = np.ones(n)
        for rule in lat.request.rules:
            inside = rule.contains(lat.centroid)
            if rule.material is not None:
                names[inside] = library[rule.material].name
            scale[inside] *= rule.strength_scale
        unique_names, inverse = np.unique(names, return_inverse=True)
        lookup = np.array([material_index(str(u)) for u in unique_names], dtype=np.int32)
        per["material_name_idx"].append(lookup[inverse.ravel()])
        per["vertices"].append(lat.positions)
        per["voxel_vertices"].append(lat.voxel_vertices + vertex_base)
        per["voxel_ijk"].append(lat.ijk)
        per["voxel_object"].append(object_ids)
        per["voxel_volume"].append(lat.volume)
        per["voxel_fill"].append(lat.volume if lat.fill is None else lat.fill)
        per["voxel_solid_box"].append(lat.solid_box)
        per["voxel_centroid"].append(lat.centroid)
        per["voxel_inertia"].append(lat.inertia)
        per["voxel_boundary"].append(lat.boundary)
        per["strength"].append(scale)
        per["chunk_size"].append(chunks.requested_sizes(lat.request, lat.centroid))
        per["voxel_side"].append(np.full(n, float(np.cbrt(np.prod(lat.grid.spacing)))))
        per["link_voxels"].append(lat.link_voxels + voxel_base)
        per["link_face"].append(lat.link_face)
        per["link_midpoint"].append(lat.link_midpoint)
        per["link_area"].append(lat.link_area)
        across = lat.part[lat.link_voxels[:, 0]] != lat.part[lat.link_voxels[:, 1]]
        per["link_bond"].append(np.where(across, lat.request.part_bond, 1.0))
        per["anchored"].append(np.full(n, lat.request.anchored))
        per["conform_voxels"].append(lat.conform_local + voxel_base)
        per["conform_offsets"].append(lat.conform_offsets[:-1] + tri_base)
        per["conform_triangles"].append(lat.conform_triangles)
        per["conform_tag"].append(lat.conform_tags)
        voxel_base += n
        vertex_base += len(lat.positions)
        tri_base += len(lat.conform_triangles)

    cat = {k: np.concatenate(v) if v else np.zeros(0) for k, v in per.items()}
    arrays = _material_arrays(cat, material_names, library, settings, up)
    arrays.update(
        vertices=cat["vertices"].astype(np.float64).reshape(-1, 3),
        voxel_vertices=cat["voxel_vertices"].astype(np.int32).reshape(-1, 8),
        voxel_ijk=cat["voxel_ijk"].astype(np.int32).reshape(-1, 3),
        voxel_object=cat["voxel_object"].astype(np.int32),
        voxel_part=cat["voxel_part"].astype(np.int32),
        voxel_solid_box=cat["voxel_solid_box"].astype(np.float64).reshape(-1, 2, 3),
        voxel_material=cat["material_name_idx"].astype(np.int32),
        voxel_volume=cat["voxel_volume"].astype(np.float64),
        voxel_centroid=cat["voxel_centroid"].reshape(-1, 3),
        voxel_inertia=cat["voxel_inertia"].reshape(-1, 3, 3),
        voxel_boundary=cat["voxel_boundary"].astype(np.uint8),
        link_voxels=cat["link_voxels"].astype(np.int32).reshape(-1, 2),
        link_face=cat["link_face"].astype(np.uint8),
        link_midpoint=cat["link_midpoint"].reshape(-1, 3),
        link_area=cat["link_area"].astype(np.float64),
        conform_voxels=cat["conform_voxels"].astype(np.int32),
        conform_offsets=np.append(cat["conform_offsets"], tri_base).astype(np.int64),
        conform_triangles=cat["conform_triangles"].reshape(-1, 3, 3).astype(np.float64),
        conform_tag=cat["conform_tag"].astype(np.uint8),
    )
    lv = arrays["link_voxels"]
    d = arrays["voxel_centroid"][lv[:, 1]] - arrays["voxel_centroid"][lv[:, 0]]
    arrays["link_direction"] = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    density = arrays["material_density"][arrays["voxel_material"]]
    fill = cat["voxel_fill"].astype(np.float64)  # the solid a voxel holds: its mass
    arrays["voxel_mass"] = fill * density
    arrays["voxel_inertia"] = (arrays["voxel_inertia"] * density[:, None, None]
                               * (fill / arrays["voxel_volume"])[:, None, None])
    ground = _ground_height(settings.ground, arrays["voxel_solid_box"], up)
    meta = {
        "tool_version": __version__, "up_axis": settings.up_axis, "ground_height": ground,
        "seed": settings.seed, "settings": settings.recorded, "objects": objects,
        "materials": material_names, "parts": parts,
    }
    surface, textures = look.arrays()
    if surface:  # only a textured or smooth input adds the look (others are unchanged)
        arrays.update(surface)
        meta["textures"] = textures
    _foundations(arrays, ground, up, cat["strength"], cat["anchored"].astype(bool))
    return VoxelModel(arrays=arrays, meta=meta)


def _part_indices(lat: _Lattice) -> np.ndarray:
    """(solids,) int: the index in ``lat.parts`` of each solid (a part that failed to
    clean has no solid)."""
    return np.array([next(i for i, part in enumerate(lat.parts) if part is solid.part)
                     for solid in lat.solids], dtype=np.int64)


def _voxel_materials(lat: _Lattice) -> np.ndarray:
    """Material name per voxel before region rules: object default, then mesh material."""
    library_names = {lat.request.material}
    per_part = []
    mapping = {k.lower(): v for k, v in lat.request.material_map.items()}
    for solid in lat.solids:
        own = (solid.part.material or "").lower()
        name = mapping.get(own, lat.request.material)
        per_part.append(name)
        library_names.add(name)
    # object dtype: a fixed-width str array would truncate longer names set by rules
    return np.array(per_part, dtype=object)[lat.part]


def _material_arrays(cat, material_names, library: MaterialLibrary, settings, up) -> dict:
    table = material_table(library, material_names)
    mat = cat["material_name_idx"].astype(np.int64)
    strength = cat["strength"]
    n = len(mat)
    seq = np.random.SeedSequence(settings.seed)
    rng_voxel, rng_link, rng_found, rng_chunk = (np.random.default_rng(s) for s in seq.spawn(4))
    voxel_yield = perturbed(table["material_voxel_yield_mean"][mat],
                            table["material_voxel_yield_var"][mat], rng_voxel, n) * strength
    lv = cat["link_voxels"].astype(np.int64).reshape(-1, 2)
    la, lb = mat[lv[:, 0]], mat[lv[:, 1]]
    link_mean = table["material_link_yield_mean"]
    weaker = np.where(link_mean[la] <= link_mean[lb], la, lb)
    link_strength = np.minimum(strength[lv[:, 0]], strength[lv[:, 1]])
    link_yield = perturbed(link_mean[weaker], table["material_link_yield_var"][weaker],
                           rng_link, len(lv)) * link_strength
    voxel_chunk = chunks.group(mat, cat["chunk_size"], cat["voxel_side"], cat["voxel_volume"],
                               cat["voxel_centroid"].reshape(-1, 3), lv, table, rng_chunk)
    link_yield = link_yield * chunks.bond_factor(voxel_chunk, lv,
                                                 table["material_chunk_bond_scale"][weaker])
    link_yield = link_yield * cat["link_bond"]  # touching parts: ObjectRequest.part_bond
    table.update(voxel_yield=voxel_yield, link_yield=link_yield, voxel_chunk=voxel_chunk,
                 voxel_combustibility=table["material_combustibility"][mat].astype(np.float64),
                 _rng_found=np.asarray(rng_found.random(n)))
    return table


def _ground_height(ground, solid_box: np.ndarray, up: int) -> float | None:
    """The ground plane's height (m along ``up``): as set, or "auto", the lowest point of
    the voxels' solid (solid_box (N, 2, 3) m), not of their cells: a crate whose cells
    reach below its mesh stands on the ground with the rest."""
    if ground is None or ground == "none":
        return None
    if ground == "auto":
        return float(solid_box[:, 0, up].min())
    return float(ground)


def _foundations(arrays: dict, ground: float | None, up: int, strength: np.ndarray,
                 anchored: np.ndarray) -> None:
    """Tag voxels touching the ground (of anchored objects, (N,) bool) and give them
    perturbed foundation yields."""
    u = arrays.pop("_rng_found")
    n = len(arrays["voxel_mass"])
    if ground is None:
        arrays["voxel_foundation"] = np.zeros(n, dtype=bool)
        arrays["voxel_foundation_yield"] = np.zeros(n)
        return
    lowest = arrays["voxel_solid_box"][:, 0, up]  # where its solid reaches down to
    size = np.cbrt(np.maximum(arrays["voxel_volume"], 0.0))
    found = (lowest <= ground + 1e-3 * size) & anchored
    mat = arrays["voxel_material"]
    mean = arrays["material_foundation_yield"][mat]
    voxel_mean = arrays["material_voxel_yield_mean"][mat]
    rel = np.divide(arrays["material_voxel_yield_var"][mat], voxel_mean, out=np.zeros(n),
                    where=np.isfinite(voxel_mean) & (voxel_mean > 0))
    value = mean * (1.0 + rel * (2.0 * u - 1.0)) * strength
    arrays["voxel_foundation"] = found
    arrays["voxel_foundation_yield"] = np.where(found, np.maximum(value, 0.0), 0.0)
