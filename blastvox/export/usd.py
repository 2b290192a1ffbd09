"""OpenUSD export: ``write_usd(cache, path, options)``.

Stage layout (``/Shot`` is the default prim; time code = frame index)::

    /Shot
      Materials/<material>, <material>_damage     UsdPreviewSurface per used material
      Materials/texture_<name>                    the source look: UsdPreviewSurface whose
                                                  diffuse colour is a UsdUVTexture of
                                                  ``<stem>_textures/<name>.png`` beside the file
      <object>/piece_00000 (Xform)                layout "xforms": pieces under an Xform
                                                  per scene object; a constant translate:start
        piece_NNNNN (Mesh)                        (double3), time-sampled translate (float3
                                                  offsets from it) and orient (quatf), visibility
          surface_<material>, damage_<material>,  for pieces that vanish; a static mesh with
          textured_<name>                         GeomSubsets (materialBind, partition), a
                                                  time-sampled per-face ``primvars:damage``
                                                  and faceVarying ``primvars:st`` (UVs in
                                                  rest space: blastvox.export.uv); a piece
                                                  of one material is bound as a whole
      Pieces (PointInstancer)                     layout "instancer": one prototype Mesh per
        Prototypes/piece_00000 (Mesh)             piece, time-sampled positions, orientations
                                                  (quath) and orientationsf (quatf, which
                                                  readers prefer), extent and invisibleIds
      Particles/<system> (Volume)                 dust, fire, smoke, fireball particles as
        density, temperature (OpenVDBAsset)       volumes: per-frame .vdb files in
                                                  ``<stem>_volumes/`` (usd_volumes.py);
      Particles/<system> (PointInstancer)         or (options.particles "spheres", .usdz) a
        Prototypes/sprite (Mesh)                  soft ball (three translucent shells) of
                                                  diameter 1 bound to
                                                  Materials/particle_<system>, scaled to
                                                  each particle's width
      Particles/<system>_glow (PointInstancer)    fire and fireball, either way: emissive
        Prototypes/sprite (Mesh)                  shells (GeomSubsets shell_0..2 bound to
                                                  Materials/particle_<system>_glow_<k>)
                                                  at blobs of hot particles, the glow
                                                  Blender imports (it reads no material
                                                  of a Volume)
      Camera                                      the scene camera, shake baked in; lens and
                                                  filmback in tenths of a metre (UsdGeomCamera)
      Effects/shock_<c> (Sphere)                  shock front of charge c, a guide prim
                                                  (renders skip it); only with options.shock

Every prim renders: a particle system never has an empty ``positions`` sample (an
empty point cloud crashed Blender 5.0's Cycles at frame 0): a frame without particles
holds a single instance of scale 0, and the instancer is invisible at those frames.

The whole layer is written through the Sdf API inside one ``Sdf.ChangeBlock``: prim,
attribute and relationship specs one call each, values from numpy (``Vt.*Array.FromNumpy``)
and time samples in bulk (:mod:`blastvox.export.usd_pieces`). Transform samples are kept
only at the ends of runs of equal values, so USD's linear interpolation reproduces the
cache at every frame. The layer is exported to a temporary file beside the output (whose
name ends in the real suffix, so USD picks the format) and moved into place. The same
cache and options give the same bytes.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

import numpy as np
from pxr import Sdf, Tf, Vt

from blastvox import __version__
from blastvox.cache import SimCache
from blastvox.errors import OutputError
from blastvox.export.damage_textures import damage_textures
from blastvox.export.options import ExportOptions
from blastvox.export.pieces import (
    animation,
    export_origin,
    piece_meshes,
    piece_objects,
    piece_parts,
    velocities,
)
from blastvox.export.usd_effects import write_camera, write_particles, write_shock
from blastvox.export.usd_pieces import write_instancer, write_materials, write_xforms
from blastvox.export.usd_specs import (
    ROOT,
    object_prim_names,
    origin_translate,
    part_prim_names,
    vec3f,
)
from blastvox.export.uv import face_uvs, texture_names
from blastvox.geometry import quaternion
from blastvox.geometry.frames import frame_change
from blastvox.geometry.transforms import rest_to_world
from blastvox.io.atomic import atomic_path


def _fps(cache: SimCache) -> float:
    fps = cache.meta.get("fps")
    if fps:
        return float(fps)
    t = cache.frame_time
    return float(1.0 / np.median(np.diff(t))) if len(t) > 1 else 24.0


def _material_names(cache: SimCache) -> list[str]:
    """Valid, unique USD identifiers for the model's materials (by index)."""
    names = list(cache.model.meta.get("materials", []))
    count = max(len(names), len(cache.model.arrays.get("material_color", ())),
                int(cache.model.voxel_material.max(initial=-1)) + 1)
    used: set[str] = set()
    out = []
    for i in range(count):
        base = Tf.MakeValidIdentifier(str(names[i])) if i < len(names) else f"material_{i}"
        name, k = base, 1
        while name in used or f"{name}_damage" in used:
            name, k = f"{base}_{k}", k + 1
        used.update((name, f"{name}_damage"))
        out.append(name)
    return out


def _material_colors(cache: SimCache, count: int) -> tuple[np.ndarray, np.ndarray]:
    a = cache.model.arrays
    color = np.full((count, 3), 0.5)
    damage = np.full((count, 3), 0.35)
    if "material_color" in a:
        color[:len(a["material_color"])] = a["material_color"]
    if "material_damage_color" in a:
        damage[:len(a["material_damage_color"])] = a["material_damage_color"]
    return color, damage


def _finite_hold(a: np.ndarray) -> np.ndarray:
    """Replace non-finite rows of (F, P, k) by the previous frame's (or 0)."""
    bad = ~np.all(np.isfinite(a), axis=-1)
    if not bad.any():
        return a
    out = a.copy()
    for f in range(len(out)):
        out[f, bad[f]] = out[f - 1, bad[f]] if f else 0.0
    return out


# ----------------------------------------------------------------------------- writer

class _Writer:
    def __init__(self, cache: SimCache, options: ExportOptions,
                 texture_dir: str | None = None, volume_out: Path | None = None) -> None:
        self.cache = cache
        self.options = options
        #: "volumes" (into the folder ``volume_out``, named ``volume_dir`` in the layer)
        #: or "spheres"
        self.particle_mode = ("volumes" if volume_out is not None
                              and options.particles in ("auto", "volumes") else "spheres")
        self.volume_out = volume_out
        self.volume_dir = volume_out.name if volume_out is not None else ""
        self.frames = cache.frame_count
        self.fps = _fps(cache)
        self.pieces = cache.piece_count
        self.instancer = options.layout == "instancer"
        self.meshes = piece_meshes(cache, options.up_axis, options.fracture_faces)
        self.anim = animation(cache, options.up_axis)
        #: float32 arrays (the instancer's positions, the particles') are relative to it
        self.origin = export_origin(self.anim)
        self.objects = piece_objects(cache)
        self.object_prims = object_prim_names(self.objects)
        self.parts = piece_parts(cache)
        self.part_prims = part_prim_names(self.objects, self.parts)
        self.change = frame_change(cache.model.meta.get("up_axis", "Y"), options.up_axis)
        self.material_names = _material_names(cache)
        self.colors, self.damage_colors = _material_colors(cache, len(self.material_names))
        self.end = np.minimum(self.anim.end_frame.astype(np.int64), self.frames)
        self.look = face_uvs(cache, self.meshes)
        self.texture_names = texture_names(cache)
        self.texture_dir = texture_dir or ""
        self._prepare_meshes()
        fractured = np.unique(self.meshes.material[self.meshes.damage]).tolist()
        self.damage_textures = {
            d.material: d for d in (damage_textures(cache, fractured, self.texture_names)
                                    if options.damage_textures else [])}
        self.layer = Sdf.Layer.CreateAnonymous("blastvox.usda")

    def build(self) -> Sdf.Layer:
        layer = self.layer
        with Sdf.ChangeBlock():
            root = layer.pseudoRoot
            shot = Sdf.PrimSpec(root, ROOT[1:], Sdf.SpecifierDef, "Xform")
            write_materials(self, shot)
            self.damage_paths: list = [None] * self.pieces
            instancer = (write_instancer(self, shot) if self.instancer
                         else write_xforms(self, shot))
            root.SetInfo("upAxis", self.options.up_axis)
            root.SetInfo("metersPerUnit", 1.0)
            layer.defaultPrim = ROOT[1:]
            fps = _fps(self.cache)
            layer.timeCodesPerSecond = fps
            layer.framesPerSecond = fps
            layer.startTimeCode = 0.0
            layer.endTimeCode = float(max(self.frames - 1, 0))
            layer.customLayerData = {
                "creator": f"blastvox {__version__}",
                "blastvox": {"pieces": self.pieces, "frames": self.frames,
                             "layout": self.options.layout},
            }
            self._damage_samples()
            if self.instancer:
                self._instancer_samples(instancer)
            write_particles(self, shot)
            write_shock(self, shot)
            write_camera(self, shot)
        return layer

    # -- numpy preparation
    def _prepare_meshes(self) -> None:
        """Everything per piece that numpy can do at once: shared points (corners
        deduplicated per piece), indices, normals, face colours and subset groups."""
        m = self.meshes
        p_count = self.pieces
        t = len(m.vertices)
        tri_piece = np.repeat(np.arange(p_count), np.diff(m.offsets))
        corners = m.vertices.reshape(-1, 3).astype(np.float32) + np.float32(0.0)  # no -0
        corner_piece = np.repeat(tri_piece, 3)
        # sorted by piece, then by the corners' float32 bit patterns (two uint64 keys: a
        # sort of two keys instead of four; equal bits are equal floats, -0 being gone)
        bits = corners.view(np.uint32).astype(np.uint64)
        order = np.lexsort(((bits[:, 1] << np.uint64(32)) | bits[:, 2],
                            (corner_piece.astype(np.uint64) << np.uint64(32)) | bits[:, 0]))
        sc, sp = corners[order], corner_piece[order]
        new = np.ones(len(order), dtype=bool)
        new[1:] = (sp[1:] != sp[:-1]) | np.any(sc[1:] != sc[:-1], axis=1)
        inverse = np.empty(len(order), dtype=np.int64)
        inverse[order] = np.cumsum(new) - 1
        self.points = sc[new]
        self.point_offsets = np.searchsorted(sp[new], np.arange(p_count + 1))
        self.indices = (inverse - self.point_offsets[corner_piece]).astype(np.int32)
        self.normals = self.look.normal.reshape(-1, 3)  # smooth where the source is
        self.face_color = (np.where(m.damage[:, None], self.damage_colors[m.material],
                                    self.colors[m.material]) if t else
                           np.zeros((0, 3))).astype(np.float32)
        self.local_face = (np.arange(t) - m.offsets[tri_piece]).astype(np.int32)
        # materialBind subsets: runs of (piece, key) after a stable sort; key is
        # material * 2 + damage, or 2 M + k for the source look's texture k
        self.texture_key = 2 * len(self.material_names)
        key = np.where(self.look.texture >= 0, self.texture_key + self.look.texture,
                       m.material.astype(np.int64) * 2 + m.damage.astype(np.int64))
        self.subset_order = np.lexsort((np.arange(t), key, tri_piece))
        sk, spc = key[self.subset_order], tri_piece[self.subset_order]
        run = np.ones(t, dtype=bool)
        run[1:] = (sk[1:] != sk[:-1]) | (spc[1:] != spc[:-1])
        starts = np.flatnonzero(run)
        self.subset_key = sk[starts]
        self.subset_piece_offsets = np.searchsorted(spc[starts], np.arange(p_count + 1))
        self.subset_start = np.append(starts, t)
        self.used_materials = (np.unique(m.material) if t else
                               np.unique(self.cache.model.voxel_material)).tolist()

    # -- names
    def material_path(self, m: int, damage: bool) -> str:
        return f"{ROOT}/Materials/{self.material_names[m]}{'_damage' if damage else ''}"

    def texture_material_path(self, k: int) -> str:
        return f"{ROOT}/Materials/texture_{self.texture_names[k]}"

    def subset(self, key: int) -> tuple[str, str]:
        """(subset name, material path) of a subset key (see _prepare_meshes)."""
        if key >= self.texture_key:
            name = self.texture_names[key - self.texture_key]
            return f"textured_{name}", self.texture_material_path(key - self.texture_key)
        material, damage = divmod(key, 2)
        return (("damage_" if damage else "surface_") + self.material_names[material],
                self.material_path(material, bool(damage)))

    # -- values
    def _damage_samples(self) -> None:
        """Time samples of each piece's per-face damage primvar, in one pass over the
        frames: a sample where a piece's damage changes, plus one on the frame before
        that holds the old values (primvars interpolate linearly between samples)."""
        c, m = self.cache, self.meshes
        frames = c.damage_frame.astype(np.int64)
        if not len(frames):
            return
        voxels = c.damage_voxel.astype(np.int64)
        values = c.damage_value.astype(np.float32) / 255.0
        valid = ((frames >= 0) & (frames < self.frames) & (voxels >= 0)
                 & (voxels < len(c.voxel_piece)))
        order = np.lexsort((np.arange(len(frames)), frames))
        order = order[valid[order]]
        frames, voxels, values = frames[order], voxels[order], values[order]
        has_faces = np.diff(m.offsets) > 0
        piece_of = c.voxel_piece.astype(np.int64)
        if not self.options.damage_samples:
            self._damage_final(frames, voxels, values, piece_of, has_faces)
            return
        level = np.zeros(len(piece_of), dtype=np.float32)
        last: dict[int, tuple[int, np.ndarray]] = {}
        set_sample = self.layer.SetTimeSample
        bounds = np.flatnonzero(np.diff(frames)) + 1
        for s, e in zip(np.concatenate([[0], bounds]).tolist(),
                        np.concatenate([bounds, [len(frames)]]).tolist(), strict=True):
            f = int(frames[s])
            level[voxels[s:e]] = values[s:e]  # later events of the same frame win
            pieces = np.unique(piece_of[voxels[s:e]])
            for p in pieces[has_faces[pieces]].tolist():
                t0, t1 = int(m.offsets[p]), int(m.offsets[p + 1])
                current = level[m.voxel[t0:t1]]
                written, previous = last.get(p, (-1, np.zeros(t1 - t0, dtype=np.float32)))
                if f > 0 and written < f - 1:
                    set_sample(self.damage_paths[p], float(f - 1),
                               Vt.FloatArray.FromNumpy(previous))
                set_sample(self.damage_paths[p], float(f), Vt.FloatArray.FromNumpy(current))
                last[p] = (f, current)

    def _damage_final(self, frames: np.ndarray, voxels: np.ndarray, values: np.ndarray,
                      piece_of: np.ndarray, has_faces: np.ndarray) -> None:
        """Without damage samples: each damaged piece's ``primvars:damage`` default is its
        final per-face value (the last event of each voxel, events in frame order), and
        ``primvars:blastvox:damageFrame`` (int, uniform) the first frame each face's
        damage is above 0 (-1: never). Constant values: Blender reads no mesh animation."""
        m = self.meshes
        level = np.zeros(len(piece_of), dtype=np.float32)
        level[voxels] = values  # later events win (frame order, stable)
        first = np.full(len(piece_of), -1, dtype=np.int64)
        hit = values > 0
        seen = np.unique(voxels[hit], return_index=True)
        first[seen[0]] = frames[hit][seen[1]]
        pieces = np.unique(piece_of[voxels])
        for p in pieces[(pieces >= 0) & (pieces < self.pieces)].tolist():
            if not has_faces[p]:
                continue
            face_voxel = m.voxel[int(m.offsets[p]):int(m.offsets[p + 1])]
            path = self.damage_paths[p]
            self.layer.GetAttributeAtPath(path).default = Vt.FloatArray.FromNumpy(
                level[face_voxel])
            mesh = self.layer.GetPrimAtPath(path.GetPrimPath())
            spec = Sdf.AttributeSpec(mesh, "primvars:blastvox:damageFrame",
                                     Sdf.ValueTypeNames.IntArray, Sdf.VariabilityVarying)
            spec.SetInfo("interpolation", "uniform")
            spec.default = Vt.IntArray.FromNumpy(first[face_voxel].astype(np.int32))

    def animation_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        pos = _finite_hold(self.anim.position)
        ori = quaternion.sign_continuous(_finite_hold(self.anim.orientation))
        return pos, ori

    def _instancer_samples(self, spec: Sdf.PrimSpec) -> None:
        p_count = self.pieces
        inst = spec.path
        self.layer.GetAttributeAtPath(inst.AppendProperty("protoIndices")).default = \
            Vt.IntArray.FromNumpy(np.arange(p_count, dtype=np.int32))
        pos, ori = self.animation_arrays()
        pos = pos - self.origin  # float32 points: relative to the instancer's translate
        origin_translate(spec, self.origin)
        # the corners of each prototype's box, turned and moved per frame, bound the instances
        lo = np.zeros((p_count, 3))
        hi = np.zeros((p_count, 3))
        has_points = np.diff(self.point_offsets) > 0
        if has_points.any():
            starts = self.point_offsets[:-1][has_points]
            lo[has_points] = np.minimum.reduceat(self.points, starts, axis=0)
            hi[has_points] = np.maximum.reduceat(self.points, starts, axis=0)
        pick = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], dtype=bool)
        corners = np.where(pick[None], hi[:, None, :], lo[:, None, :])             # (P, 8, 3)
        positions, orientations, orientationsf, extent, invisible = (
            inst.AppendProperty(n) for n in ("positions", "orientations", "orientationsf",
                                             "extent", "invisibleIds"))
        set_sample = self.layer.SetTimeSample
        ids = np.arange(p_count, dtype=np.int64)
        get = self.layer.GetAttributeAtPath
        get(inst.AppendProperty("ids")).default = Vt.Int64Array.FromNumpy(ids)
        get(inst.AppendProperty("primvars:blastvox:mass")).default = Vt.DoubleArray.FromNumpy(
            np.ascontiguousarray(self.cache.piece_mass, dtype=np.float64))
        get(inst.AppendProperty("primvars:blastvox:object")).default = Vt.StringArray(
            self.objects)
        linear, angular = velocities(self.anim)
        angular = np.degrees(angular)  # UsdGeomPointInstancer: degrees per second
        gone_count = -1
        for f in range(self.frames):
            set_sample(positions, float(f), vec3f(pos[f]))
            set_sample(inst.AppendProperty("velocities"), float(f), vec3f(linear[f]))
            set_sample(inst.AppendProperty("angularVelocities"), float(f), vec3f(angular[f]))
            quat = np.ascontiguousarray(ori[f][:, [1, 2, 3, 0]], dtype=np.float32)
            set_sample(orientationsf, float(f), Vt.QuatfArray.FromNumpy(quat))
            set_sample(orientations, float(f), Vt.QuathArray.FromNumpy(quat.astype(np.float16)))
            shown = self.end > f
            if shown.any():
                world = rest_to_world(corners[shown], pos[f][shown][:, None, :],
                                      ori[f][shown][:, None, :])
                box = np.stack([world.min(axis=(0, 1)), world.max(axis=(0, 1))]) + 0.0
            else:
                box = np.zeros((2, 3))
            set_sample(extent, float(f), vec3f(box))
            gone = ids[~shown]
            if len(gone) != gone_count:  # pieces never come back: the set only grows
                set_sample(invisible, float(f), Vt.Int64Array.FromNumpy(gone))
                gone_count = len(gone)

    def texture_files(self) -> list[tuple[str, bytes]]:
        """(name, PNG bytes) of every texture the layer's materials read: the source
        look's, then the damage textures."""
        return ([(name, self.cache.model.texture_file(k))
                 for k, name in enumerate(self.texture_names)]
                + [(d.name, d.png) for d in self.damage_textures.values()])


def build_layer(cache: SimCache, options: ExportOptions,
                texture_dir: str | None = None) -> Sdf.Layer:
    """The export as an anonymous in-memory layer (for tests and other writers);
    textured materials read their files from ``./<texture_dir>/``."""
    return _Writer(cache, options, texture_dir).build()


def write_usd(cache: SimCache, path: Path, options: ExportOptions) -> None:
    """Write ``cache`` to ``path`` (.usda, .usdc or .usd: crate), atomically. Its
    textures (the source look's, the damage textures) go beside it as PNG files in
    ``<stem>_textures/``, and with ``options.particles`` "volumes" or "auto" its
    particle volumes as .vdb files in ``<stem>_volumes/`` (both removed again if the
    USD file cannot be written)."""
    path = Path(path)
    texture_dir = f"{path.stem}_textures"
    volumes = volume_folder(path)
    volumes_existed = volumes.exists()
    before = set(volumes.iterdir()) if volumes_existed else set()
    directory = path.parent / texture_dir
    existed = directory.exists()
    written: list[Path] = []
    try:
        writer = _Writer(cache, options, texture_dir, volumes)
        layer = writer.build()
        written = _write_textures(writer.texture_files(), directory)
        _export_layer(layer, path)
    except BaseException:
        for file in written:
            with contextlib.suppress(OSError):
                file.unlink()
        if not existed:
            with contextlib.suppress(OSError):
                directory.rmdir()
        if volumes.exists():  # the volume files this export added
            if not volumes_existed:
                shutil.rmtree(volumes, ignore_errors=True)
            else:
                for file in set(volumes.iterdir()) - before:
                    with contextlib.suppress(OSError):
                        file.unlink()
        raise


def volume_folder(path: Path) -> Path:
    """``<stem>_volumes/`` beside a USD file: its particle volumes (.vdb files)."""
    return path.parent / f"{path.stem}_volumes"


def _write_textures(files: list[tuple[str, bytes]], directory: Path) -> list[Path]:
    """``files`` (name, PNG bytes) as ``directory/<name>.png`` (each written atomically)."""
    written: list[Path] = []
    if files:
        directory.mkdir(exist_ok=True)
    for name, data in files:
        target = directory / f"{name}.png"
        with atomic_path(target) as tmp:
            tmp.write_bytes(data)
        written.append(target)
    return written


def _export_layer(layer: Sdf.Layer, path: Path) -> None:
    with atomic_path(path) as tmp:
        # USD picks the file format from the suffix, so export beside the .partial file
        # under a name that ends in the real suffix, then move it onto the .partial.
        usd_tmp = tmp.with_name(tmp.name + path.suffix.lower())
        try:
            if not layer.Export(str(usd_tmp)):
                raise OutputError(f"{path}: USD could not write the file")
            os.replace(usd_tmp, tmp)
        finally:
            with contextlib.suppress(FileNotFoundError):
                usd_tmp.unlink()
