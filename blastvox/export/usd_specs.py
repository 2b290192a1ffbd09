"""Small helpers of the USD writer: Sdf specs, value conversion and sample thinning.

Shared by :mod:`blastvox.export.usd` (pieces) and :mod:`blastvox.export.usd_effects`
(particles, camera, shock fronts).
"""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, Tf, Vt

from blastvox.cache import SimCache
from blastvox.export.names import unique
from blastvox.geometry.frames import gravity_vector

ROOT = "/Shot"
#: children of /Shot that are not objects; an object with one of these names gets a suffix
RESERVED_PRIMS = frozenset({"Materials", "Pieces", "Particles", "Camera", "Effects"})
_T = Sdf.ValueTypeNames


def prim_spec(parent: Sdf.PrimSpec, name: str, type_name: str = "") -> Sdf.PrimSpec:
    """A ``def`` prim spec under ``parent``."""
    return Sdf.PrimSpec(parent, name, Sdf.SpecifierDef, type_name)


def attr_spec(prim: Sdf.PrimSpec, name: str, type_name, value=None,
              interpolation: str | None = None, uniform: bool = False) -> Sdf.AttributeSpec:
    """An attribute spec on ``prim``, with its default value and interpolation if given."""
    spec = Sdf.AttributeSpec(prim, name, type_name,
                             Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    if value is not None:
        spec.default = value
    if interpolation is not None:
        spec.SetInfo("interpolation", interpolation)
    return spec


def xform_order(prim: Sdf.PrimSpec, ops: list[str]) -> None:
    spec = Sdf.AttributeSpec(prim, "xformOpOrder", _T.TokenArray, Sdf.VariabilityUniform)
    spec.default = Vt.TokenArray(ops)


def origin_translate(prim: Sdf.PrimSpec, origin) -> None:
    """Give ``prim`` (an Xformable) a double3 ``xformOp:translate`` of ``origin`` (3,) m,
    the export's origin (:func:`blastvox.export.pieces.export_origin`), when it is not
    zero: the float32 points below it are relative to it."""
    if not any(float(x) for x in origin):
        return
    attr_spec(prim, "xformOp:translate", _T.Double3, Gf.Vec3d(*map(float, origin)))
    xform_order(prim, ["xformOp:translate"])


def object_prim_names(objects: list[str]) -> list[str]:
    """A valid, unique prim name for each piece's object name (P,): the name made a USD
    identifier (``Tf.MakeValidIdentifier``), ``object`` for an empty one, and a
    ``_<n>`` suffix where two names meet or a name is one of :data:`RESERVED_PRIMS`."""
    prim_of: dict[str, str] = {}
    taken = set(RESERVED_PRIMS)
    for name in dict.fromkeys(objects):
        prim_of[name] = unique(Tf.MakeValidIdentifier(name) if name else "object", taken)
    return [prim_of[name] for name in objects]


def part_prim_names(objects: list[str], parts: list[str]) -> list[str]:
    """A valid prim name, unique within its object, for each piece's part name (P,),
    as :func:`object_prim_names` makes them; "" where a piece has no part name."""
    prim_of: dict[tuple[str, str], str] = {}
    taken: dict[str, set[str]] = {}
    for key in dict.fromkeys(zip(objects, parts, strict=True)):
        if key[1]:
            prim_of[key] = unique(Tf.MakeValidIdentifier(key[1]), taken.setdefault(key[0], set()))
    return [prim_of.get(key, "") for key in zip(objects, parts, strict=True)]


def piece_prim_paths(objects: list[str], parts: list[str] | None = None) -> list[str]:
    """The path of each piece's Xform in the ``xforms`` layout (P,), given each piece's
    object name and part name: ``/Shot/<object>/piece_NNNNN``, or
    ``/Shot/<object>/<part>/piece_NNNNN`` for a piece of an input of several parts."""
    groups = object_prim_names(objects)
    if parts is not None:
        groups = [f"{o}/{q}" if q else o
                  for o, q in zip(groups, part_prim_names(objects, parts), strict=True)]
    return [f"{ROOT}/{g}/piece_{p:05d}" for p, g in enumerate(groups)]


def vec3f(a: np.ndarray) -> Vt.Vec3fArray:
    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1, 3))


def points_extent(points: np.ndarray) -> Vt.Vec3fArray:
    if len(points) == 0:
        return vec3f(np.zeros((2, 3)))
    return vec3f(np.stack([points.min(axis=0), points.max(axis=0)]))


def run_ends(values: np.ndarray) -> np.ndarray:
    """(F,) bool: frames that start or end a run of equal values along axis 0 of (F, ...)."""
    f = len(values)
    keep = np.zeros(f, dtype=bool)
    if f == 0:
        return keep
    keep[0] = True
    if f > 1:
        diff = (values[1:] != values[:-1]).reshape(f - 1, -1).any(axis=1)
        keep[1:] |= diff     # first frame of a new value
        keep[:-1] |= diff    # last frame of the old one (so interpolation holds it)
    return keep


def run_ends_pf(values: np.ndarray, live: np.ndarray) -> np.ndarray:
    """(P, F) bool: per piece, :func:`_run_ends` of ``values`` (P, F, k) over its live
    frames (``live`` (P, F), a prefix of the frames for each piece)."""
    p, f = live.shape
    keep = np.zeros((p, f), dtype=bool)
    if f == 0:
        return keep
    keep[:, 0] = True
    if f > 1:
        diff = (values[:, 1:] != values[:, :-1]).any(axis=-1) & live[:, 1:]
        keep[:, 1:] |= diff
        keep[:, :-1] |= diff
    return keep & live


def model_gravity(cache: SimCache) -> np.ndarray:
    """Model-frame gravity (m/s^2): meta["gravity_vector"], else -settings.gravity * up."""
    if cache.meta.get("gravity_vector") is not None:
        return np.asarray(cache.meta["gravity_vector"], dtype=np.float64).reshape(3)
    return gravity_vector(cache.model.meta.get("up_axis", "Y"),
                          cache.meta.get("settings", {}).get("gravity", 9.81))
