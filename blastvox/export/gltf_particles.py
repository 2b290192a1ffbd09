"""The glTF export's particles (``--particles spheres``): a node per particle, a shared
translucent sphere per system, its translation and scale animated.

glTF cannot animate the points of one mesh (only morph targets, a whole copy of the
positions per frame), so each particle is a node: the system's unit UV sphere (the
shock sphere's mesh, radius 1) scaled to the particle's radius while it lives and to
0 before its birth and after its death (a STEP ``scale`` channel keyed at every
frame), and moved LINEARly through its closed-form positions (blastvox.particles)
at every frame. At most :data:`GLTF_PARTICLE_BUDGET` particles per system are
written, evenly spread over its particles in index order (importers make an object
per node and slow down with their number). Materials ``particle_<system>``:
translucent (``alphaMode`` BLEND, the USD sprite's colour, its opacity but at most
:data:`GLTF_MAX_ALPHA`), fire and the fireball emissive.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from blastvox.export.gltf_buffer import FLOAT, _Builder, _f32, _floats
from blastvox.geometry import exact

#: particles per system in a .glb at most (a node each)
GLTF_PARTICLE_BUDGET = 256
#: a sphere's alpha at most: the USD sprites' 0.8-0.9 for fire made the fireball a
#: heap of solid balls in Blender; overlapping spheres of 0.3 build up to a haze
GLTF_MAX_ALPHA = 0.3


#: each system's sphere: its colour (linear RGB) and look (alpha, emission). The USD
#: export's spheres are soft shells with a glow of their own (usd_effects); a glTF
#: sphere is one translucent ball, fire and the fireball emitting their colour.
PARTICLE_COLORS = {"dust": (0.55, 0.50, 0.45), "fire": (1.0, 0.45, 0.05),
                   "smoke": (0.25, 0.25, 0.25), "fireball": (1.0, 0.55, 0.1)}
PARTICLE_LOOKS = {"dust": {"opacity": 0.35, "emissive": 0.0},
                  "fire": {"opacity": 0.8, "emissive": 1.0},
                  "smoke": {"opacity": 0.3, "emissive": 0.0},
                  "fireball": {"opacity": 0.9, "emissive": 1.0}}


def add_particles(cache, b: _Builder, mats: list, meshes: list, nodes: list, channel,
                  t_acc: int | None, sphere_mesh, origin: np.ndarray) -> list[int]:
    """Append the particle nodes (and their materials, meshes and channels) of ``cache``
    (Y-up glTF) and return their node indices. ``sphere_mesh(b, material)`` makes the
    unit sphere mesh; ``channel(node, path, input, output, interpolation)`` adds an
    animation channel; ``t_acc`` the frame times' accessor (None: no frames); ``origin``
    (3,) m: the root node's translation, which the particles' are relative to."""
    from blastvox.export.usd_specs import model_gravity
    from blastvox.geometry.frames import frame_change, up_vector
    from blastvox.particles import SYSTEM_NAMES, all_positions_at, ground_plane

    system = cache.arrays.get("particle_system")
    if system is None or not len(system) or t_acc is None:
        return []
    change = frame_change(cache.model.meta.get("up_axis", "Y"), "Y")
    g = exact.turn(change, model_gravity(cache))
    x0 = exact.turn(change, cache.particle_position.astype(np.float64))
    v0 = exact.turn(change, cache.particle_velocity.astype(np.float64))
    ground = ground_plane(cache.meta.get("ground_height"),
                          up_vector(cache.model.meta.get("up_axis", "Y")), change)
    birth = cache.particle_birth.astype(np.float64)
    radius = cache.particle_size.astype(np.float64) / 2
    times = cache.frame_time.astype(np.float64)
    added = []
    for index, name in enumerate(SYSTEM_NAMES):
        mine = np.flatnonzero(system == index)
        if not mine.size:
            continue
        if len(mine) > GLTF_PARTICLE_BUDGET:
            mine = mine[np.unique(np.linspace(0, len(mine) - 1, GLTF_PARTICLE_BUDGET)
                                  .round().astype(np.int64))]
        look, color = PARTICLE_LOOKS[name], PARTICLE_COLORS[name]
        material: dict[str, Any] = {
            "name": f"particle_{name}", "alphaMode": "BLEND",
            "pbrMetallicRoughness": {"baseColorFactor": [*color, min(look["opacity"],
                                                                     GLTF_MAX_ALPHA)],
                                     "metallicFactor": 0.0, "roughnessFactor": 1.0}}
        if look["emissive"]:
            material["emissiveFactor"] = [c * look["emissive"] for c in color]
        mats.append(material)
        mesh = sphere_mesh(b, len(mats) - 1)
        mesh["name"] = f"particle_{name}"
        meshes.append(mesh)
        kinds = np.full(len(mine), index, dtype=np.uint8)
        states = [all_positions_at(birth[mine], x0[mine], v0[mine], kinds, t, g, ground)
                  for t in times]
        position = np.stack([x for _, x in states], axis=1) - origin       # (K, F, 3)
        alive = np.stack([a for a, _ in states], axis=1)                   # (K, F)
        scale = np.repeat((alive * radius[mine][:, None])[:, :, None], 3, axis=2)
        n_frames = len(times)
        tr_view, sc_view = b.view(_f32(position)), b.view(_f32(scale))
        for k, q in enumerate(mine.tolist()):
            nodes.append({"name": f"{name}_{q:06d}", "mesh": len(meshes) - 1,
                          "translation": _floats(position[k, 0]),
                          "scale": _floats(scale[k, 0]),
                          "extras": {"particle": q, "system": name}})
            node = len(nodes) - 1
            channel(node, "translation", t_acc,
                    b.accessor(tr_view, k * n_frames * 12, FLOAT, n_frames, "VEC3"))
            channel(node, "scale", t_acc,
                    b.accessor(sc_view, k * n_frames * 12, FLOAT, n_frames, "VEC3"), "STEP")
            added.append(node)
    return added
