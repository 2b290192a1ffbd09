"""glTF 2.0 export (.glb and .gltf): one node and one mesh per piece, TRS animation.

Layout (written straight from numpy: one JSON document and one binary buffer):

* the scene holds one root node ``blastvox`` whose children are one node per
  source object (named after it, ``extras.object``) holding that object's piece
  nodes ``piece_00000``... (node index = piece index; ``extras``: piece, object,
  mass_kg), the camera and, with ``ExportOptions.shock``, one node per charge,
  ``shock_00``...;
* with ``layout="skinned"`` the piece nodes carry no mesh: they are the joints of
  skins of up to 512 pieces (``gltf_meshes.SKIN_JOINTS``) of one object each (``skin_NNN``
  nodes under the object node hold their pieces), and one mesh per skin on a
  root node holds its pieces' triangles, a primitive per material, each vertex
  bound to its piece (JOINTS_0, WEIGHTS_0 = 1); importers make an armature and
  a mesh per skin instead of an object per piece;
* piece p's mesh has one primitive per (material, surface) and per (material,
  damage) present, indexed triangles with POSITION (min/max) and NORMAL (the
  source's smooth normals on its surface, flat face normals elsewhere:
  :mod:`blastvox.export.uv`; vertices shared only where position, normal and UV
  agree);
* materials ``<name>`` (``material_color``) and ``<name>_damage``
  (``material_damage_color``), pbrMetallicRoughness, metallic 0, roughness 0.8;
  ``shock_front`` (translucent, single-sided) for the shock spheres;
* one animation ``blastvox``: per piece LINEAR translation and rotation
  samplers at the frame times (rotation keys sign-continuous, (x, y, z, w));
  a piece that vanishes (``piece_end_frame < frame_count``) gets a STEP scale
  sampler that drops to 0 at its end frame; a shock sphere (a unit UV sphere at
  the charge) is scaled LINEARly to the shock radius (0 before detonation).

glTF is Y-up and in metres, so geometry and animation always come from
:func:`blastvox.export.pieces.piece_meshes` / :func:`~blastvox.export.pieces.animation`
with up "Y", whatever ``ExportOptions.up_axis`` says. Dust is not exported (glTF
cannot animate point positions per point without morph targets); destroyed
voxels are pieces of their own and vanish at their frame.

A .gltf is written with a sibling ``<stem>.bin`` (its buffer), both atomically;
a .glb holds everything. Output is byte-deterministic: the same cache gives
the same bytes (stable order, no timestamps, ``asset.generator`` = "blastvox
<version>").
"""

from __future__ import annotations

import json
import math
import struct
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np

from blastvox import __version__
from blastvox.cache import SimCache
from blastvox.errors import BlastvoxError
from blastvox.export.damage_textures import damage_textures
from blastvox.export.gltf_buffer import (
    ARRAY_BUFFER,
    ELEMENT_ARRAY_BUFFER,
    FLOAT,
    UINT16,
    _Builder,
    _f32,
    _floats,
)
from blastvox.export.gltf_keys import piece_channels
from blastvox.export.gltf_meshes import TRIANGLES, _piece_meshes, _skin_groups
from blastvox.export.options import ExportOptions
from blastvox.export.pieces import (
    animation,
    export_origin,
    object_groups,
    piece_meshes,
    piece_objects,
    piece_parts,
)
from blastvox.export.uv import texture_names
from blastvox.geometry import exact, fixed, quaternion
from blastvox.geometry.frames import frame_change, up_vector
from blastvox.io.atomic import atomic_path

#: glTF sampler constants (OpenGL enums): LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT
LINEAR_FILTER, LINEAR_MIPMAP_LINEAR, REPEAT = 9729, 9987, 10497
SAMPLER = {"magFilter": LINEAR_FILTER, "minFilter": LINEAR_MIPMAP_LINEAR,
           "wrapS": REPEAT, "wrapT": REPEAT}
ROUGHNESS = 0.8
#: the camera's film (mm): 36 mm wide at 16:9, as the USD export's filmback
#: (usd_effects.FILMBACK_MM). Blender's glTF importer keeps yfov with a vertical fit
#: and ignores aspectRatio, so at its default 16:9 render it frames what the USD
#: import (36 mm, horizontal fit) frames
FILM_MM = (36.0, 20.25)
SHOCK_COLOR = (1.0, 0.55, 0.15, 0.15)
SPHERE_SEGMENTS, SPHERE_RINGS = 32, 16
_GLB_MAGIC, _GLB_JSON, _GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


def write_gltf(cache: SimCache, path: str | Path, options: ExportOptions | None = None) -> None:
    """Write ``cache`` as glTF 2.0: binary .glb, or .gltf JSON plus a sibling ``<stem>.bin``.

    ``options`` (:class:`blastvox.export.options.ExportOptions`): its ``shock`` adds
    the shock spheres; glTF is always Y-up, so its ``up_axis`` is ignored.
    """
    path = Path(path)
    bin_name = path.stem + ".bin"
    options = options or ExportOptions()
    doc, blob = build_gltf(cache, buffer_uri=None if path.suffix.lower() == ".glb"
                           else quote(bin_name), shock=options.shock,
                           damage_textures=options.damage_textures,
                           skinned=options.layout == "skinned",
                           fracture_faces=options.fracture_faces,
                           particles=options.particles == "spheres",
                           key_tolerance_m=options.key_tolerance_m,
                           key_tolerance_deg=options.key_tolerance_deg)
    if path.suffix.lower() == ".glb":
        with atomic_path(path) as tmp:
            tmp.write_bytes(glb_bytes(doc, blob))
        return
    with ExitStack() as stack:  # both renamed only if both were written; .gltf last
        gltf_tmp = stack.enter_context(atomic_path(path))
        bin_tmp = stack.enter_context(atomic_path(path.with_name(bin_name)))
        bin_tmp.write_bytes(blob)
        gltf_tmp.write_bytes(_json_bytes(doc))


def glb_bytes(doc: dict[str, Any], blob: bytes) -> bytes:
    """A GLB container: 12-byte header, JSON chunk (space padded), BIN chunk (zero padded)."""
    js = _json_bytes(doc)
    js += b" " * (-len(js) % 4)
    blob = blob + b"\0" * (-len(blob) % 4)
    chunks = struct.pack("<II", len(js), _GLB_JSON) + js
    if blob:
        chunks += struct.pack("<II", len(blob), _GLB_BIN) + blob
    if 12 + len(chunks) > 0xFFFFFFFF:
        raise BlastvoxError(f"the shot is too large for a .glb ({(12 + len(chunks)) / 2**30:.1f} "
                            f"GiB; GLB holds at most 4 GiB): export to .gltf instead")
    return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def _json_bytes(doc: dict[str, Any]) -> bytes:
    return json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")


def build_gltf(cache: SimCache, buffer_uri: str | None = None, shock: bool = False,
               damage_textures: bool = True, skinned: bool = False,
               fracture_faces: str = "rough", particles: bool = False,
               key_tolerance_m: float = 0.0, key_tolerance_deg: float = 0.0
               ) -> tuple[dict[str, Any], bytes]:
    """The glTF document (JSON-ready dict) and its binary buffer for ``cache``.

    ``buffer_uri``: the buffer's uri (.gltf), or None for a GLB's embedded buffer.
    ``shock``: also one translucent sphere node per charge, scaled to its shock radius.
    ``damage_textures``: fracture faces show their material's damage texture.
    ``skinned``: skinned meshes of up to SKIN_JOINTS pieces each, a joint per piece
    (the piece nodes), instead of a mesh per piece: importers make a few objects,
    not thousands.
    ``fracture_faces``: "rough" (rubble surfaces) or "voxel" (cell faces).
    ``particles``: also a node per particle (:mod:`blastvox.export.gltf_particles`).
    ``key_tolerance_m``, ``key_tolerance_deg``: keyframe reduction of the pieces'
    animation (:mod:`blastvox.export.gltf_keys`; m and degrees); 0 and 0 key every frame.
    """
    b = _Builder()
    mats, mat_index = _materials(cache)
    look = _texture_materials(cache, b, mats)
    pm = piece_meshes(cache, "Y", fracture_faces)
    if damage_textures:
        _damage_texture_materials(cache, b, mats, mat_index, look,
                                  np.unique(pm.material[pm.damage]).tolist())
    objects = piece_objects(cache)
    parts = piece_parts(cache)
    skins = _skin_groups(objects) if skinned else []
    skin_of = np.zeros(cache.piece_count, dtype=np.int64)
    for k, joints in enumerate(skins):
        skin_of[joints] = k
    meshes, piece_mesh = _piece_meshes(cache, b, mat_index, look["material"], pm,
                                       skin_of if skinned else None)
    anim = animation(cache, "Y")
    origin = export_origin(anim)  # float32 far from the origin: relative to the root's
    n_pieces, n_frames = cache.piece_count, cache.frame_count

    nodes: list[dict[str, Any]] = []
    samplers: list[dict[str, Any]] = []
    channels: list[dict[str, Any]] = []

    def channel(node: int, path: str, input_acc: int, output: int,
                interpolation: str = "LINEAR") -> None:
        samplers.append({"input": input_acc, "interpolation": interpolation, "output": output})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})

    times = anim.times.astype(np.float32)
    position = (anim.position - origin).astype(np.float32)  # (F, P, 3)
    rotation = _gltf_quaternions(anim.orientation)  # (F, P, 4), (x, y, z, w), sign continuous
    end = np.asarray(anim.end_frame, dtype=np.int64)
    first_t = _floats(position[0]) if n_frames else []
    first_r = _floats(rotation[0]) if n_frames else []
    masses = np.asarray(cache.piece_mass, dtype=np.float64).tolist()
    for p in range(n_pieces):
        node: dict[str, Any] = {"name": f"piece_{p:05d}",
                                "extras": {"piece": p, "object": objects[p],
                                           "mass_kg": masses[p]}}
        if parts[p]:
            node["extras"]["part"] = parts[p]
        if piece_mesh[p] >= 0 and not skinned:
            node["mesh"] = int(piece_mesh[p])
        if n_frames:
            node["translation"] = first_t[p]
            node["rotation"] = first_r[p]
            if end[p] <= 0:
                node["scale"] = [0.0, 0.0, 0.0]
        nodes.append(node)

    if n_frames:
        made: list[int] = []

        def frame_input() -> int:
            """The accessor of every frame time, made once, where first used."""
            if not made:
                made.append(b.accessor(b.view(_f32(times)), 0, FLOAT, n_frames, "SCALAR",
                                       _floats([times.min()]), _floats([times.max()])))
            return made[0]
        if key_tolerance_m > 0 or key_tolerance_deg > 0:
            steps = _step_accessors(b, times, end)
            reduced = piece_channels(b, times, position, rotation, end, key_tolerance_m,
                                     key_tolerance_deg)
        else:  # every frame, the layout of the exports before keyframe reduction
            t_acc = frame_input()
            tr_view = b.view(_f32(position.transpose(1, 0, 2)))
            rot_view = b.view(_f32(rotation.transpose(1, 0, 2)))
            steps = _step_accessors(b, times, end)
            reduced = [((t_acc, b.accessor(tr_view, p * n_frames * 12, FLOAT, n_frames,
                                           "VEC3"), "LINEAR"),
                        (t_acc, b.accessor(rot_view, p * n_frames * 16, FLOAT, n_frames,
                                           "VEC4"), "LINEAR")) for p in range(n_pieces)]
        for p, (translation, rotation_keys) in enumerate(reduced):
            channel(p, "translation", *translation)
            channel(p, "rotation", *rotation_keys)
            if end[p] < n_frames:
                step_in, step_out = steps[int(end[p])]
                channel(p, "scale", step_in, step_out, "STEP")

    # shock fronts: one shared unit UV sphere, one node per charge, scaled to the radius
    n_charges = len(cache.charge_tnt_kg) if shock else 0
    if n_charges:
        mats.append({"name": "shock_front", "pbrMetallicRoughness": {
            "baseColorFactor": list(SHOCK_COLOR), "metallicFactor": 0.0,
            "roughnessFactor": 1.0}, "alphaMode": "BLEND"})
        meshes.append(_sphere_mesh(b, len(mats) - 1))
        change = frame_change(cache.model.meta.get("up_axis", "Y"), "Y")
        centres = exact.turn(change, np.asarray(cache.charge_position, dtype=np.float64)) - origin
        radius = np.asarray(cache.shock_radius, dtype=np.float32).reshape(n_frames, n_charges)
        scale = np.repeat(radius.T[:, :, None], 3, axis=2)  # (C, F, 3)
        sc_view = b.view(_f32(scale)) if n_frames else -1
        for c in range(n_charges):
            node = {"name": f"shock_{c:02d}", "mesh": len(meshes) - 1,
                    "translation": _floats(centres[c]),
                    "scale": _floats(scale[c, 0]) if n_frames else [0.0] * 3}
            nodes.append(node)
            if n_frames:
                channel(len(nodes) - 1, "scale", frame_input(),
                        b.accessor(sc_view, c * n_frames * 12, FLOAT, n_frames, "VEC3"))

    cameras = _camera(cache, b, nodes, channel, frame_input if n_frames else None, origin)
    if particles:
        from blastvox.export.gltf_particles import add_particles

        add_particles(cache, b, mats, meshes, nodes, channel,
                      frame_input() if n_frames else None,
                      _sphere_mesh, origin)

    others = list(range(n_pieces, len(nodes)))  # shock fronts, camera, particles
    groups = object_groups(objects)
    if skinned:  # a node per skin between each object and its pieces
        for name in groups:
            groups[name] = []
        for k, joints in enumerate(skins):
            groups[objects[joints[0]]].append(len(nodes))
            nodes.append({"name": f"skin_{k:03d}", "children": joints})
    object_nodes = []
    for name, pieces in groups.items():
        children = pieces if skinned else _part_nodes(nodes, name, pieces, parts)
        object_nodes.append(len(nodes))
        nodes.append({"name": name or "object", "children": children,
                      "extras": {"object": name}})
    root: dict[str, Any] = {"name": "blastvox", "children": object_nodes + others}
    if origin.any():  # a scene far from the origin: its children are relative to this
        root["translation"] = _floats(origin)
    nodes.append(root)
    roots = [len(nodes) - 1]
    if skinned:  # a skinned mesh's node ignores its transform: keep it a root
        for m, k in sorted({int(piece_mesh[j[0]]): k for k, j in enumerate(skins)
                            if piece_mesh[j[0]] >= 0}.items()):
            roots.append(len(nodes))
            nodes.append({"name": f"pieces_{k:03d}", "mesh": m, "skin": k})
    fps = cache.meta.get("fps")
    doc: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": f"blastvox {__version__}"},
        "scene": 0,
        "scenes": [{"name": "blastvox", "nodes": roots,
                    "extras": {"up_axis": "Y", "units": "m", "frame_count": n_frames,
                               "fps": fps if isinstance(fps, int | float) else None,
                               "piece_count": n_pieces}}],
        "nodes": nodes,
    }
    if cameras:
        doc["cameras"] = cameras
    if skinned and meshes:  # no inverseBindMatrices: identity, the vertices are piece-local
        doc["skins"] = [{"name": f"skin_{k:03d}", "joints": joints}
                        for k, joints in enumerate(skins)]
    if meshes:
        doc["meshes"] = meshes
    if mats:
        doc["materials"] = mats
    for key in ("images", "samplers", "textures"):
        if look[key]:
            doc[key] = look[key]
    if channels:
        doc["animations"] = [{"name": "blastvox", "channels": channels, "samplers": samplers}]
    blob = b.blob()
    if b.views:
        if b.accessors:
            doc["accessors"] = b.accessors
        doc["bufferViews"] = b.views
        buffer: dict[str, Any] = {"byteLength": len(blob)}
        if buffer_uri is not None:
            buffer["uri"] = buffer_uri
        doc["buffers"] = [buffer]
    return doc, blob


def _camera(cache: SimCache, b: _Builder, nodes: list, channel, t_acc,
            origin: np.ndarray) -> list[dict]:
    """The scene's camera (if any) as a perspective camera node whose translation is
    animated with the baked shake; glTF cameras look down -Z with +Y up. ``t_acc``: a
    callable giving the accessor of the frame times, or None (no frames); ``origin``
    (3,) m: the root node's translation, which the camera's is relative to."""
    camera = cache.meta.get("camera")
    if not camera:
        return []
    change = frame_change(cache.model.meta.get("up_axis", "Y"), "Y")
    position = exact.turn(change, np.asarray(camera["position"], dtype=np.float64)) - origin
    target = exact.turn(change, np.asarray(camera["look_at"], dtype=np.float64)) - origin
    offset = exact.turn(change, np.asarray(
        cache.arrays.get("camera_offset", np.zeros((cache.frame_count, 3))), dtype=np.float64))
    back = (position - target) / exact.length(position - target)
    right = np.cross(up_vector("Y"), back)
    if exact.length(right) < 1e-9:
        right = np.array([1.0, 0.0, 0.0])
    right /= exact.length(right)
    up = np.cross(back, right)
    rot = np.stack([right, up, back], axis=1)  # columns: camera axes in the world
    quat = quaternion.from_matrix(rot)[[1, 2, 3, 0]]  # glTF order (x, y, z, w)
    focal = float(camera.get("focal_length_mm", 35.0))
    nodes.append({"name": "camera", "camera": 0, "translation": _floats(position + offset[0]),
                  "rotation": _floats(quat)})
    if t_acc is not None and np.abs(offset).max() > 0:
        view = b.view(_f32((position + offset).astype(np.float32)))
        channel(len(nodes) - 1, "translation", t_acc(),
                b.accessor(view, 0, FLOAT, len(offset), "VEC3"))
    return [{"name": "camera", "type": "perspective", "perspective": {
        "yfov": 2.0 * math.atan(FILM_MM[1] / (2.0 * focal)),  # libm's, not numpy's
        "aspectRatio": FILM_MM[0] / FILM_MM[1],
        "znear": 0.1, "zfar": 10000.0}}]


def _gltf_quaternions(wxyz: np.ndarray) -> np.ndarray:
    """(F, P, 4) (w, x, y, z) -> float32 (x, y, z, w), each key flipped to the hemisphere
    of the previous one so LINEAR (nlerp/slerp) interpolation takes the short way."""
    q = quaternion.sign_continuous(quaternion.normalize(wxyz))
    return np.ascontiguousarray(q[..., [1, 2, 3, 0]], dtype=np.float32) + np.float32(0.0)  # no -0


def _step_accessors(b: _Builder, times: np.ndarray,
                    end: np.ndarray) -> dict[int, tuple[int, int]]:
    """STEP scale keys per distinct end frame e < F: (input, output) accessors.

    e > 0: keys at times[0] (scale 1) and times[e] (scale 0); e <= 0: one key (scale 0).
    Pieces with the same end frame share the accessors.
    """
    n_frames = len(times)
    ends = sorted({int(e) for e in end if e < n_frames})
    out: dict[int, tuple[int, int]] = {}
    if not ends:
        return out
    key_times = np.array([[times[0], times[max(e, 0)]] for e in ends], dtype=np.float32)
    key_view = b.view(_f32(key_times))
    values = b.view(_f32([1, 1, 1, 0, 0, 0]))  # scale 1 then 0
    outputs: dict[int, int] = {}  # key count -> output accessor (only those used)
    for i, e in enumerate(ends):
        n = 1 if e <= 0 else 2
        if n not in outputs:
            outputs[n] = b.accessor(values, 12 if n == 1 else 0, FLOAT, n, "VEC3")
        acc = b.accessor(key_view, i * 8, FLOAT, n, "SCALAR", _floats(key_times[i, :1]),
                         _floats(key_times[i, n - 1:n]))
        out[e] = (acc, outputs[n])
    return out


def _materials(cache: SimCache) -> tuple[list[dict[str, Any]], dict[tuple[int, bool], int]]:
    """glTF materials for the (model material, damage) pairs the pieces use, in order."""
    a = cache.model.arrays
    names = list(cache.model.meta.get("materials", []))
    used = np.unique(np.asarray(a["voxel_material"], dtype=np.int64))
    colors = np.asarray(a["material_color"], dtype=np.float64)
    damage_colors = np.asarray(a["material_damage_color"], dtype=np.float64)
    mats: list[dict[str, Any]] = []
    index: dict[tuple[int, bool], int] = {}
    for m in used.tolist():
        name = names[m] if m < len(names) else f"material_{m}"
        for damage, rgb, suffix in ((False, colors[m], ""), (True, damage_colors[m], "_damage")):
            rgba = [float(np.clip(x, 0.0, 1.0)) for x in rgb] + [1.0]
            index[(m, damage)] = len(mats)
            mats.append({"name": name + suffix, "pbrMetallicRoughness": {
                "baseColorFactor": rgba, "metallicFactor": 0.0, "roughnessFactor": ROUGHNESS}})
    return mats, index


def _texture_materials(cache: SimCache, b: _Builder, mats: list[dict[str, Any]]
                       ) -> dict[str, list]:
    """The source look's textures, embedded (one bufferView each, PNG), and one material
    per texture appended to ``mats``: {"images", "samplers", "textures", "material"}
    where "material"[k] is texture k's material index."""
    names = texture_names(cache)
    look: dict[str, list] = {"images": [], "samplers": [], "textures": [], "material": [],
                             "names": names}
    if not names:
        return look
    look["samplers"].append(SAMPLER)
    for k, name in enumerate(names):
        look["images"].append({"name": name, "mimeType": "image/png",
                               "bufferView": b.view(cache.model.texture_file(k))})
        look["textures"].append({"sampler": 0, "source": k})
        look["material"].append(len(mats))
        mats.append({"name": f"texture_{name}", "pbrMetallicRoughness": {
            "baseColorTexture": {"index": k}, "metallicFactor": 0.0,
            "roughnessFactor": ROUGHNESS}})
    return look


def _damage_texture_materials(cache: SimCache, b: _Builder, mats: list[dict[str, Any]],
                              mat_index: dict[tuple[int, bool], int], look: dict[str, list],
                              fractured: list[int]) -> None:
    """Each fractured material's damage texture, embedded like the look's textures and
    made the ``baseColorTexture`` of its ``<material>_damage`` material (whose colour
    factor becomes white: the texture carries the damage colour)."""
    for d in damage_textures(cache, fractured, look["names"]):
        if not look["samplers"]:
            look["samplers"].append(SAMPLER)
        look["images"].append({"name": d.name, "mimeType": "image/png",
                               "bufferView": b.view(d.png)})
        look["textures"].append({"sampler": 0, "source": len(look["images"]) - 1})
        pbr = mats[mat_index[(d.material, True)]]["pbrMetallicRoughness"]
        pbr["baseColorTexture"] = {"index": len(look["textures"]) - 1}
        pbr["baseColorFactor"] = [1.0, 1.0, 1.0, 1.0]


def _sphere_mesh(b: _Builder, material: int) -> dict[str, Any]:
    """A unit UV sphere (outward normals = positions), indexed triangles."""
    rings, segs = SPHERE_RINGS, SPHERE_SEGMENTS
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, segs + 1)
    st, ct = fixed.sin(theta)[:, None], fixed.cos(theta)[:, None]
    pos = np.stack([st * fixed.cos(phi), np.broadcast_to(ct, (rings + 1, segs + 1)),
                    -st * fixed.sin(phi)], axis=-1).reshape(-1, 3)
    pos = pos / exact.length(pos, keepdims=True)
    pos = pos.astype(np.float32)
    i, j = np.meshgrid(np.arange(rings), np.arange(segs), indexing="ij")
    a = i * (segs + 1) + j
    bb, c, d = a + segs + 1, a + 1, a + segs + 2
    tris = np.concatenate([np.stack([a, bb, c], -1)[1:].reshape(-1, 3),  # none at the pole
                           np.stack([c, bb, d], -1)[:-1].reshape(-1, 3)])
    idx = tris.astype("<u2").tobytes()
    pv = b.view(_f32(pos), ARRAY_BUFFER)
    nv = b.view(_f32(pos), ARRAY_BUFFER)
    iv = b.view(idx, ELEMENT_ARRAY_BUFFER)
    return {"name": "shock_sphere", "primitives": [{
        "attributes": {"POSITION": b.accessor(pv, 0, FLOAT, len(pos), "VEC3",
                                              _floats(pos.min(0)), _floats(pos.max(0))),
                       "NORMAL": b.accessor(nv, 0, FLOAT, len(pos), "VEC3")},
        "indices": b.accessor(iv, 0, UINT16, tris.size, "SCALAR"),
        "material": material, "mode": TRIANGLES}]}


# --- benchmark -------------------------------------------------------------------------------

def bench_cache(pieces: int = 1000, frames: int = 120, fps: float = 24.0,
                seed: int = 0) -> SimCache:
    """A synthetic SimCache for export benchmarks: a cube of 0.25 m voxels cut into
    ``pieces`` blocks of 2x2x2 voxels (pieces whose count is not a cube merge
    neighbouring blocks), each flying off ballistically and tumbling for
    ``frames`` frames; a tenth of them vanish part-way, one charge's shock grows.
    """
    import tempfile

    import trimesh

    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    voxel = 0.25
    k = max(1, int(np.ceil(round(math.cbrt(pieces), 9))))
    side = 2 * k * voxel
    with tempfile.TemporaryDirectory() as tmp:
        mesh = Path(tmp) / "block.stl"
        trimesh.creation.box(extents=(side,) * 3).export(mesh)
        model = voxelize([ObjectRequest(mesh=mesh, voxel_size=(voxel,) * 3, material="brick")],
                         VoxelizeSettings(up_axis="Z", ground=None))
    ijk = model.arrays["voxel_ijk"].astype(np.int64)
    block = (ijk[:, 0] // 2) * (k * k) + (ijk[:, 1] // 2) * k + ijk[:, 2] // 2
    piece = (block * pieces // (k * k * k)).astype(np.int32)
    mass = np.bincount(piece, weights=model.arrays["voxel_mass"], minlength=pieces)
    pivot = np.stack([np.bincount(piece, weights=model.arrays["voxel_mass"]
                                  * model.arrays["voxel_centroid"][:, i], minlength=pieces)
                      for i in range(3)], axis=1) / np.maximum(mass, 1e-12)[:, None]

    rng = np.random.default_rng(seed)
    t = np.arange(frames) / fps
    velocity = rng.normal(0.0, 5.0, (pieces, 3))
    gravity = np.array([0.0, 0.0, -9.81])
    position = (pivot[None] + t[:, None, None] * velocity[None]
                + 0.5 * t[:, None, None] ** 2 * gravity)
    axis = rng.normal(size=(pieces, 3))
    axis /= exact.length(axis, keepdims=True)
    half = 0.5 * rng.uniform(0.0, 20.0, pieces)[None] * t[:, None]  # (F, P) half angles
    orientation = np.concatenate([fixed.cos(half)[..., None],
                                  fixed.sin(half)[..., None] * axis[None]], axis=-1)
    end = np.full(pieces, frames, dtype=np.int32)
    gone = rng.random(pieces) < 0.1
    end[gone] = rng.integers(1, max(frames, 2), gone.sum())
    n = model.voxel_count
    i4, f8 = np.zeros(0, np.int32), np.zeros(0)
    arrays = {
        "frame_time": t, "voxel_piece": piece, "piece_pivot": pivot, "piece_mass": mass,
        "piece_position": position.astype(np.float32),
        "piece_orientation": orientation.astype(np.float32), "piece_end_frame": end,
        "voxel_destroyed_frame": np.full(n, -1, np.int32),
        "damage_frame": i4, "damage_voxel": i4, "damage_value": np.zeros(0, np.uint8),
        "link_break_link": i4, "link_break_time": f8, "dust_voxel": i4, "dust_time": f8,
        "dust_mass": f8, "dust_position": np.zeros((0, 3)), "dust_velocity": np.zeros((0, 3)),
        "charge_position": np.array([[0.0, -2.0 * side, 0.5 * side]]),
        "charge_tnt_kg": np.array([10.0]), "charge_time": np.array([0.0]),
        "shock_radius": (340.0 * t)[:, None],
    }
    return SimCache(arrays=arrays, model=model, meta={"fps": fps, "duration": float(t[-1])})


def bench_gltf(pieces: int = 1000, frames: int = 120, repeat: int = 3,
               cache: SimCache | None = None, suffix: str = ".glb") -> dict[str, Any]:
    """Time :func:`write_gltf` (best of ``repeat``) on ``cache`` or :func:`bench_cache`.

    Returns pieces, frames, triangles, seconds (best), bytes of the output.
    """
    import tempfile

    cache = cache if cache is not None else bench_cache(pieces, frames)
    best = float("inf")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / f"bench{suffix}"
        for _ in range(max(1, repeat)):
            started = time.perf_counter()
            write_gltf(cache, out)
            best = min(best, time.perf_counter() - started)
        size = out.stat().st_size + (out.with_suffix(".bin").stat().st_size
                                     if suffix == ".gltf" else 0)
    return {"format": suffix.lstrip("."), "pieces": cache.piece_count,
            "frames": cache.frame_count, "voxels": cache.model.voxel_count,
            "seconds": best, "bytes": size}


if __name__ == "__main__":  # python -m blastvox.export.gltf: the benchmark
    print(json.dumps(bench_gltf(), indent=1))


def _part_nodes(nodes: list[dict], name: str, pieces: list[int], parts: list[str]
                ) -> list[int]:
    """The children of object ``name``'s node: its pieces, with those of an input of
    several parts under a node per part (appended to ``nodes``; extras object, part)."""
    children: list[int] = []
    part_node: dict[str, int] = {}
    for p in pieces:
        if not parts[p]:
            children.append(p)
            continue
        if parts[p] not in part_node:
            part_node[parts[p]] = len(nodes)
            children.append(len(nodes))
            nodes.append({"name": parts[p], "children": [],
                          "extras": {"object": name, "part": parts[p]}})
        nodes[part_node[parts[p]]]["children"].append(p)
    return children
