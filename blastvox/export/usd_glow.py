"""The USD export's glow of fire and the fireball: ``/Shot/Particles/<system>_glow``.

Blender's USD importer gives a Volume no material, so a plain import would show fire
and the fireball as grey smoke; it does import a PointInstancer's prototypes with
their UsdPreviewSurface, emission included, so fire and the fireball glow through an
instancer of emissive, translucent balls written beside the volume or the spheres
(:func:`write_glow`). How big each glow is and how particles are pooled into blobs
that keep their identity from frame to frame: :mod:`blastvox.export.glow`.
"""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, Vt

from blastvox.export.glow import glow_blobs, glow_groups, glow_share
from blastvox.export.usd_effects import (
    _bind,
    _sampled_frames,
    _velocity,
    sphere_mesh,
)
from blastvox.export.usd_specs import ROOT, attr_spec, prim_spec, vec3f
from blastvox.geometry import exact, fixed

_T = Sdf.ValueTypeNames
#: how deep the glow's balls are dented (a share of their radius): billows, so that
#: their edges are not circles
GLOW_LUMP = 0.3
#: the glow of fire and the fireball, per system. A particle glows over ``core`` times
#: its diameter at birth, shrinking as it cools to nothing at the Draper point (the
#: fireball's after the measured duration of its charge's fireball, fire's at the end
#: of its life), fire's growing in over ``rise`` s; a group (one blob) is the particles
#: born within ``window`` s and ``reach`` particle diameters (the system's median) of
#: its first. Each blob is two instances, both dented balls: its ``rim``, as wide as
#: the blob, and its ``hot`` core, the part of the blob still above ``hot_core_k`` (K),
#: which shrinks away first as the gas cools. Each emits its colour (linear RGB, above
#: 1 to glow through the smoke: a flame's red rim, its yellow core) through its
#: ``opacity``: a ray through a blob's centre crosses four translucent surfaces,
#: keeping (1 - rim)^2 (1 - hot)^2 of what is behind it (0.44 for the fireball while
#: its core is hot, 0.77 once it is gone), and Blender's Cycles stops after 8.
GLOW_LOOKS = {"fire": {"core": 1.2, "rise": 0.2, "window": 0.25, "reach": 4.0,
                       "hot_core_k": 1200.0,
                       "rim": ((1.2, 0.25, 0.03), 0.15), "hot": ((1.6, 0.7, 0.15), 0.25)},
              "fireball": {"core": 1.0, "rise": 0.0, "window": 0.25, "reach": 2.0,
                           "hot_core_k": 1500.0,
                           "rim": ((1.2, 0.25, 0.03), 0.12),
                           "hot": ((1.6, 0.8, 0.2), 0.25)}}
#: a hot core's diameter while all its blob's gas is above hot_core_k: a share of the blob's
HOT_SHARE = 0.6
#: the two prototypes of a glow instancer, in protoIndices order
GLOW_PARTS = ("rim", "hot")


def write_glow(w, scope: Sdf.PrimSpec, name: str, mine: np.ndarray, states: list, spec,
               birth: np.ndarray, v0: np.ndarray, size: np.ndarray, g: np.ndarray) -> None:
    """Particles/<name>_glow (see the module docstring): a PointInstancer in the
    alive-only layout (time-sampled positions, scales, velocities, ids, protoIndices
    and extent; a frame without a blob holds one of scale 0, the instancer invisible)
    with two prototypes, Prototypes/rim and Prototypes/hot (GLOW_PARTS), each bound to
    Materials/particle_<name>_glow_<k>. Blob b of
    :func:`blastvox.export.glow.glow_blobs` is instance id 2 b (its rim, as wide as the
    blob) and, while it has a hot core, id 2 b + 1 (the core), at the blob's centre;
    a blob's id is its group's for the whole shot. ``states[f]`` is (alive (P,) bool,
    positions (P, 3) m) of the system's particles ``mine`` at frame f; ``birth`` s,
    ``v0`` m/s and ``size`` m are all particles'; ``g`` (3,) m/s^2 gravity."""
    from blastvox.export.volumes import VOLUME_LOOKS

    look = GLOW_LOOKS[name]
    hot_k = VOLUME_LOOKS[name].hot_k
    times = w.cache.frame_time.astype(np.float64)
    sizes = size[mine].astype(np.float64)
    born = birth[mine]
    full = look["core"] * sizes
    duration = glow_duration(name, spec, sizes)
    group = glow_groups(born, w.cache.particle_position[mine].astype(np.float64),
                        look["window"], look["reach"] * float(np.median(sizes)))
    totals = np.bincount(group, full)
    blobs = []
    for t, (alive, x) in zip(times, states, strict=True):
        age = t - born[alive]
        glow = full[alive] * glow_share(age, duration[alive], hot_k, look["rise"])
        core = full[alive] * glow_share(age, duration[alive], hot_k, look["rise"],
                                        floor_k=look["hot_core_k"])
        ids, centre, diameter, hot, vel = glow_blobs(
            group[alive], x[alive], _velocity(spec, v0[mine][alive], age, g), glow, core,
            totals)
        hot = HOT_SHARE * hot
        keep = hot > 0
        blobs.append((np.concatenate([2 * ids, 2 * ids[keep] + 1]),
                      np.concatenate([centre, centre[keep]]),
                      np.concatenate([diameter, hot[keep]]),
                      np.concatenate([vel, vel[keep]]),
                      np.repeat([0, 1], [len(ids), int(keep.sum())]).astype(np.int32)))
    instancer = _glow_instancer(w, scope, name)
    specs = {key: attr_spec(instancer, key, kind) for key, kind in
             (("positions", _T.Point3fArray), ("scales", _T.Float3Array),
              ("velocities", _T.Vector3fArray), ("ids", _T.Int64Array),
              ("protoIndices", _T.IntArray), ("extent", _T.Float3Array))}
    first = next((b[1][:1] for b in blobs if len(b[0])), np.zeros((1, 3)))
    for f, empty in _sampled_frames(w, instancer, [not len(b[0]) for b in blobs]):
        ids, x, diameter, vel, proto = blobs[f]
        if empty:
            ids, x, diameter, vel = np.array([-1]), first, np.zeros(1), np.zeros((1, 3))
            proto = np.zeros(1, dtype=np.int32)
        box = np.stack([(x - diameter[:, None] / 2).min(axis=0),
                        (x + diameter[:, None] / 2).max(axis=0)])
        sample = float(f)
        w.layer.SetTimeSample(specs["positions"].path, sample, vec3f(x))
        w.layer.SetTimeSample(specs["scales"].path, sample,
                              vec3f(np.repeat(diameter[:, None], 3, axis=1)))
        w.layer.SetTimeSample(specs["velocities"].path, sample, vec3f(vel))
        w.layer.SetTimeSample(specs["ids"].path, sample, Vt.Int64Array.FromNumpy(
            np.ascontiguousarray(ids, dtype=np.int64)))
        w.layer.SetTimeSample(specs["protoIndices"].path, sample,
                              Vt.IntArray.FromNumpy(np.ascontiguousarray(proto)))
        w.layer.SetTimeSample(specs["extent"].path, sample, vec3f(box))


def glow_duration(name: str, spec, sizes: np.ndarray) -> np.ndarray:
    """(n,) s each particle of widths ``sizes`` (n,) m glows: its life, and for the
    fireball at most the measured duration of a fireball of its charge
    (:func:`blastvox.export.glow.fireball_duration`; the simulator makes the fireball's
    particles spec.size times W^(1/3) wide, W its charge's kg TNT)."""
    from blastvox.export.glow import fireball_duration

    life = np.full(len(sizes), spec.lifetime)
    if name != "fireball":
        return life
    ratio = sizes / spec.size
    return np.minimum(life, fireball_duration(ratio * ratio * ratio))


def _billow(unit: np.ndarray, k: int) -> np.ndarray:
    """A smooth bump in [-1, 1] over the unit directions ``unit`` (n, 3), pattern k's."""
    a = np.array([[0.8, 0.5, 0.3], [-0.4, 0.9, 0.2], [0.3, -0.2, 0.93]])[k % 3]
    b = np.array([[0.1, -0.7, 0.7], [0.9, 0.1, -0.4], [-0.6, 0.6, 0.5]])[k % 3]
    # (3 unit) . a, unit's float32 scaled first, as ``3.0 * unit @ a`` did (through BLAS,
    # whose FMA kernels, Haswell's or SkylakeX's, round otherwise than a CPU's without)
    return (fixed.sin(exact.dot(3.0 * unit, a) + 1.3 * k)
            * fixed.cos(exact.dot(2.0 * unit, b) + 0.7 * k))


def _glow_instancer(w, scope: Sdf.PrimSpec, name: str) -> Sdf.PrimSpec:
    """Particles/<name>_glow (PointInstancer) with Prototypes/rim and Prototypes/hot
    (GLOW_PARTS): each a ball of diameter 1 (an icosphere of 320 faces, smooth normals)
    dented by up to GLOW_LUMP of its radius in its own smooth pattern, bound to
    Materials/particle_<name>_glow_<k> (k its index in GLOW_PARTS)."""
    import trimesh

    instancer = prim_spec(scope, f"{name}_glow", "PointInstancer")
    prototypes = prim_spec(instancer, "Prototypes", "Scope")
    ball = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    unit = np.asarray(ball.vertices, dtype=np.float32)
    paths = []
    for k, part in enumerate(GLOW_PARTS):
        mesh = prim_spec(prototypes, part, "Mesh")
        radius = 0.5 * (1.0 - GLOW_LUMP * (1.0 - _billow(unit, k)) / 2.0)
        sphere_mesh(mesh, unit * radius[:, None], unit, np.asarray(ball.faces),
                    GLOW_LOOKS[name][part][0])
        _bind(mesh, _glow_material(w, name, k))
        paths.append(mesh.path)
    targets = Sdf.RelationshipSpec(instancer, "prototypes")
    targets.targetPathList.explicitItems = paths
    return instancer


def _glow_material(w, name: str, k: int) -> Sdf.Path:
    """/Shot/Materials/particle_<name>_glow_<k>: a UsdPreviewSurface that emits the
    colour of GLOW_LOOKS[name][GLOW_PARTS[k]] (no diffuse), translucent (its opacity)."""
    color, opacity = GLOW_LOOKS[name][GLOW_PARTS[k]]
    materials = w.layer.GetPrimAtPath(f"{ROOT}/Materials")
    material = prim_spec(materials, f"particle_{name}_glow_{k}", "Material")
    shader = prim_spec(material, "PreviewSurface", "Shader")
    attr_spec(shader, "info:id", _T.Token, "UsdPreviewSurface", uniform=True)
    attr_spec(shader, "inputs:diffuseColor", _T.Color3f, Gf.Vec3f(0.0))
    attr_spec(shader, "inputs:emissiveColor", _T.Color3f, Gf.Vec3f(*color))
    attr_spec(shader, "inputs:opacity", _T.Float, opacity)
    attr_spec(shader, "inputs:roughness", _T.Float, 1.0)
    out = attr_spec(shader, "outputs:surface", _T.Token)
    surface = attr_spec(material, "outputs:surface", _T.Token)
    surface.connectionPathList.explicitItems = [out.path]
    return material.path
