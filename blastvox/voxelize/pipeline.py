"""``voxelize(requests, settings) -> VoxelModel``: the whole first stage.

Per input (one lattice each): read parts, clean them, pick cells by winding
number, place (jittered) lattice vertices, clip conform cells, measure mass
properties, link face neighbours. Then across inputs (:mod:`blastvox.voxelize.assemble`):
split into objects (connected components), assign materials and region rules, perturb
yield limits from the seed, tag foundation voxels, and pack the flat arrays.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blastvox.bounds import DEFAULT_MAX_VOXELS, MAX_COORDINATE_M, printable
from blastvox.errors import MeshError
from blastvox.geometry.frames import up_index
from blastvox.geometry.voxel_faces import CORNER_OFFSETS, SURFACE_BIT, SURFACE_TAG
from blastvox.io.references import ReferencePolicy
from blastvox.materials import MaterialLibrary
from blastvox.model import VoxelModel
from blastvox.voxelize import budget, chunks
from blastvox.voxelize import cells as cellsel
from blastvox.voxelize.assemble import Lattice, assemble, release_freed_memory
from blastvox.voxelize.conform import (
    block_keys_for,
    clip_cells,
    solid_manifold,
)
from blastvox.voxelize.diagnostics import warn_islands, warn_overlaps
from blastvox.voxelize.fill import corner_bounds, cube_fill, solid_mass_frame, triangle_bounds
from blastvox.voxelize.hashing import uniform_by_key
from blastvox.voxelize.lattice import Grid, fit_grid, spacing_for
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
    lattices: list[Lattice] = []
    budget_left = settings.max_voxels
    triangles_left = [settings.max_triangles]
    for index, request in enumerate(requests):
        lattices.append(_voxelize_one(index, request, settings, up, budget_left, progress,
                                      warn, triangles_left))
        budget_left -= len(lattices[-1].ijk)
        release_freed_memory()  # its cells' and clips' work arrays
    warn_overlaps([(lat.name, lat.grid, lat.ijk, lat.centroid, lat.volume)
                   for lat in lattices], warn)
    return assemble(lattices, settings, up)  # consumes the lattices


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
                  triangles_left: list[int] | None = None) -> Lattice:
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
    lat = Lattice(request=request, name=request.name or Path(source).stem, grid=grid,
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
    clipped = clip_cells(solid, positions, voxel_vertices[candidates],
                         block_keys_for(chosen.ijk[candidates]),
                         MIN_CLIP_FRACTION * hex_volume[candidates], progress.advance)
    keep = chosen.inside & ~chosen.touched
    keep[candidates[clipped.cells]] = True
    return keep, (candidates[clipped.cells], clipped.offsets, clipped.triangles, clipped.tags)


def _link(lat: Lattice) -> None:
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


def _merge_slivers(lat: Lattice, cell_volume: np.ndarray, fraction: float, source: str,
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


def _boundary(lat: Lattice) -> None:
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
