"""The USD export's pieces and materials, written as Sdf specs (no usda text).

Functions of the writer ``w`` (:class:`blastvox.export.usd._Writer`: its ``layer``,
``cache``, prepared meshes and animation), called once each while the layer is
built; the stage layout is in :mod:`blastvox.export.usd`.

Speed: a call into the USD Python bindings costs microseconds, so the specs are
made with as few calls as the scene needs (one per spec, value and metadata
field), values go in from numpy (``Vt.*Array.FromNumpy``), and time samples in
bulk: a whole kind of sample (every piece's translations, say) is boxed by one
``Vt`` array and handed to ``SdfLayer.SetTimeSample`` through ``itertools.starmap``,
so no Python bytecode runs per sample.

Transform and velocity samples are quantised as the exports always were: a
translation to whole nanometres, a quaternion component to 1e-9, a velocity to
1e-6 m/s (or deg/s), and each value is the integer divided by its power of ten
(correctly rounded, as a parsed decimal ``123e-9`` would be), then rounded to the
attribute's precision. Samples are kept only at the ends of runs of equal values,
so USD's linear interpolation reproduces the cache at every frame.
"""

from __future__ import annotations

from collections import deque
from itertools import chain, repeat, starmap

import numpy as np
from pxr import Gf, Sdf, Vt

from blastvox.export.keys import reduce_keys
from blastvox.export.pieces import object_groups, velocities
from blastvox.export.usd_specs import ROOT, points_extent, run_ends_pf, vec3f

_T = Sdf.ValueTypeNames
_UNIFORM, _VARYING = Sdf.VariabilityUniform, Sdf.VariabilityVarying
#: translations are clamped to +-NANO_LIMIT m so that nanometres fit an int64
NANO_LIMIT = 9.0e9
ROUGHNESS = 0.8
_BINDING_API = Sdf.TokenListOp.Create(prependedItems=["MaterialBindingAPI"])


def _user_properties(prim: Sdf.PrimSpec, *properties: tuple) -> None:
    """Custom ``userProperties:<key>`` attributes (key, type, value) on ``prim``: what
    Blender imports as the object's custom properties, without the namespace."""
    for key, type_name, value in properties:
        Sdf.AttributeSpec(prim, f"userProperties:{key}", type_name, _VARYING,
                          True).default = value


def _prim(parent: Sdf.PrimSpec, name: str, type_name: str) -> Sdf.PrimSpec:
    return Sdf.PrimSpec(parent, name, Sdf.SpecifierDef, type_name)


def _attr(prim: Sdf.PrimSpec, name: str, type_name, value=None, uniform: bool = False,
          interpolation: str | None = None) -> Sdf.AttributeSpec:
    spec = Sdf.AttributeSpec(prim, name, type_name, _UNIFORM if uniform else _VARYING)
    if interpolation is not None:
        spec.SetInfo("interpolation", interpolation)
    if value is not None:
        spec.default = value
    return spec


def _rel(prim: Sdf.PrimSpec, name: str, targets: list) -> Sdf.RelationshipSpec:
    spec = Sdf.RelationshipSpec(prim, name, False)
    spec.targetPathList.explicitItems = targets
    return spec


def _connect(prim: Sdf.PrimSpec, name: str, type_name, source: str) -> None:
    _attr(prim, name, type_name).connectionPathList.explicitItems = [Sdf.Path(source)]


def set_samples(layer: Sdf.Layer, paths: list, counts: np.ndarray, frames: np.ndarray,
                values) -> None:
    """Time samples in bulk: ``counts[i]`` samples on ``paths[i]``, at ``frames`` (their
    concatenation, float time codes), taking ``values`` (an iterable of USD values, in
    the same order) one each."""
    rows = chain.from_iterable(map(repeat, paths, counts.tolist()))
    deque(starmap(layer.SetTimeSample, zip(rows, frames.astype(np.float64).tolist(),
                                           values, strict=True)), maxlen=0)


# ----------------------------------------------------------------------------- materials

def write_materials(w, shot: Sdf.PrimSpec) -> None:
    """/Shot/Materials: a UsdPreviewSurface per used material and its damage material
    (textured where it has a damage texture), and one per source-look texture."""
    scope = _prim(shot, "Materials", "Scope")
    for m in w.used_materials:
        _material(scope, w.material_path(m, False), w.colors[m])
        if m in w.damage_textures:
            _texture_material(scope, w.material_path(m, True), w.damage_textures[m].name,
                              w.texture_dir)
        else:
            _material(scope, w.material_path(m, True), w.damage_colors[m])
    for k in np.unique(w.look.texture[w.look.texture >= 0]).tolist():
        _texture_material(scope, w.texture_material_path(k), w.texture_names[k], w.texture_dir)


def _surface(material: Sdf.PrimSpec, path: str, color) -> None:
    """Material ``path``'s outputs:surface and its PreviewSurface shader: diffuse colour
    ``color`` (RGB) or, given a str, connected to that attribute."""
    _connect(material, "outputs:surface", _T.Token, f"{path}/PreviewSurface.outputs:surface")
    shader = _prim(material, "PreviewSurface", "Shader")
    _attr(shader, "info:id", _T.Token, "UsdPreviewSurface", uniform=True)
    if isinstance(color, str):
        _connect(shader, "inputs:diffuseColor", _T.Color3f, color)
    else:
        _attr(shader, "inputs:diffuseColor", _T.Color3f, Gf.Vec3f(*map(float, color)))
    _attr(shader, "inputs:metallic", _T.Float, 0.0)
    _attr(shader, "inputs:roughness", _T.Float, ROUGHNESS)
    _attr(shader, "outputs:surface", _T.Token)


def _material(scope: Sdf.PrimSpec, path: str, color: np.ndarray) -> None:
    _surface(_prim(scope, path.rsplit("/", 1)[1], "Material"), path, color)


def _texture_material(scope: Sdf.PrimSpec, path: str, texture: str, directory: str) -> None:
    """Material ``path``: a UsdPreviewSurface whose diffuse colour is a UsdUVTexture of
    ``./<directory>/<texture>.png`` beside the cache, read at the mesh's ``st``."""
    material = _prim(scope, path.rsplit("/", 1)[1], "Material")
    _surface(material, path, f"{path}/Texture.outputs:rgb")
    tex = _prim(material, "Texture", "Shader")
    _attr(tex, "info:id", _T.Token, "UsdUVTexture", uniform=True)
    _attr(tex, "inputs:file", _T.Asset, Sdf.AssetPath(f"./{directory}/{texture}.png"))
    _attr(tex, "inputs:sourceColorSpace", _T.Token, "sRGB")
    _connect(tex, "inputs:st", _T.Float2, f"{path}/UV.outputs:result")
    _attr(tex, "inputs:wrapS", _T.Token, "repeat")
    _attr(tex, "inputs:wrapT", _T.Token, "repeat")
    _attr(tex, "outputs:rgb", _T.Float3)
    uv = _prim(material, "UV", "Shader")
    _attr(uv, "info:id", _T.Token, "UsdPrimvarReader_float2", uniform=True)
    _attr(uv, "inputs:varname", _T.String, "st")
    _attr(uv, "outputs:result", _T.Float2)


# ----------------------------------------------------------------------------- meshes

def write_mesh(w, parent: Sdf.PrimSpec, name: str, p: int) -> None:
    """Piece p's static Mesh with its values: points shared within the piece, faceVarying
    normals and ``st``, per-face colour and damage (its samples come later:
    ``w.damage_paths[p]``), and its material: a ``material:binding`` of the Mesh where
    all its faces share one (material, surface or damage, or texture), else a GeomSubset
    per material, damage material and texture (a ``materialBind`` partition; the
    subsets' ``elementType`` is the schema's fallback, "face")."""
    t0, t1 = int(w.meshes.offsets[p]), int(w.meshes.offsets[p + 1])
    v0, v1 = int(w.point_offsets[p]), int(w.point_offsets[p + 1])
    g0, g1 = int(w.subset_piece_offsets[p]), int(w.subset_piece_offsets[p + 1])
    points = w.points[v0:v1]
    mesh = _prim(parent, name, "Mesh")
    if g1 - g0 == 1:
        mesh.SetInfo("apiSchemas", _BINDING_API)
    _attr(mesh, "extent", _T.Float3Array, points_extent(points))
    _attr(mesh, "faceVertexCounts", _T.IntArray, Vt.IntArray(t1 - t0, 3))
    _attr(mesh, "faceVertexIndices", _T.IntArray,
          Vt.IntArray.FromNumpy(w.indices[3 * t0:3 * t1]))
    _attr(mesh, "normals", _T.Normal3fArray, vec3f(w.normals[3 * t0:3 * t1]),
          interpolation="faceVarying")
    _attr(mesh, "points", _T.Point3fArray, vec3f(points))
    damage = _attr(mesh, "primvars:damage", _T.FloatArray, Vt.FloatArray(t1 - t0, 0.0),
                   interpolation="uniform")
    w.damage_paths[p] = damage.path
    _attr(mesh, "primvars:displayColor", _T.Color3fArray, vec3f(w.face_color[t0:t1]),
          interpolation="uniform")
    _attr(mesh, "primvars:st", _T.TexCoord2fArray, Vt.Vec2fArray.FromNumpy(
        np.ascontiguousarray(w.look.uv[t0:t1].reshape(-1, 2))), interpolation="faceVarying")
    _attr(mesh, "subdivisionScheme", _T.Token, "none", uniform=True)
    if g1 - g0 == 1:  # one material for every face: bound to the Mesh, no subsets
        _rel(mesh, "material:binding", [w.subset(int(w.subset_key[g0]))[1]])
        return
    if g1 == g0:
        return
    _attr(mesh, "subsetFamily:materialBind:familyType", _T.Token, "partition", uniform=True)
    for g in range(g0, g1):
        subset_name, target = w.subset(int(w.subset_key[g]))
        subset = _prim(mesh, subset_name, "GeomSubset")
        subset.SetInfo("apiSchemas", _BINDING_API)
        _attr(subset, "familyName", _T.Token, "materialBind", uniform=True)
        faces = w.subset_order[w.subset_start[g]:w.subset_start[g + 1]]
        _attr(subset, "indices", _T.IntArray, Vt.IntArray.FromNumpy(w.local_face[faces]))
        _rel(subset, "material:binding", [target])


# ----------------------------------------------------------------------------- xforms

def write_xforms(w, shot: Sdf.PrimSpec) -> None:
    """Layout "xforms": an Xform per scene object holding an Xform per piece (piece, mass
    and object as custom ``userProperties:``, which Blender imports as the object's
    custom properties; time-sampled velocity and angularVelocity primvars, translate,
    orient and, for a piece that vanishes, visibility and a scale
    to 0) whose child Mesh carries the piece's name (importers that merge an Xform
    with its only child, Blender's, keep it)."""
    f_count, p_count = w.frames, w.pieces
    live = np.arange(f_count)[None, :] < np.maximum(w.end, 1)[:, None]       # (P, F)
    kinds, start_n = _xform_samples(w, live)
    start = (start_n / 1e9).tolist()  # each piece's first translation, m (double3)
    paths: dict[str, list] = {name: [None] * p_count for name in kinds}
    mass = w.cache.piece_mass
    for pieces in object_groups(w.objects).values():
        group = _prim(shot, w.object_prims[pieces[0]], "Xform")
        _user_properties(group, ("object", _T.String, w.objects[pieces[0]]))
        part_groups: dict[str, Sdf.PrimSpec] = {}  # an input's nodes, where it had several
        for p in pieces:
            name = f"piece_{p:05d}"
            parent = group
            if w.part_prims[p]:
                if w.part_prims[p] not in part_groups:
                    part_groups[w.part_prims[p]] = _prim(group, w.part_prims[p], "Xform")
                    _user_properties(part_groups[w.part_prims[p]],
                                     ("object", _T.String, w.objects[p]),
                                     ("part", _T.String, w.parts[p]))
                parent = part_groups[w.part_prims[p]]
            xform = _prim(parent, name, "Xform")
            # custom properties, which Blender's importer reads (its own convention for
            # them: the namespace is dropped): piece, mass_kg, object (and part), the
            # names the glTF export's node extras give them
            properties = [("piece", _T.Int, p), ("mass_kg", _T.Double, float(mass[p])),
                          ("object", _T.String, w.objects[p])]
            if w.parts[p]:
                properties.append(("part", _T.String, w.parts[p]))
            _user_properties(xform, *properties)
            for key, type_name in (("primvars:blastvox:velocity", _T.Vector3f),
                                   ("primvars:blastvox:angularVelocity", _T.Vector3f)):
                if key in paths:
                    paths[key][p] = _attr(xform, key, type_name).path
            end = int(w.end[p])
            if end < f_count:
                _vanish(w.layer, _attr(xform, "visibility", _T.Token).path, end)
            _attr(xform, "xformOp:translate:start", _T.Double3, Gf.Vec3d(*start[p]))
            for key, type_name in (("xformOp:orient", _T.Quatf),
                                   ("xformOp:translate", _T.Float3)):
                paths[key][p] = _attr(xform, key, type_name).path
            ops = ["xformOp:translate:start", "xformOp:translate", "xformOp:orient"]
            if end < f_count:
                # Blender's USD importer ignores visibility: shrink to nothing as well,
                # held at 1 up to the frame before (samples interpolate linearly)
                _shrink(w.layer, _attr(xform, "xformOp:scale", _T.Float3).path, end)
                ops.append("xformOp:scale")
            _attr(xform, "xformOpOrder", _T.TokenArray, Vt.TokenArray(ops), uniform=True)
            write_mesh(w, xform, name, p)
    for key, (keep, values) in kinds.items():
        set_samples(w.layer, paths[key], keep.sum(axis=1), np.nonzero(keep)[1], values)


def _xform_samples(w, live: np.ndarray) -> tuple[dict[str, tuple[np.ndarray, object]],
                                                  np.ndarray]:
    """Per sampled Xform attribute: (which frames each piece keeps (P, F), its kept values
    in piece-major order as a Vt array), and each piece's translation at frame 0 in whole
    nanometres (P, 3): the constant double3 ``xformOp:translate:start``, from which the
    float3 ``xformOp:translate`` samples are offsets (float32 of an offset d is within
    d 2^-24 of it: 0.06 mm after 1 km of travel). With key tolerances (``w.options``) the frames
    are chosen by :func:`blastvox.export.keys.reduce_keys` (USD interpolates linearly in
    the time code, the frame index, and quaternions by slerp); the velocities with the
    tolerances times the frame rate (an error of v_tol over a frame moves tol)."""
    pos, ori = w.animation_arrays()
    pos_n = np.rint(np.clip(pos, -NANO_LIMIT, NANO_LIMIT) * 1e9).astype(np.int64)
    ori_n = np.rint(ori.astype(np.float32) * 1e9).astype(np.int64)
    tol_m, tol_deg = float(w.options.key_tolerance_m), float(w.options.key_tolerance_deg)
    reduce = tol_m > 0 or tol_deg > 0
    times = np.arange(w.frames, dtype=np.float64)
    count = live.sum(axis=1)
    fps = w.fps

    def keys(values: np.ndarray, exact: np.ndarray, tolerance: float,
             rotation: bool = False) -> np.ndarray:
        if not reduce:
            return run_ends_pf(exact, live)
        return reduce_keys(times, None if rotation else values, values if rotation else None,
                           count, tolerance, tolerance)

    out = {}
    wanted: tuple = ()
    if w.options.velocity_primvars:
        linear, angular = velocities(w.anim)
        wanted = (("primvars:blastvox:velocity", linear, 1e6, tol_m * fps),
                  ("primvars:blastvox:angularVelocity", np.degrees(angular), 1e6,
                   tol_deg * fps))
    for key, v, scale, tol in wanted:
        n = np.rint(np.clip(np.nan_to_num(v), -NANO_LIMIT, NANO_LIMIT) * scale).astype(np.int64)
        n = n.transpose(1, 0, 2)
        keep = keys(n / scale, n, tol)
        out[key] = keep, vec3f(n[keep] / scale)
    o = ori_n.transpose(1, 0, 2)
    quat = (o / 1e9).astype(np.float32)
    keep = keys(quat.astype(np.float64), o, tol_deg, rotation=True)
    out["xformOp:orient"] = keep, Vt.QuatfArray.FromNumpy(
        np.ascontiguousarray(quat[keep][:, [1, 2, 3, 0]]))    # Gf: (i, j, k, real)
    t = pos_n.transpose(1, 0, 2)
    keep = keys(t / 1e9, t, tol_m)
    start = t[:, 0] if w.frames else np.zeros((w.pieces, 3), dtype=np.int64)
    offset = (t - start[:, None, :])[keep]  # exact in nanometres, then float32
    out["xformOp:translate"] = keep, vec3f(offset / 1e9)
    return out, start


def _vanish(layer: Sdf.Layer, path: Sdf.Path, end: int) -> None:
    """visibility: inherited from frame 0 (if shown at all), invisible from ``end``."""
    if end > 0:
        layer.SetTimeSample(path, 0.0, "inherited")
    layer.SetTimeSample(path, float(end), "invisible")


def _shrink(layer: Sdf.Layer, path: Sdf.Path, end: int) -> None:
    """xformOp:scale: 1 at frames 0 and end - 1 (those shown), 0 from ``end``."""
    one = Gf.Vec3f(1.0, 1.0, 1.0)
    for f in sorted({0, end - 1}):
        if 0 <= f < end:
            layer.SetTimeSample(path, float(f), one)
    layer.SetTimeSample(path, float(end), Gf.Vec3f(0.0, 0.0, 0.0))


# ----------------------------------------------------------------------------- instancer

def write_instancer(w, shot: Sdf.PrimSpec) -> Sdf.PrimSpec:
    """Layout "instancer": /Shot/Pieces, a PointInstancer whose prototypes are the piece
    meshes (Prototypes/piece_NNNNN); its per-frame arrays come from
    :func:`instancer_samples`."""
    inst = _prim(shot, "Pieces", "PointInstancer")
    for name, type_name in (("extent", _T.Float3Array), ("invisibleIds", _T.Int64Array),
                            ("ids", _T.Int64Array), ("velocities", _T.Vector3fArray),
                            ("angularVelocities", _T.Vector3fArray)):
        _attr(inst, name, type_name)
    _attr(inst, "primvars:blastvox:mass", _T.DoubleArray, interpolation="vertex")
    _attr(inst, "primvars:blastvox:object", _T.StringArray, interpolation="vertex")
    for name, type_name in (("orientations", _T.QuathArray), ("orientationsf", _T.QuatfArray),
                            ("positions", _T.Point3fArray), ("protoIndices", _T.IntArray)):
        _attr(inst, name, type_name)
    prototypes = _prim(inst, "Prototypes", "Scope")
    if w.pieces:
        _rel(inst, "prototypes", [Sdf.Path(f"{ROOT}/Pieces/Prototypes/piece_{p:05d}")
                                  for p in range(w.pieces)])
    for p in range(w.pieces):
        write_mesh(w, prototypes, f"piece_{p:05d}", p)
    return inst
