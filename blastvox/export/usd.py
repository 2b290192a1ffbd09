"""OpenUSD export: ``write_usd(cache, path, options)``.

Stage layout (``/Shot`` is the default prim, time code = frame index)::

    /Shot
      Materials/<material>, <material>_damage     UsdPreviewSurface per used material
      Pieces/piece_00000 (Xform)                  layout "xforms": animated translate + orient,
        geom (Mesh)                               time-sampled visibility; static mesh with
          surface_<material>, damage_<material>   GeomSubsets (materialBind partition) and a
                                                  time-sampled per-face ``primvars:damage``
      Pieces (PointInstancer)                     layout "instancer": one prototype per piece,
        Prototypes/piece_00000 (Mesh)             time-sampled positions, orientations and
                                                  invisibleIds
      Particles/dust (Points)                     destroyed voxels, ballistic for DUST_LIFE_S
      Effects/shock_<c> (Sphere)                  shock front of charge c

Everything is authored with the Sdf layer API (the Usd stage API is ~10x slower
for hundreds of thousands of time samples) into an anonymous layer that is then
exported to a temporary file beside the output and moved into place. Time
samples are kept only at the ends of runs of equal values, so USD's linear
interpolation between samples reproduces the cache exactly at every frame.
The output is byte-identical for the same cache and options.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Tf, Vt

from blastvox import __version__
from blastvox.cache import SimCache
from blastvox.export.api import ExportOptions
from blastvox.export.pieces import PieceMeshes, animation, frame_change, piece_meshes
from blastvox.io.atomic import atomic_path

ROOT = "/Shot"
DUST_LIFE_S = 2.0
ROUGHNESS = 0.8
SHOCK_COLOR = (0.9, 0.9, 0.95)
_T = Sdf.ValueTypeNames
_UNIFORM = Sdf.VariabilityUniform


# ----------------------------------------------------------------------------- Sdf helpers

def _prim(parent: Sdf.PrimSpec, name: str, type_name: str = "") -> Sdf.PrimSpec:
    return Sdf.PrimSpec(parent, name, Sdf.SpecifierDef, type_name)


def _attr(prim: Sdf.PrimSpec, name: str, type_name, value=None, uniform: bool = False,
          interpolation: str | None = None) -> Sdf.AttributeSpec:
    spec = Sdf.AttributeSpec(prim, name, type_name, _UNIFORM if uniform else
                             Sdf.VariabilityVarying)
    if value is not None:
        spec.default = value
    if interpolation is not None:
        spec.SetInfo("interpolation", interpolation)
    return spec


def _rel(prim: Sdf.PrimSpec, name: str, targets: list[Sdf.Path]) -> Sdf.RelationshipSpec:
    spec = Sdf.RelationshipSpec(prim, name, False)
    spec.targetPathList.explicitItems = targets
    return spec


def _apply_binding_api(prim: Sdf.PrimSpec) -> None:
    prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["MaterialBindingAPI"]))


def _bind(prim: Sdf.PrimSpec, material: Sdf.Path) -> None:
    _apply_binding_api(prim)
    _rel(prim, "material:binding", [material])


def _xform_order(prim: Sdf.PrimSpec, ops: list[str]) -> None:
    _attr(prim, "xformOpOrder", _T.TokenArray, Vt.TokenArray(ops), uniform=True)


def _vec3f(a: np.ndarray) -> Vt.Vec3fArray:
    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1, 3))


def _extent(points: np.ndarray) -> Vt.Vec3fArray:
    if len(points) == 0:
        return _vec3f(np.zeros((2, 3)))
    return _vec3f(np.stack([points.min(axis=0), points.max(axis=0)]))


def _run_ends(values: np.ndarray) -> np.ndarray:
    """(F,) bool: frames that start or end a run of equal values along axis 0 (F, ...)."""
    f = len(values)
    if f == 0:
        return np.zeros(0, dtype=bool)
    diff = (values[1:] != values[:-1]).reshape(f - 1, -1).any(axis=1) if f > 1 else \
        np.zeros(0, dtype=bool)
    keep = np.zeros(f, dtype=bool)
    keep[0] = True
    keep[1:] |= diff     # first frame of a new value
    keep[:-1] |= diff    # last frame of the old value (so interpolation holds it)
    return keep


# ----------------------------------------------------------------------------- data prep

def _fps(cache: SimCache) -> float:
    fps = cache.meta.get("fps")
    if fps:
        return float(fps)
    t = cache.frame_time
    return float(1.0 / np.median(np.diff(t))) if len(t) > 1 else 24.0


def _material_names(cache: SimCache) -> list[str]:
    """Valid, unique USD identifiers for the model's materials (by index)."""
    names = list(cache.model.meta.get("materials", []))
    count = len(cache.model.arrays.get("material_color", np.zeros((0, 3))))
    used: set[str] = set()
    out = []
    for i in range(max(count, len(names), int(cache.model.voxel_material.max(initial=-1)) + 1)):
        base = Tf.MakeValidIdentifier(str(names[i])) if i < len(names) else f"material_{i}"
        name, k = base, 1
        while name in used or name.endswith("_damage") and name[:-7] in used:
            name, k = f"{base}_{k}", k + 1
        used.add(name)
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


def _sign_continuous(q: np.ndarray) -> np.ndarray:
    """Flip quaternions (F, P, 4) so consecutive frames have a non-negative dot product
    (the same rotations; interpolation then takes the short way)."""
    if len(q) < 2:
        return q
    dots = np.einsum("fpi,fpi->fp", q[1:], q[:-1])
    sign = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
    out = q.copy()
    out[1:] *= sign[..., None]
    return out


def _finite_hold(a: np.ndarray) -> np.ndarray:
    """Replace non-finite frames (F, P, k) by the last finite one (or 0)."""
    bad = ~np.all(np.isfinite(a), axis=-1)
    if not bad.any():
        return a
    out = a.copy()
    for f in range(len(out)):
        rows = bad[f]
        out[f, rows] = out[f - 1, rows] if f else 0.0
    return out


def _face_damage_events(cache: SimCache, meshes: PieceMeshes):
    """Per piece: sorted frames where any of its faces' damage changes."""
    frames = cache.damage_frame.astype(np.int64)
    voxels = cache.damage_voxel.astype(np.int64)
    values = cache.damage_value.astype(np.float32) / 255.0
    n = len(cache.voxel_piece)
    has_face = np.zeros(n, dtype=bool)
    has_face[meshes.voxel] = True
    keep = has_face[voxels] & (frames >= 0) & (frames < max(cache.frame_count, 1))
    frames, voxels, values = frames[keep], voxels[keep], values[keep]
    piece = cache.voxel_piece.astype(np.int64)[voxels]
    order = np.lexsort((np.arange(len(frames)), frames, piece))
    return piece[order], frames[order], voxels[order], values[order]


# ----------------------------------------------------------------------------- builders

class _Writer:
    def __init__(self, cache: SimCache, options: ExportOptions) -> None:
        self.cache = cache
        self.options = options
        self.frames = cache.frame_count
        self.layer = Sdf.Layer.CreateAnonymous("blastvox.usda")
        self.meshes = piece_meshes(cache, options.up_axis)
        self.anim = animation(cache, options.up_axis)
        self.change = frame_change(cache.model.meta.get("up_axis", "Y"), options.up_axis)
        self.material_names = _material_names(cache)
        self.colors, self.damage_colors = _material_colors(cache, len(self.material_names))

    # -- stage
    def build(self) -> Sdf.Layer:
        layer = self.layer
        with Sdf.ChangeBlock():
            root = layer.pseudoRoot
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
                "blastvox": {"pieces": self.cache.piece_count, "frames": self.frames,
                             "layout": self.options.layout},
            }
            shot = _prim(root, ROOT[1:], "Xform")
            self._materials(shot)
            if self.options.layout == "instancer":
                self._instancer(shot)
            else:
                self._xforms(shot)
            self._dust(shot)
            self._shock(shot)
        return layer

    # -- materials
    def _materials(self, shot: Sdf.PrimSpec) -> None:
        scope = _prim(shot, "Materials", "Scope")
        self.used = np.unique(self.meshes.material) if len(self.meshes.material) else \
            np.unique(self.cache.model.voxel_material)
        for m in self.used:
            name = self.material_names[m]
            self._preview_surface(scope, name, self.colors[m])
            self._preview_surface(scope, f"{name}_damage", self.damage_colors[m])

    def _material_path(self, m: int, damage: bool) -> Sdf.Path:
        name = self.material_names[m] + ("_damage" if damage else "")
        return Sdf.Path(f"{ROOT}/Materials/{name}")

    @staticmethod
    def _preview_surface(scope: Sdf.PrimSpec, name: str, color: np.ndarray) -> None:
        material = _prim(scope, name, "Material")
        shader = _prim(material, "PreviewSurface", "Shader")
        _attr(shader, "info:id", _T.Token, "UsdPreviewSurface", uniform=True)
        _attr(shader, "inputs:diffuseColor", _T.Color3f, Gf.Vec3f(*map(float, color)))
        _attr(shader, "inputs:roughness", _T.Float, ROUGHNESS)
        _attr(shader, "inputs:metallic", _T.Float, 0.0)
        _attr(shader, "outputs:surface", _T.Token)
        out = _attr(material, "outputs:surface", _T.Token)
        out.connectionPathList.explicitItems = [shader.path.AppendProperty("outputs:surface")]

    # -- meshes
    def _prepare_meshes(self) -> None:
        """Shared points per piece (corners deduplicated), face data, damage timelines."""
        m = self.meshes
        t = len(m.vertices)
        tri_piece = np.repeat(np.arange(self.cache.piece_count), np.diff(m.offsets))
        corners = m.vertices.reshape(-1, 3).astype(np.float32)
        corner_piece = np.repeat(tri_piece, 3)
        order = np.lexsort((corners[:, 2], corners[:, 1], corners[:, 0], corner_piece))
        sc, sp = corners[order], corner_piece[order]
        new = np.ones(len(order), dtype=bool)
        new[1:] = (sp[1:] != sp[:-1]) | np.any(sc[1:] != sc[:-1], axis=1)
        unique_id = np.cumsum(new) - 1
        inverse = np.empty(len(order), dtype=np.int64)
        inverse[order] = unique_id
        self.points = sc[new]
        point_piece = sp[new]
        self.point_offsets = np.searchsorted(point_piece, np.arange(self.cache.piece_count + 1))
        self.indices = (inverse - self.point_offsets[corner_piece]).astype(np.int32)
        self.normals = np.repeat(m.normals.astype(np.float32), 3, axis=0)
        face_color = np.where(m.damage[:, None], self.damage_colors[m.material],
                              self.colors[m.material]) if t else np.zeros((0, 3))
        self.face_color = face_color.astype(np.float32)
        # damage: per voxel level after each piece's events
        self.dmg_piece, self.dmg_frame, self.dmg_voxel, self.dmg_value = \
            _face_damage_events(self.cache, m)
        self.dmg_offsets = np.searchsorted(self.dmg_piece, np.arange(self.cache.piece_count + 1))

    def _mesh(self, parent: Sdf.PrimSpec, name: str, p: int) -> Sdf.PrimSpec:
        m = self.meshes
        t0, t1 = int(m.offsets[p]), int(m.offsets[p + 1])
        v0, v1 = int(self.point_offsets[p]), int(self.point_offsets[p + 1])
        points = self.points[v0:v1]
        mesh = _prim(parent, name, "Mesh")
        _attr(mesh, "points", _T.Point3fArray, _vec3f(points))
        _attr(mesh, "faceVertexCounts", _T.IntArray,
              Vt.IntArray.FromNumpy(np.full(t1 - t0, 3, dtype=np.int32)))
        _attr(mesh, "faceVertexIndices", _T.IntArray,
              Vt.IntArray.FromNumpy(np.ascontiguousarray(self.indices[3 * t0:3 * t1])))
        _attr(mesh, "normals", _T.Normal3fArray, _vec3f(self.normals[3 * t0:3 * t1]),
              interpolation="faceVarying")
        _attr(mesh, "extent", _T.Float3Array, _extent(points))
        _attr(mesh, "subdivisionScheme", _T.Token, "none", uniform=True)
        _attr(mesh, "primvars:displayColor", _T.Color3fArray, _vec3f(self.face_color[t0:t1]),
              interpolation="uniform")
        self._damage_primvar(mesh, p, t0, t1)
        self._subsets(mesh, t0, t1)
        return mesh

    def _damage_primvar(self, mesh: Sdf.PrimSpec, p: int, t0: int, t1: int) -> None:
        faces = t1 - t0
        spec = _attr(mesh, "primvars:damage", _T.FloatArray,
                     Vt.FloatArray.FromNumpy(np.zeros(faces, dtype=np.float32)),
                     interpolation="uniform")
        e0, e1 = int(self.dmg_offsets[p]), int(self.dmg_offsets[p + 1])
        if e0 == e1 or faces == 0:
            return
        face_voxel = self.meshes.voxel[t0:t1]
        voxels, local = np.unique(face_voxel, return_inverse=True)
        level = np.zeros(len(voxels), dtype=np.float32)
        ev_frame = self.dmg_frame[e0:e1]
        ev_slot = np.searchsorted(voxels, self.dmg_voxel[e0:e1])
        ev_value = self.dmg_value[e0:e1]
        bounds = np.flatnonzero(np.diff(ev_frame)) + 1
        starts = np.concatenate([[0], bounds])
        ends = np.concatenate([bounds, [len(ev_frame)]])
        layer, path = self.layer, spec.path
        previous = level[local].copy()
        if int(ev_frame[0]) > 0:
            layer.SetTimeSample(path, 0.0, Vt.FloatArray.FromNumpy(previous))
        last_written = 0 if int(ev_frame[0]) > 0 else -1
        for s, e in zip(starts, ends, strict=True):
            f = int(ev_frame[s])
            level[ev_slot[s:e]] = ev_value[s:e]  # later events of a frame win
            current = level[local]
            if f - 1 > last_written:  # hold the old value up to the frame before the step
                layer.SetTimeSample(path, float(f - 1), Vt.FloatArray.FromNumpy(previous))
            layer.SetTimeSample(path, float(f), Vt.FloatArray.FromNumpy(current))
            previous, last_written = current, f

    def _subsets(self, mesh: Sdf.PrimSpec, t0: int, t1: int) -> None:
        if t1 == t0:
            return
        material = self.meshes.material[t0:t1]
        damage = self.meshes.damage[t0:t1]
        key = material * 2 + damage.astype(np.int64)
        groups = np.unique(key)
        main = int(np.bincount(material).argmax())
        _bind(mesh, self._material_path(main, False))
        _attr(mesh, "subsetFamily:materialBind:familyType", _T.Token, "partition", uniform=True)
        for k in groups:
            m, is_damage = int(k) // 2, bool(k % 2)
            name = ("damage_" if is_damage else "surface_") + self.material_names[m]
            subset = _prim(mesh, name, "GeomSubset")
            _attr(subset, "elementType", _T.Token, "face", uniform=True)
            _attr(subset, "familyName", _T.Token, "materialBind", uniform=True)
            _attr(subset, "indices", _T.IntArray,
                  Vt.IntArray.FromNumpy(np.flatnonzero(key == k).astype(np.int32)))
            _bind(subset, self._material_path(m, is_damage))

    # -- pieces: one Xform per piece
    def _animation_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        pos = _finite_hold(self.anim.position)
        ori = _sign_continuous(_finite_hold(self.anim.orientation))
        return pos, ori

    def _xforms(self, shot: Sdf.PrimSpec) -> None:
        self._prepare_meshes()
        scope = _prim(shot, "Pieces", "Xform")
        f_count, p_count = self.frames, self.cache.piece_count
        pos, ori = self._animation_arrays()
        pos_pf = np.ascontiguousarray(pos.transpose(1, 0, 2))            # (P, F, 3)
        ori_pf = np.ascontiguousarray(ori.transpose(1, 0, 2)[..., [1, 2, 3, 0]],
                                      dtype=np.float32)                  # (P, F, xyzw)
        vt_pos = Vt.Vec3dArray.FromNumpy(pos_pf.reshape(-1, 3))
        vt_ori = Vt.QuatfArray.FromNumpy(ori_pf.reshape(-1, 4))
        end = np.minimum(self.anim.end_frame.astype(np.int64), f_count)
        layer = self.layer
        for p in range(p_count):
            xf = _prim(scope, f"piece_{p:05d}", "Xform")
            tr = _attr(xf, "xformOp:translate", _T.Double3)
            ro = _attr(xf, "xformOp:orient", _T.Quatf)
            _xform_order(xf, ["xformOp:translate", "xformOp:orient"])
            live = max(int(end[p]), 1)  # frames after the piece is gone are not needed
            base = p * f_count
            for spec, values, vt in ((tr, pos_pf[p, :live], vt_pos),
                                     (ro, ori_pf[p, :live], vt_ori)):
                path = spec.path
                for f in np.flatnonzero(_run_ends(values)).tolist():
                    layer.SetTimeSample(path, float(f), vt[base + f])
            if end[p] < f_count:
                vis = _attr(xf, "visibility", _T.Token, uniform=False)
                if end[p] > 0:
                    layer.SetTimeSample(vis.path, 0.0, "inherited")
                layer.SetTimeSample(vis.path, float(end[p]), "invisible")
            self._mesh(xf, "geom", p)

    # -- pieces: one PointInstancer
    def _instancer(self, shot: Sdf.PrimSpec) -> None:
        self._prepare_meshes()
        p_count, f_count = self.cache.piece_count, self.frames
        inst = _prim(shot, "Pieces", "PointInstancer")
        protos = _prim(inst, "Prototypes", "Scope")
        paths = [self._mesh(protos, f"piece_{p:05d}", p).path for p in range(p_count)]
        _rel(inst, "prototypes", paths)
        _attr(inst, "protoIndices", _T.IntArray,
              Vt.IntArray.FromNumpy(np.arange(p_count, dtype=np.int32)))
        pos, ori = self._animation_arrays()
        end = np.minimum(self.anim.end_frame.astype(np.int64), f_count)
        # radius of each prototype about its origin (the pivot), for a conservative extent
        radius = np.zeros(p_count, dtype=np.float64)
        if len(self.points):
            piece_of_point = np.repeat(np.arange(p_count), np.diff(self.point_offsets))
            np.maximum.at(radius, piece_of_point, np.linalg.norm(self.points, axis=1))
        positions = _attr(inst, "positions", _T.Point3fArray)
        orientations = _attr(inst, "orientations", _T.QuathArray)
        extent = _attr(inst, "extent", _T.Float3Array)
        invisible = _attr(inst, "invisibleIds", _T.Int64Array)
        layer = self.layer
        ids = np.arange(p_count, dtype=np.int64)
        last_gone = None
        for f in range(f_count):
            layer.SetTimeSample(positions.path, float(f), _vec3f(pos[f]))
            quat = np.ascontiguousarray(ori[f][:, [1, 2, 3, 0]], dtype=np.float16)
            layer.SetTimeSample(orientations.path, float(f), Vt.QuathArray.FromNumpy(quat))
            shown = end > f
            if shown.any():
                lo = (pos[f][shown] - radius[shown, None]).min(axis=0)
                hi = (pos[f][shown] + radius[shown, None]).max(axis=0)
                box = np.stack([lo, hi])
            else:
                box = np.zeros((2, 3))
            layer.SetTimeSample(extent.path, float(f), _vec3f(box))
            gone = ids[~shown]
            if last_gone is None or len(gone) != len(last_gone):
                layer.SetTimeSample(invisible.path, float(f), Vt.Int64Array.FromNumpy(gone))
                last_gone = gone

    # -- dust
    def _dust(self, shot: Sdf.PrimSpec) -> None:
        c = self.cache
        if len(c.dust_voxel) == 0 or self.frames == 0:
            return
        scope = _prim(shot, "Particles", "Xform")
        points = _prim(scope, "dust", "Points")
        up = np.zeros(3)
        up["XYZ".index(c.model.meta.get("up_axis", "Y"))] = 1.0
        gravity = float(c.meta.get("settings", {}).get("gravity", 9.81))
        g = self.change @ (-gravity * up)
        x0 = c.dust_position.astype(np.float64) @ self.change.T
        v0 = c.dust_velocity.astype(np.float64) @ self.change.T
        t0 = c.dust_time.astype(np.float64)
        volume = c.model.voxel_volume[c.dust_voxel.astype(np.int64)]
        width = np.cbrt(np.maximum(volume, 0.0)).astype(np.float32)
        material = c.model.voxel_material[c.dust_voxel.astype(np.int64)].astype(np.int64)
        color = self.damage_colors[np.bincount(material).argmax()]
        ids_all = np.arange(len(t0), dtype=np.int64)
        _attr(points, "primvars:displayColor", _T.Color3fArray,
              Vt.Vec3fArray([Gf.Vec3f(*map(float, color))]), interpolation="constant")
        specs = {name: _attr(points, name, kind) for name, kind in
                 (("points", _T.Point3fArray), ("velocities", _T.Vector3fArray),
                  ("widths", _T.FloatArray),
                  ("ids", _T.Int64Array), ("extent", _T.Float3Array))}
        layer = self.layer
        eps = 1e-9
        previous_empty = False
        for f, t in enumerate(c.frame_time.astype(np.float64).tolist()):
            age = t - t0
            alive = (age >= -eps) & (age <= DUST_LIFE_S + eps)
            if not alive.any() and previous_empty:
                continue  # an empty frame after an empty frame adds nothing
            previous_empty = not alive.any()
            a = np.maximum(age[alive], 0.0)[:, None]
            x = x0[alive] + v0[alive] * a + 0.5 * g * a * a
            w = width[alive]
            box = (np.stack([(x - w[:, None] / 2).min(axis=0), (x + w[:, None] / 2).max(axis=0)])
                   if len(x) else np.zeros((2, 3)))
            layer.SetTimeSample(specs["points"].path, float(f), _vec3f(x))
            layer.SetTimeSample(specs["velocities"].path, float(f), _vec3f(v0[alive] + g * a))
            layer.SetTimeSample(specs["widths"].path, float(f), Vt.FloatArray.FromNumpy(w))
            layer.SetTimeSample(specs["ids"].path, float(f),
                                Vt.Int64Array.FromNumpy(np.ascontiguousarray(ids_all[alive])))
            layer.SetTimeSample(specs["extent"].path, float(f), _vec3f(box))

    # -- shock fronts
    def _shock(self, shot: Sdf.PrimSpec) -> None:
        c = self.cache
        radius_all = np.asarray(c.shock_radius, dtype=np.float64).reshape(self.frames, -1)
        if radius_all.shape[1] == 0 or self.frames == 0:
            return
        scope = _prim(shot, "Effects", "Xform")
        centres = c.charge_position.astype(np.float64) @ self.change.T
        layer = self.layer
        for k in range(radius_all.shape[1]):
            radius = np.nan_to_num(radius_all[:, k], nan=0.0, posinf=0.0, neginf=0.0)
            r_max = float(radius.max())
            opacity = np.clip(1.0 - radius / r_max, 0.0, 1.0) if r_max > 0 else \
                np.zeros_like(radius)
            sphere = _prim(scope, f"shock_{k}", "Sphere")
            _attr(sphere, "xformOp:translate", _T.Double3, Gf.Vec3d(*map(float, centres[k])))
            _xform_order(sphere, ["xformOp:translate"])
            _attr(sphere, "primvars:displayColor", _T.Color3fArray,
                  Vt.Vec3fArray([Gf.Vec3f(*SHOCK_COLOR)]), interpolation="constant")
            r_spec = _attr(sphere, "radius", _T.Double)
            e_spec = _attr(sphere, "extent", _T.Float3Array)
            o_spec = _attr(sphere, "primvars:displayOpacity", _T.FloatArray,
                           interpolation="constant")
            for f in np.flatnonzero(_run_ends(radius)).tolist():
                r = float(radius[f])
                layer.SetTimeSample(r_spec.path, float(f), r)
                layer.SetTimeSample(e_spec.path, float(f),
                                    _vec3f(np.array([[-r] * 3, [r] * 3])))
                layer.SetTimeSample(o_spec.path, float(f),
                                    Vt.FloatArray([float(opacity[f])]))
            vis = _attr(sphere, "visibility", _T.Token)
            live = np.flatnonzero(radius > 0)
            if len(live) == 0:
                vis.default = "invisible"
            elif live[0] == 0:
                vis.default = "inherited"
            else:
                layer.SetTimeSample(vis.path, 0.0, "invisible")
                layer.SetTimeSample(vis.path, float(live[0]), "inherited")


def build_layer(cache: SimCache, options: ExportOptions) -> Sdf.Layer:
    """The export as an anonymous in-memory layer (for tests and other writers)."""
    return _Writer(cache, options).build()


def write_usd(cache: SimCache, path: Path, options: ExportOptions) -> None:
    """Write ``cache`` to ``path`` (.usda, .usdc or .usd: crate), atomically."""
    path = Path(path)
    layer = build_layer(cache, options)
    with atomic_path(path) as tmp:
        # USD picks the file format from the suffix, so export beside the .partial file
        # under a name that ends in the real suffix, then move it onto the .partial.
        usd_tmp = tmp.with_name(tmp.name + path.suffix.lower())
        try:
            if not layer.Export(str(usd_tmp)):
                raise OSError(f"{path}: USD export failed")
            os.replace(usd_tmp, tmp)
        finally:
            with contextlib.suppress(FileNotFoundError):
                usd_tmp.unlink()
