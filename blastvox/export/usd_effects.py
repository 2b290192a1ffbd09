"""The USD export's effects: particle systems, the scene camera and the shock fronts.

Functions of the writer ``w`` (:class:`blastvox.export.usd._Writer`: its ``layer``,
``cache``, ``change`` of frame, ``frames`` and ``options``), called once each while
the layer is built; see the stage layout in :mod:`blastvox.export.usd`.
"""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, Vt

from blastvox.export.usd_specs import (
    ROOT,
    attr_spec,
    model_gravity,
    origin_translate,
    points_extent,
    prim_spec,
    run_ends,
    vec3f,
    xform_order,
)
from blastvox.geometry import exact, fixed
from blastvox.geometry.frames import up_vector

_T = Sdf.ValueTypeNames
SHOCK_COLOR = (0.9, 0.9, 0.95)
PARTICLE_COLORS = {"dust": (0.55, 0.50, 0.45), "fire": (0.35, 0.27, 0.2),
                   "smoke": (0.25, 0.25, 0.25), "fireball": (0.4, 0.3, 0.22)}
#: UsdPreviewSurface inputs of each particle system's material: matte and translucent,
#: the smoke of fire and of the fireball included (their flame is the glow below).
#: ``opacity`` is each of the sprite's shells' (SPRITE_SHELLS): a ray through a lone
#: particle's centre keeps (1 - opacity)^6 of what is behind it, one near its rim
#: (1 - opacity)^2.
PARTICLE_LOOKS = {"dust": {"opacity": 0.13, "emissive": 0.0},
                  "fire": {"opacity": 0.08, "emissive": 0.0},
                  "smoke": {"opacity": 0.11, "emissive": 0.0},
                  "fireball": {"opacity": 0.1, "emissive": 0.0}}
#: spheres: one particle in this many of a system is drawn (a fixed subset, every n-th
#: in the cache's order), the rest left to the glow. The fireball's 200 particles, born
#: together, overlap so much that a ray crossed more than Cycles' 8 transparent
#: surfaces (3 shells, 2 surfaces each, a sphere) and stopped, drawing black.
SPHERE_EVERY = {"fireball": 4}
#: the sprite: concentric icosphere shells, their radii (m) in a sprite of diameter 1.
#: Translucent shells draw a soft ball (denser towards its centre, fading to its rim),
#: not a hard disc; three keep a centre ray under Blender's 8 transparent bounces.
SPRITE_SHELLS = (0.5, 0.36, 0.22)
#: UsdGeomCamera measures lens and filmback in tenths of a scene unit; the stage is in
#: metres (metersPerUnit 1), so 1 mm is 1 / MM_PER_TENTH_METRE of that unit.
MM_PER_TENTH_METRE = 100.0
#: the filmback: 36 mm wide at 16:9, the frame of ``blastvox preview`` and of Blender's
#: default render (1920 x 1080). Blender's USD importer fits the width (sensor_fit
#: HORIZONTAL); the glTF export's yfov is the same frame's (gltf.FILM_MM).
FILMBACK_MM = (36.0, 20.25)


# ----------------------------------------------------------------------------- particles

def write_particles(w, shot: Sdf.PrimSpec) -> None:
    """One UsdGeomPointInstancer per particle system (dust, fire, smoke, fireball)
    whose prototype, a soft ball of diameter 1 bound to the system's material, is
    instanced at each particle and scaled to its width (for fire and the fireball, their
    smoke's share of it, 1 - (T / hot_k)^2: :func:`_cooled`, in the alive-only layout).
    Positions come from the cache's particle births evaluated in closed form
    (blastvox.particles), one time sample per frame, in the cheaper of two layouts
    (see :func:`_layout_of`):

    * **fixed**: every particle of the system at every frame (a constant count,
      ids and scales written once), an unborn or dead one at its birth or death
      position and pointed at the second prototype, ``hidden``, an empty Xform.
      Positions alone carry the motion: with a constant count a renderer blurs by
      interpolating them, so no velocities are written;
    * **alive only**: the live particles of each frame with their ids, scales and
      velocities (the count changes, so motion blur needs the velocities); a
      frame without particles holds one instance of scale 0.

    Either way the instancer is invisible at a frame without live particles. With
    ``w.particle_mode`` "volumes" each system is a Volume of per-frame OpenVDB files
    instead (:mod:`blastvox.export.usd_volumes`). Either way fire and the fireball
    also get ``<system>_glow`` (:func:`blastvox.export.usd_glow.write_glow`): Blender
    imports no material of a Volume, and it is the glow of a plain import. An instancer,
    not UsdGeomPoints: Blender 5.0 imports Points without their material (white balls), and an empty
    points array crashed its Cycles. Re-checked in bpy 5.0.1 (2026-11-30): a Points
    prim with widths and a bound UsdPreviewSurface imports as a POINTCLOUD object
    with no material slot, and rendering its frame with an empty points sample
    killed the process (SIGSEGV, exit 139)."""
    from blastvox.export.usd_glow import GLOW_LOOKS, write_glow
    from blastvox.particles import SYSTEM_NAMES, SYSTEMS, all_positions_at, ground_plane

    c = w.cache
    system = c.arrays.get("particle_system")
    if system is None or len(system) == 0 or w.frames == 0:
        return
    scope = prim_spec(shot, "Particles", "Xform")
    origin_translate(scope, w.origin)  # the particles' float32 points are relative to it
    g = exact.turn(w.change, model_gravity(c))
    x0 = exact.turn(w.change, c.particle_position.astype(np.float64))
    v0 = exact.turn(w.change, c.particle_velocity.astype(np.float64))
    birth = c.particle_birth.astype(np.float64)
    size = c.particle_size.astype(np.float32)
    times = c.frame_time.astype(np.float64).tolist()
    ground = ground_plane(c.meta.get("ground_height"),
                          up_vector(c.model.meta.get("up_axis", "Y")), w.change)
    for index, name in enumerate(SYSTEM_NAMES):
        mine = np.flatnonzero(system == index)
        if not mine.size:
            continue
        states = [(alive, x - w.origin) for alive, x in (
            all_positions_at(birth[mine], x0[mine], v0[mine],
                             np.full(len(mine), index, dtype=np.uint8), t, g, ground)
            for t in times)]
        if name in GLOW_LOOKS:
            write_glow(w, scope, name, mine, states, SYSTEMS[name], birth, v0, size, g)
        if w.particle_mode == "volumes":
            from blastvox.export.usd_volumes import write_volume

            write_volume(w, scope, name, states, size[mine].astype(np.float64), birth[mine],
                         SYSTEMS[name].lifetime,
                         lambda prim, n: _bind(prim, _particle_material(w, n)))
            continue
        # fire and the fireball as spheres are their smoke, growing as they cool (from
        # nothing at birth, when the glow is the whole flame): the alive-only layout
        smoke = _cooled(name, SYSTEMS[name]) if name in GLOW_LOOKS else None
        every = SPHERE_EVERY.get(name, 1)
        mine, states = mine[::every], [(alive[::every], x[::every]) for alive, x in states]
        fixed = smoke is None and _layout_of(
            len(mine), [int(alive.sum()) for alive, _ in states]) == "fixed"
        instancer = _particle_instancer(w, scope, name, hidden=fixed)
        if fixed:
            _fixed_samples(w, instancer, mine, states, size)
            continue
        _instance_samples(w, instancer, mine, _live_frames(times, states), SYSTEMS[name],
                          birth, v0, size, g, smoke)


def _heat(name: str, spec):
    """``age (s) -> (T / hot_k)^2`` of a fire or fireball particle whose temperature
    falls linearly over its life from the volumes' hot_k to cool_k (VOLUME_LOOKS)."""
    from blastvox.export.volumes import VOLUME_LOOKS

    look = VOLUME_LOOKS[name]

    def heat(age: np.ndarray) -> np.ndarray:
        fraction = np.clip(np.asarray(age, dtype=np.float64) / spec.lifetime, 0.0, 1.0)
        return ((look.hot_k + (look.cool_k - look.hot_k) * fraction) / look.hot_k) ** 2
    return heat


def _cooled(name: str, spec):
    """``age (s) -> 1 - (T / hot_k)^2``: the share of a fire or fireball particle's
    size that its smoke sphere takes (the glow, :mod:`blastvox.export.usd_glow`, the rest)."""
    heat = _heat(name, spec)
    return lambda age: 1.0 - heat(age)


def _velocity(spec, v0: np.ndarray, age: np.ndarray, g: np.ndarray) -> np.ndarray:
    """(n, 3) m/s: particles born at v0 (n, 3) m/s, ``age`` (n,) s old, slowed by their
    system's drag (spec.drag, 1/s) and pulled by spec.gravity_scale times g (3,) m/s^2:
    the derivative of blastvox.particles' closed form."""
    decay = fixed.exp(-spec.drag * age)[:, None]
    return v0 * decay + spec.gravity_scale * g * (1 - decay) / spec.drag


def _live_frames(times: list, states: list) -> list:
    """(time s, alive indices, (n, 3) positions m) of each frame's live particles."""
    return [(t, np.flatnonzero(alive), x[alive])
            for t, (alive, x) in zip(times, states, strict=True)]


def _layout_of(count: int, alive: list[int]) -> str:
    """"fixed" when ``count`` particles at every frame from the first with a live one to
    the last (12 bytes of position each) cost no more than the live ones of each frame
    (``alive``) with their velocities (24 bytes each), else "alive only"."""
    live = np.flatnonzero(np.asarray(alive) > 0)
    if not live.size:
        return "alive only"
    span = int(live[-1] - live[0] + 1)
    return "fixed" if count * span <= 2 * sum(alive) else "alive only"


def _fixed_samples(w, instancer: Sdf.PrimSpec, mine: np.ndarray, states: list,
                   size: np.ndarray) -> None:
    """The fixed layout's samples (see :func:`write_particles`): ``states[f]`` is
    (alive (P,) bool, positions (P, 3) m) of the system's P particles ``mine`` at frame
    f; ``size`` (all particles,) m their widths."""
    layer = w.layer
    attr_spec(instancer, "ids", _T.Int64Array,
              Vt.Int64Array.FromNumpy(np.ascontiguousarray(mine.astype(np.int64))))
    attr_spec(instancer, "scales", _T.Float3Array,
              vec3f(np.repeat(size[mine][:, None], 3, axis=1)))
    specs = {key: attr_spec(instancer, key, kind) for key, kind in
             (("positions", _T.Point3fArray), ("protoIndices", _T.IntArray),
              ("extent", _T.Float3Array))}
    width = size[mine][:, None]
    for f, empty in _sampled_frames(w, instancer, [not alive.any() for alive, _ in states]):
        alive, x = states[f]
        shown = x[alive] if not empty else x
        half = width[alive] / 2 if not empty else width / 2
        box = np.stack([(shown - half).min(axis=0), (shown + half).max(axis=0)])
        layer.SetTimeSample(specs["positions"].path, float(f), vec3f(x))
        layer.SetTimeSample(specs["protoIndices"].path, float(f), Vt.IntArray.FromNumpy(
            np.ascontiguousarray(np.where(alive, 0, 1).astype(np.int32))))
        layer.SetTimeSample(specs["extent"].path, float(f), vec3f(box))


def _sampled_frames(w, instancer: Sdf.PrimSpec, empty: list[bool]):
    """Yield (frame, empty) for the frames an instancer is sampled at (``empty`` (F,):
    no live particle there): every frame but an empty one after an empty one, which
    would repeat it. Writes the instancer's visibility, "invisible" while empty."""
    visibility = attr_spec(instancer, "visibility", _T.Token)
    previous = None
    for f, now in enumerate(empty):
        if now and previous:
            continue
        if now != previous:
            w.layer.SetTimeSample(visibility.path, float(f),
                                  "invisible" if now else "inherited")
        previous = now
        yield f, now


def _particle_instancer(w, scope: Sdf.PrimSpec, name: str, hidden: bool) -> Sdf.PrimSpec:
    """Particles/<name> (PointInstancer) with Prototypes/sprite, a soft ball of
    diameter 1 (SPRITE_SHELLS: concentric icospheres of 80 faces, smooth normals) bound
    to Materials/particle_<name>, and if ``hidden`` Prototypes/hidden, an empty Xform
    (prototype 1: nothing drawn)."""
    import trimesh

    instancer = prim_spec(scope, name, "PointInstancer")
    prototypes = prim_spec(instancer, "Prototypes", "Scope")
    sprite = prim_spec(prototypes, "sprite", "Mesh")
    ball = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    unit = np.asarray(ball.vertices, dtype=np.float32)
    vertices = np.concatenate([unit * r for r in SPRITE_SHELLS]).astype(np.float32)
    faces = np.concatenate([ball.faces + k * len(unit) for k in range(len(SPRITE_SHELLS))])
    sphere_mesh(sprite, vertices, np.tile(unit, (len(SPRITE_SHELLS), 1)), faces,
                PARTICLE_COLORS[name])
    _bind(sprite, _particle_material(w, name))
    targets = Sdf.RelationshipSpec(instancer, "prototypes")
    targets.targetPathList.explicitItems = [sprite.path] + (
        [prim_spec(prototypes, "hidden", "Xform").path] if hidden else [])
    return instancer


def sphere_mesh(mesh: Sdf.PrimSpec, vertices: np.ndarray, normals: np.ndarray,
                faces: np.ndarray, color) -> None:
    """A particle sprite's Mesh attributes: ``vertices`` (V, 3) m, ``normals`` (V, 3)
    smooth per vertex, triangles ``faces`` (F, 3), no subdivision, displayColor
    ``color`` (linear RGB)."""
    attr_spec(mesh, "points", _T.Point3fArray, vec3f(vertices))
    attr_spec(mesh, "normals", _T.Normal3fArray, vec3f(normals), interpolation="vertex")
    attr_spec(mesh, "extent", _T.Float3Array, points_extent(vertices))
    attr_spec(mesh, "faceVertexCounts", _T.IntArray, Vt.IntArray(len(faces), 3))
    attr_spec(mesh, "faceVertexIndices", _T.IntArray, Vt.IntArray.FromNumpy(
        np.ascontiguousarray(faces.ravel(), dtype=np.int32)))
    attr_spec(mesh, "subdivisionScheme", _T.Token, "none", uniform=True)
    attr_spec(mesh, "primvars:displayColor", _T.Color3fArray,
              Vt.Vec3fArray([Gf.Vec3f(*color)]), interpolation="constant")


def _instance_samples(w, instancer: Sdf.PrimSpec, mine: np.ndarray, frames: list,
                      spec, birth: np.ndarray, v0: np.ndarray, size: np.ndarray,
                      g: np.ndarray, grow=None) -> None:
    """Time samples of one system's instancer: ``frames[f]`` is (time s, alive
    indices into ``mine``, (n, 3) positions m) at frame f; each instance's scale is its
    particle's size, times ``grow(age s)`` if given. Runs of empty frames keep
    one sample; an empty frame holds one instance of scale 0 where the first
    particle shows."""
    layer = w.layer
    specs = {key: attr_spec(instancer, key, kind) for key, kind in
             (("positions", _T.Point3fArray), ("scales", _T.Float3Array),
              ("velocities", _T.Vector3fArray), ("ids", _T.Int64Array),
              ("protoIndices", _T.IntArray), ("extent", _T.Float3Array))}
    first = next((x[:1] for _, alive, x in frames if alive.size), np.zeros((1, 3)))
    for f, empty in _sampled_frames(w, instancer, [not alive.size for _, alive, _ in frames]):
        t, alive, x = frames[f]
        if empty:
            x, vel, w = first, np.zeros((1, 3)), np.zeros(1, dtype=np.float32)
            ids = np.array([-1], dtype=np.int64)
        else:
            age = t - birth[mine][alive]
            vel = _velocity(spec, v0[mine][alive], age, g)
            w = size[mine][alive] * (1.0 if grow is None else grow(age))
            ids = mine[alive].astype(np.int64)
        box = np.stack([(x - w[:, None] / 2).min(axis=0), (x + w[:, None] / 2).max(axis=0)])
        sample = float(f)
        layer.SetTimeSample(specs["positions"].path, sample, vec3f(x))
        layer.SetTimeSample(specs["scales"].path, sample, vec3f(np.repeat(
            w[:, None], 3, axis=1)))
        layer.SetTimeSample(specs["velocities"].path, sample, vec3f(vel))
        layer.SetTimeSample(specs["ids"].path, sample,
                            Vt.Int64Array.FromNumpy(np.ascontiguousarray(ids)))
        layer.SetTimeSample(specs["protoIndices"].path, sample,
                            Vt.IntArray(len(ids), 0))
        layer.SetTimeSample(specs["extent"].path, sample, vec3f(box))

def _particle_material(w, name: str) -> Sdf.Path:
    """/Shot/Materials/particle_<name>: a UsdPreviewSurface that reads as the system
    (PARTICLE_COLORS, PARTICLE_LOOKS)."""
    color = Gf.Vec3f(*PARTICLE_COLORS[name])
    look = PARTICLE_LOOKS[name]
    materials = w.layer.GetPrimAtPath(f"{ROOT}/Materials")
    material = prim_spec(materials, f"particle_{name}", "Material")
    shader = prim_spec(material, "PreviewSurface", "Shader")
    attr_spec(shader, "info:id", _T.Token, "UsdPreviewSurface", uniform=True)
    emissive = look["emissive"]
    attr_spec(shader, "inputs:diffuseColor", _T.Color3f,
          Gf.Vec3f(0.0) if emissive else color)
    attr_spec(shader, "inputs:emissiveColor", _T.Color3f, color * emissive)
    attr_spec(shader, "inputs:opacity", _T.Float, look["opacity"])
    attr_spec(shader, "inputs:roughness", _T.Float, 1.0)
    out = attr_spec(shader, "outputs:surface", _T.Token)
    surface = attr_spec(material, "outputs:surface", _T.Token)
    surface.connectionPathList.explicitItems = [out.path]
    return material.path


def _bind(prim: Sdf.PrimSpec, material: Sdf.Path) -> None:
    prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["MaterialBindingAPI"]))
    binding = Sdf.RelationshipSpec(prim, "material:binding")
    binding.targetPathList.explicitItems = [material]

# ----------------------------------------------------------------------------- camera

def write_camera(w, shot: Sdf.PrimSpec) -> None:
    """The scene's camera with the blast's shake baked into its translation."""
    camera = w.cache.meta.get("camera")
    if not camera:
        return
    position = exact.turn(w.change, np.asarray(camera["position"], dtype=np.float64))
    target = exact.turn(w.change, np.asarray(camera["look_at"], dtype=np.float64))
    offset = exact.turn(w.change, np.asarray(
        w.cache.arrays.get("camera_offset", np.zeros((w.frames, 3))), dtype=np.float64))
    up = up_vector(w.options.up_axis)
    back = position - target
    back /= exact.length(back)
    right = np.cross(up, back)
    if exact.length(right) < 1e-9:  # looking straight along up
        right = np.cross(np.roll(up, 1), back)
    right /= exact.length(right)
    true_up = np.cross(back, right)
    # USD cameras look down -Z with +Y up; in USD's row-vector convention the
    # rows of the local-to-world matrix are the camera's axes in the world
    rotation = Gf.Matrix3d(*np.stack([right, true_up, back]).ravel().tolist())
    quat = rotation.ExtractRotation().GetQuat()
    cam = prim_spec(shot, "Camera", "Camera")
    tenths = MM_PER_TENTH_METRE  # lens and filmback in tenths of a metre
    attr_spec(cam, "focalLength", _T.Float,
          float(camera.get("focal_length_mm", 35.0)) / tenths)
    attr_spec(cam, "horizontalAperture", _T.Float, FILMBACK_MM[0] / tenths)
    attr_spec(cam, "verticalAperture", _T.Float, FILMBACK_MM[1] / tenths)
    attr_spec(cam, "clippingRange", _T.Float2, Gf.Vec2f(0.1, 10000.0))
    translate = attr_spec(cam, "xformOp:translate", _T.Double3)
    attr_spec(cam, "xformOp:orient", _T.Quatd, Gf.Quatd(quat))
    xform_order(cam, ["xformOp:translate", "xformOp:orient"])
    keep = run_ends(offset)
    for f in np.flatnonzero(keep).tolist():
        w.layer.SetTimeSample(translate.path, float(f),
                                 Gf.Vec3d(*map(float, position + offset[f])))

# ----------------------------------------------------------------------------- shock fronts

def write_shock(w, shot: Sdf.PrimSpec) -> None:
    """With ``options.shock``, a guide sphere per charge: time-sampled radius and
    extent, displayOpacity from the cache's ``shock_opacity`` (else 1 - r / r_max),
    invisible while the radius or the opacity is 0 (before detonation, or switched
    off). Guide purpose: viewports may show it, renders and Blender's importer skip
    it (it grows past the camera and would hide the shot)."""
    c = w.cache
    radius_all = np.asarray(c.shock_radius, dtype=np.float64).reshape(w.frames, -1)
    if not w.options.shock or radius_all.shape[1] == 0 or w.frames == 0:
        return
    opacity_all = c.arrays.get("shock_opacity")
    scope = prim_spec(shot, "Effects", "Xform")
    centres = exact.turn(w.change, c.charge_position.astype(np.float64))
    set_sample = w.layer.SetTimeSample
    for k in range(radius_all.shape[1]):
        radius = np.nan_to_num(radius_all[:, k], nan=0.0, posinf=0.0, neginf=0.0)
        radius = np.maximum(radius, 0.0)
        if opacity_all is not None and np.shape(opacity_all) == radius_all.shape:
            opacity = np.nan_to_num(np.asarray(opacity_all, dtype=np.float64)[:, k])
        else:
            r_max = float(radius.max())
            opacity = 1.0 - radius / r_max if r_max > 0 else np.zeros_like(radius)
        opacity = np.clip(opacity, 0.0, 1.0)
        sphere = prim_spec(scope, f"shock_{k}", "Sphere")
        attr_spec(sphere, "purpose", _T.Token, "guide", uniform=True)
        attr_spec(sphere, "xformOp:translate", _T.Double3, Gf.Vec3d(*map(float, centres[k])))
        xform_order(sphere, ["xformOp:translate"])
        attr_spec(sphere, "primvars:displayColor", _T.Color3fArray,
              Vt.Vec3fArray([Gf.Vec3f(*SHOCK_COLOR)]), interpolation="constant")
        r_path = attr_spec(sphere, "radius", _T.Double).path
        e_path = attr_spec(sphere, "extent", _T.Float3Array).path
        o_path = attr_spec(sphere, "primvars:displayOpacity", _T.FloatArray,
                       interpolation="constant").path
        keep = run_ends(np.stack([radius, opacity], axis=1))
        for f in np.flatnonzero(keep).tolist():
            r = float(radius[f])
            set_sample(r_path, float(f), r)
            set_sample(e_path, float(f), vec3f(np.array([[-r] * 3, [r] * 3]) + 0.0))
            set_sample(o_path, float(f), Vt.FloatArray([float(opacity[f])]))
        shown = (radius > 0) & (opacity > 0)
        vis = attr_spec(sphere, "visibility", _T.Token)
        changes = np.flatnonzero(np.diff(shown.astype(np.int8))) + 1
        if len(changes) == 0:
            vis.default = "inherited" if shown[0] else "invisible"
        for f in [0, *changes.tolist()] if len(changes) else []:
            set_sample(vis.path, float(f), "inherited" if shown[f] else "invisible")
