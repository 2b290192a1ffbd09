"""The SimCache contract: what ``simulate`` writes and ``export`` reads.

A SimCache is self-contained: it embeds the VoxelModel it was made from
(arrays prefixed ``model.``, its meta under ``meta["model"]``), so export
needs no other file. Pieces never merge, so every *final piece* (a body alive
at the end, or a voxel turned to dust) moves rigidly for the whole shot, as
part of its ancestors before it split off; its pivot is its own rest centre of
mass. Sparse events replace dense per-voxel histories.

=========================  ==============  ======================================
name                       shape, dtype    meaning
=========================  ==============  ======================================
frame_time                 (F,) f8         s, output frame times
voxel_piece                (N,) i4         final piece of each voxel
piece_pivot                (P, 3) f8       m, rest centre of mass (model frame)
piece_mass                 (P,) f8         kg
piece_position             (F, P, 3) f4    m, world position of the pivot less position_origin
position_origin            (3,) f8         m, a multiple of ORIGIN_GRID_M (zero for a scene
                                          within 512 m of the origin; absent in version 1)
piece_orientation          (F, P, 4) f4    unit quaternion (w, x, y, z), rest -> world
piece_end_frame            (P,) i4         first frame the piece is gone (F if never)
voxel_destroyed_frame      (N,) i4         frame the voxel turned to dust, -1 never
damage_frame/voxel/value   (D,) i4/i4/u1   per-voxel damage 0..255 (=0..1) from that frame
link_break_link/time       (K,) i4/f8      link broken at time s
dust_voxel/time/mass       (Q,) i4/f8/f8   destroyed voxels as dust emitters
dust_position/velocity     (Q, 3) f8       m and m/s at destruction
charge_position            (C, 3) f8       m
charge_tnt_kg/time         (C,) f8         TNT-equivalent kg, detonation s
shock_radius               (F, C) f8       m, shock front radius (0 before detonation)
shock_opacity              (F, C) f8       0..1, shock sphere opacity (0: hidden/off)
camera_offset              (F, 3) f8       m, camera shake added to meta["camera"]
voxel_ignite_frame         (N,) i4         frame the voxel caught fire, -1 never
particle_system            (Q,) u1         index into meta["particle_systems"]
particle_birth             (Q,) f8         s
particle_position/velocity (Q, 3) f8       m, m/s at birth (model frame)
particle_size              (Q,) f4         m
=========================  ==============  ======================================

Positions are float32 offsets from a float64 origin near the scene: 2^-24 of the
distance from it, under 0.1 mm within a kilometre of it, wherever the scene is (plain
float32 moved a scene 100 km out in 7.8 mm steps). In memory (:meth:`SimCache.load`,
and what ``simulate`` returns) ``piece_position`` is float64 world positions, the
sum, so readers never see the offsets; :meth:`SimCache.save` splits them again,
exactly.

Particles are ballistic with drag; their positions at any time follow from
the birth state in closed form (blastvox.particles.positions_at) with
the system parameters in ``meta["particle_systems"]`` and the model-frame
gravity vector ``meta["gravity_vector"]``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blastvox import __version__
from blastvox.geometry.frames import UP_AXES
from blastvox.io.npz import read_npz, write_npz
from blastvox.io.validate import (
    Spec,
    check_bound,
    check_finite,
    check_index,
    check_layout,
    check_meta_number,
    check_meta_vector,
    check_non_decreasing,
    check_range,
    check_shapes,
    check_unit,
    fail,
)
from blastvox.model import ARRAY_NAMES as MODEL_ARRAY_NAMES
from blastvox.model import COORD_LIMIT_M, VoxelModel, check_model
from blastvox.particles import SYSTEM_NAMES

SCHEMA = "blastvox.SimCache"
#: 2: piece_position is relative to position_origin (version 1's, absolute float32, moved
#: a scene 100 km from the origin in 7.8 mm steps); version 1 files are still read
SCHEMA_VERSION = 2
#: Grid (m) of ``position_origin``: a power of two, so its multiples within the model's
#: 10^7 m are exact in float32 and float64 alike.
ORIGIN_GRID_M = 1024.0
MODEL_PREFIX = "model."
UNITS = {"length": "m", "time": "s", "mass": "kg", "velocity": "m/s", "damage": "1/255"}

_F8, _F4, _I4, _U1 = np.float64, np.float32, np.int32, np.uint8

#: Every SimCache array: name -> (dtype, shape). Symbols: F frames, P pieces, N voxels
#: (of the embedded model), D damage events, K link breaks, E dust emitters, X charges,
#: Q particles.
_REQUIRED: dict[str, Spec] = {
    "frame_time": (_F8, ("F",)), "voxel_piece": (_I4, ("N",)),
    "piece_pivot": (_F8, ("P", 3)), "piece_mass": (_F8, ("P",)),
    "piece_position": (_F4, ("F", "P", 3)), "position_origin": (_F8, (3,)),
    "piece_orientation": (_F4, ("F", "P", 4)),
    "piece_end_frame": (_I4, ("P",)), "voxel_destroyed_frame": (_I4, ("N",)),
    "damage_frame": (_I4, ("D",)), "damage_voxel": (_I4, ("D",)),
    "damage_value": (_U1, ("D",)), "link_break_link": (_I4, ("K",)),
    "link_break_time": (_F8, ("K",)), "dust_voxel": (_I4, ("E",)),
    "dust_time": (_F8, ("E",)), "dust_mass": (_F8, ("E",)),
    "dust_position": (_F8, ("E", 3)), "dust_velocity": (_F8, ("E", 3)),
    "charge_position": (_F8, ("X", 3)), "charge_tnt_kg": (_F8, ("X",)),
    "charge_time": (_F8, ("X",)), "shock_radius": (_F8, ("F", "X")),
    "shock_opacity": (_F8, ("F", "X")), "camera_offset": (_F8, ("F", 3)),
    "voxel_ignite_frame": (_I4, ("N",)), "particle_system": (_U1, ("Q",)),
    "particle_birth": (_F8, ("Q",)), "particle_position": (_F8, ("Q", 3)),
    "particle_velocity": (_F8, ("Q", 3)), "particle_size": (_F4, ("Q",)),
}
_MEANING = {"F": "one per frame", "P": "one per piece", "N": "one per voxel of the model",
            "D": "one per damage event", "K": "one per link break",
            "E": "one per dust emitter", "X": "one per charge", "Q": "one per particle"}
#: piece_orientation rows must be unit quaternions to this (they are stored as float32)
QUATERNION_TOLERANCE = 1e-3


def _is_member(name: str) -> bool:
    """Is ``name`` a SimCache array or an embedded model array? Others are never read."""
    if name.startswith(MODEL_PREFIX):
        return name[len(MODEL_PREFIX):] in MODEL_ARRAY_NAMES
    return name in _REQUIRED


@dataclass(frozen=True)
class SimCache:
    """Simulation result: ``arrays`` (module doc), ``meta`` and the embedded ``model``."""

    arrays: dict[str, np.ndarray]
    model: VoxelModel
    meta: dict[str, Any] = field(default_factory=dict)

    def __getattr__(self, name: str) -> np.ndarray:
        try:
            return self.__dict__["arrays"][name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def frame_count(self) -> int:
        return int(len(self.arrays["frame_time"]))

    @property
    def piece_count(self) -> int:
        return int(len(self.arrays["piece_mass"]))

    def save(self, path: str | Path) -> None:
        """Write atomically and deterministically."""
        meta = dict(self.meta)
        # the embedded model carries its contract stamps however it was obtained
        # (just voxelized or loaded), so the bytes do not depend on that
        meta.update(schema=SCHEMA, schema_version=SCHEMA_VERSION, units=UNITS,
                    tool_version=meta.get("tool_version", __version__),
                    model=self.model.contract_meta())
        arrays = dict(self.arrays)
        position = np.asarray(arrays["piece_position"], dtype=np.float64)
        origin = arrays.get("position_origin")
        origin = position_origin(position) if origin is None else np.asarray(origin, _F8)
        arrays["position_origin"] = origin
        arrays["piece_position"] = _offsets(position, origin)
        arrays.update({MODEL_PREFIX + k: v for k, v in self.model.arrays.items()})
        write_npz(path, arrays, meta)

    @classmethod
    def load(cls, path: str | Path) -> SimCache:
        """Read and validate; :class:`ContractError` if it is not a SimCache."""
        meta, arrays = read_npz(path, SCHEMA, SCHEMA_VERSION, what="SimCache",
                                members=_is_member)
        model_arrays = {k[len(MODEL_PREFIX):]: arrays.pop(k) for k in list(arrays)
                        if k.startswith(MODEL_PREFIX)}
        model_meta = meta.pop("model", None)
        upgrade(meta, arrays)
        check_cache(path, arrays, meta, model_arrays, model_meta)
        arrays["piece_position"] = world_positions(arrays["position_origin"],
                                                   arrays["piece_position"])
        model = VoxelModel(arrays=model_arrays, meta=model_meta)
        return cls(arrays=arrays, model=model, meta=meta)

    def summary(self) -> dict[str, Any]:
        """JSON-safe summary for ``blastvox info``."""
        a = self.arrays
        moving = moved_pieces(a)
        return {
            "kind": "SimCache", "schema_version": self.meta.get("schema_version"),
            "tool_version": self.meta.get("tool_version"),
            "frame_count": self.frame_count, "fps": self.meta.get("fps"),
            "dt_s": self.meta.get("dt"), "duration_s": self.meta.get("duration"),
            "piece_count": self.piece_count, "moving_piece_count": int(moving.sum()),
            "voxel_count": int(len(a["voxel_piece"])),
            "broken_link_count": int(len(a["link_break_link"])),
            "destroyed_voxel_count": int((a["voxel_destroyed_frame"] >= 0).sum()),
            "charge_count": int(len(a["charge_tnt_kg"])),
            "fracture": self.meta.get("fracture"), "seed": self.meta.get("seed"),
            "closed_room_count": len(self.meta.get("confinement") or []),
            "leaky_room_count": len(self.meta.get("leaky_rooms") or []),
            "leaky_room_volume_m3": round(sum(r["free_volume_m3"] for r in
                                              self.meta.get("leaky_rooms") or []), 3),
            **{f"momentum_{term}_n_s": [round(x, 3) for x in value]
               for term, value in self.meta.get("momentum", {}).items()},
        }


def upgrade(meta: Mapping[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """Bring the arrays of an older SimCache (``meta["schema_version"]`` < 2) to this
    version in place, losing nothing: version 1's absolute float32 ``piece_position``
    is the offset from a ``position_origin`` of zero. Anything else is left for
    :func:`check_cache` to judge."""
    version = meta.get("schema_version")
    if isinstance(version, int) and version < 2 and "position_origin" not in arrays:
        arrays["position_origin"] = np.zeros(3)


def position_origin(position: np.ndarray) -> np.ndarray:
    """(3,) float64 m: the multiple of :data:`ORIGIN_GRID_M` nearest the centre of the
    box round the first frame's finite positions ``position`` (F, P, 3); zero for a
    scene within half a grid (512 m) of the origin (then the offsets are the positions:
    version 1's bytes)."""
    position = np.asarray(position, dtype=np.float64)
    first = position[0][np.all(np.isfinite(position[0]), axis=-1)] if len(position) else ()
    if not len(first):
        return np.zeros(3)
    centre = 0.5 * (first.min(axis=0) + first.max(axis=0))
    return np.rint(centre / ORIGIN_GRID_M) * ORIGIN_GRID_M + 0.0  # no -0


def _offsets(position: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """float32 offsets (F, P, 3) of float64 ``position`` from ``origin`` (3,)."""
    offset = np.array(position, dtype=np.float64)
    for a in range(3):
        if origin[a] != 0.0:  # an axis at zero keeps its values (and signed zeros)
            offset[..., a] -= origin[a]
    return offset.astype(np.float32)


def world_positions(origin: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """float64 world positions (F, P, 3): float32 ``offset`` plus ``origin`` (3,); what
    :meth:`SimCache.save` writes for them is ``offset`` again, exactly."""
    out = np.asarray(offset).astype(np.float64)
    for a in range(3):
        if origin[a] != 0.0:
            out[..., a] += origin[a]
    return out


def quantised(position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position_origin (3,), piece_position (F, P, 3) float64) as a SimCache holds
    float64 world positions ``position`` in memory: what it saves and loads back."""
    origin = position_origin(position)
    return origin, world_positions(origin, _offsets(position, origin))


#: A piece moved when its centre travelled further than this over the shot (m).
MOVED_M = 1e-3


def moved_pieces(arrays: Mapping[str, np.ndarray]) -> np.ndarray:
    """(P,) bool: the pieces whose centre travelled more than :data:`MOVED_M` from the
    first frame to the last, from a SimCache's ``arrays``."""
    position = arrays["piece_position"]
    return np.linalg.norm(position[-1] - position[0], axis=-1) > MOVED_M


def check_cache(path: str | os.PathLike, arrays: Mapping[str, np.ndarray],
                meta: Mapping[str, Any], model_arrays: Mapping[str, np.ndarray],
                model_meta: Any) -> None:
    """Check a SimCache's arrays and meta, and its embedded model, against the contract.

    ``arrays`` and ``meta`` are the cache's own (``meta`` without ``"model"``);
    ``model_arrays`` (names without ``model.``) and ``model_meta`` the embedded
    VoxelModel's, checked by :func:`blastvox.model.check_model` including its
    schema and ``schema_version``. The cache's arrays: every dtype and shape
    (against F, P, N, D, K, E, X and Q); frame_time finite, starting at 0, never
    decreasing; finite floats everywhere; masses, TNT masses and particle sizes
    > 0; times and shock radii >= 0, shock_opacity in [0, 1]; unit quaternions;
    every voxel's piece, every event's frame, voxel and link, and every particle's
    system within bounds, every piece owning a voxel. Its meta: ``fps``, ``dt``,
    ``duration`` > 0, ``gravity_vector``, ``ground_height``, ``up_axis``,
    ``camera``, ``particle_systems`` and ``settings`` as export and preview read
    them. Raises :class:`~blastvox.errors.ContractError`: one line naming ``path``
    and the array or meta key.
    """
    if not isinstance(model_meta, dict):
        fail(path, "meta model is missing: a SimCache embeds its VoxelModel's meta")
    check_model(path, model_arrays, model_meta, MODEL_PREFIX)
    a = arrays
    check_layout(path, a, _REQUIRED, "", "SimCache")
    n, links = len(model_arrays["voxel_mass"]), len(model_arrays["link_voxels"])
    dims = {"F": len(a["frame_time"]), "P": len(a["piece_mass"]), "N": n,
            "D": len(a["damage_frame"]), "K": len(a["link_break_link"]),
            "E": len(a["dust_voxel"]), "X": len(a["charge_tnt_kg"]),
            "Q": len(a["particle_system"])}
    check_shapes(path, a, _REQUIRED, dims, "", _MEANING)
    frames, pieces = dims["F"], dims["P"]
    systems = _check_meta(path, meta, model_meta, dims["Q"])
    # frames
    if frames == 0:
        fail(path, "array 'frame_time' is empty: the SimCache holds no frames")
    check_finite(path, "frame_time", a["frame_time"])
    if a["frame_time"][0] != 0.0:
        fail(path, f"array 'frame_time' starts at {float(a['frame_time'][0])!r} s; expected 0")
    check_non_decreasing(path, "frame_time", a["frame_time"])
    # pieces
    check_index(path, "voxel_piece", a["voxel_piece"], pieces, "piece")
    owned = np.bincount(a["voxel_piece"], minlength=pieces)
    if pieces and not owned.min() > 0:
        fail(path, f"array 'voxel_piece' gives piece {int(np.argmin(owned))} no voxel")
    check_bound(path, "piece_pivot", a["piece_pivot"], COORD_LIMIT_M)
    check_bound(path, "position_origin", a["position_origin"], COORD_LIMIT_M)
    check_range(path, "piece_mass", a["piece_mass"], 0.0, lo_open=True)
    check_finite(path, "piece_position", a["piece_position"])
    check_unit(path, "piece_orientation", a["piece_orientation"], QUATERNION_TOLERANCE,
               "unit quaternion")
    check_range(path, "piece_end_frame", a["piece_end_frame"], 0, frames,
                rule=f"a frame 0..{frames} (F: never gone)")
    # per-voxel frames and events
    for key in ("voxel_destroyed_frame", "voxel_ignite_frame"):
        check_index(path, key, a[key], frames, "frame", none=-1)
    check_index(path, "damage_frame", a["damage_frame"], frames, "frame")
    check_index(path, "damage_voxel", a["damage_voxel"], n, "voxel")
    check_index(path, "link_break_link", a["link_break_link"], links, "link")
    check_index(path, "dust_voxel", a["dust_voxel"], n, "voxel")
    for key in ("link_break_time", "dust_time", "charge_time"):
        check_range(path, key, a[key], 0.0)
    for key in ("dust_mass", "charge_tnt_kg", "particle_size"):
        check_range(path, key, a[key], 0.0, lo_open=True)
    for key in ("dust_position", "dust_velocity", "camera_offset", "particle_birth",
                "particle_position", "particle_velocity"):
        check_finite(path, key, a[key])
    check_bound(path, "charge_position", a["charge_position"], COORD_LIMIT_M)
    check_range(path, "shock_radius", a["shock_radius"], 0.0)
    check_range(path, "shock_opacity", a["shock_opacity"], 0.0, 1.0)
    check_index(path, "particle_system", a["particle_system"], systems, "particle system")


def _check_meta(path: str | os.PathLike, meta: Mapping[str, Any],
                model_meta: Mapping[str, Any], particles: int) -> int:
    """The meta keys export and preview read; returns the number of particle systems."""
    for key in ("fps", "dt", "duration"):
        if meta.get(key) is not None:
            check_meta_number(path, key, meta[key], 0.0, lo_open=True)
    if meta.get("gravity_vector") is not None:
        check_meta_vector(path, "gravity_vector", meta["gravity_vector"])
    if meta.get("ground_height") is not None:
        check_meta_number(path, "ground_height", meta["ground_height"], limit=COORD_LIMIT_M)
    up = meta.get("up_axis")
    if up is not None and (up not in UP_AXES or up != model_meta.get("up_axis")):
        fail(path, f"meta up_axis is {up!r}; expected the model's, "
                   f"{model_meta.get('up_axis')!r}")
    settings = meta.get("settings")
    if settings is not None:
        if not isinstance(settings, dict):
            fail(path, f"meta settings is {type(settings).__name__}; expected an object")
        if settings.get("gravity") is not None:
            check_meta_number(path, "settings.gravity", settings["gravity"], 0.0)
    camera = meta.get("camera")
    if camera is not None:
        if not isinstance(camera, dict):
            fail(path, f"meta camera is {type(camera).__name__}; expected an object or null")
        check_meta_vector(path, "camera.position", camera.get("position"), limit=COORD_LIMIT_M)
        check_meta_vector(path, "camera.look_at", camera.get("look_at"), limit=COORD_LIMIT_M)
        if camera["position"] == camera["look_at"]:
            fail(path, "meta camera.look_at is the camera's position; the camera looks nowhere")
        if camera.get("focal_length_mm") is not None:
            check_meta_number(path, "camera.focal_length_mm", camera["focal_length_mm"], 1.0,
                              limit=10_000.0)  # an export's field of view stays valid
    systems = meta.get("particle_systems")
    if systems is None:
        if particles:
            fail(path, "meta particle_systems is missing; the particle arrays refer to it")
        return len(SYSTEM_NAMES)
    if not isinstance(systems, list) or len(systems) > len(SYSTEM_NAMES):
        fail(path, f"meta particle_systems is not a list of at most {len(SYSTEM_NAMES)} "
                   "particle systems")
    for i, system in enumerate(systems):
        where = f"particle_systems[{i}]"
        if not isinstance(system, dict) or not isinstance(system.get("name"), str):
            fail(path, f"meta {where} is not a particle system with a 'name'")
        for key in ("drag_per_s", "lifetime_s", "size_m"):
            check_meta_number(path, f"{where}.{key}", system.get(key), 0.0, lo_open=True)
        check_meta_number(path, f"{where}.gravity_scale", system.get("gravity_scale"))
    return len(systems)
