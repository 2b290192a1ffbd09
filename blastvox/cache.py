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
piece_position             (F, P, 3) f4    m, world position of the pivot
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

Particles are ballistic with drag; their positions at any time follow from
the birth state in closed form (blastvox.particles.positions_at) with
the system parameters in ``meta["particle_systems"]`` and the model-frame
gravity vector ``meta["gravity_vector"]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blastvox import __version__
from blastvox.errors import ContractError
from blastvox.io.npz import read_npz, write_npz
from blastvox.model import VoxelModel

SCHEMA = "blastvox.SimCache"
SCHEMA_VERSION = 1
MODEL_PREFIX = "model."
UNITS = {"length": "m", "time": "s", "mass": "kg", "velocity": "m/s", "damage": "1/255"}

_REQUIRED = ("frame_time", "voxel_piece", "piece_pivot", "piece_mass", "piece_position",
             "piece_orientation", "piece_end_frame", "voxel_destroyed_frame", "damage_frame",
             "damage_voxel", "damage_value", "link_break_link", "link_break_time", "dust_voxel",
             "dust_time", "dust_mass", "dust_position", "dust_velocity", "charge_position",
             "charge_tnt_kg", "charge_time", "shock_radius", "shock_opacity", "camera_offset",
             "voxel_ignite_frame", "particle_system", "particle_birth", "particle_position",
             "particle_velocity", "particle_size")


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
        arrays.update({MODEL_PREFIX + k: v for k, v in self.model.arrays.items()})
        write_npz(path, arrays, meta)

    @classmethod
    def load(cls, path: str | Path) -> SimCache:
        """Read and validate; :class:`ContractError` if it is not a SimCache."""
        meta, arrays = read_npz(path, SCHEMA, SCHEMA_VERSION, what="SimCache")
        model_arrays = {k[len(MODEL_PREFIX):]: arrays.pop(k) for k in list(arrays)
                        if k.startswith(MODEL_PREFIX)}
        missing = [k for k in _REQUIRED if k not in arrays]
        if missing:
            raise ContractError(f"{path}: SimCache is missing array '{missing[0]}'")
        model = VoxelModel(arrays=model_arrays, meta=meta.pop("model", {}))
        return cls(arrays=arrays, model=model, meta=meta)

    def summary(self) -> dict[str, Any]:
        """JSON-safe summary for ``blastvox info``."""
        a = self.arrays
        moving = np.linalg.norm(a["piece_position"][-1] - a["piece_position"][0], axis=-1) > 1e-3
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
        }
