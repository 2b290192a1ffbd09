"""The USD export's particle systems as volumes: a ``UsdVolVolume`` per system whose
``OpenVDBAsset`` fields read per-frame OpenVDB files beside the USD file.

``/Shot/Particles/<system>`` (Volume) has ``field:density`` (and for fire and the
fireball ``field:temperature``) targeting its child ``OpenVDBAsset`` prims of the same
names, whose ``filePath`` is time-sampled at every frame from the first with a live
particle to the last: ``@./<stem>_volumes/<system>.<frame:04d>.vdb@``, one file per
frame holding all of the system's grids (Blender reads one file per Volume object and
finds the frame in the file name). The Volume's ``extent`` is time-sampled (the
active voxels' box), ``visibility`` is "invisible" outside the frames that have
files, and it is bound to ``Materials/particle_<system>``, the sprite's
UsdPreviewSurface (the system's colour, a hint for lighters: Blender's USD importer
reads no material of a Volume, see docs/file-formats.md). Fire and the fireball glow
on a plain import through ``Particles/<system>_glow``, an instancer of emissive
balls written beside the Volume (:func:`blastvox.export.usd_glow.write_glow`).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf

from blastvox.errors import BlastvoxError, OutputError
from blastvox.export.usd_specs import attr_spec, prim_spec, vec3f

_T = Sdf.ValueTypeNames


def write_volume(w, scope: Sdf.PrimSpec, name: str, states: list, size: np.ndarray,
                 birth: np.ndarray, lifetime: float, bind) -> int:
    """Particles/<name> as a Volume (see the module docstring): ``states[f]`` is (alive
    (P,) bool, positions (P, 3) m in the export frame) of the system's P particles at
    frame f, ``size`` (P,) m their diameters, ``birth`` (P,) s their birth times,
    ``lifetime`` s the system's. Writes the frames' .vdb files into ``w.volume_out``
    and returns the bytes written (0 and no prim if no frame has a live particle)."""
    from blastvox.export.vdb import write_vdb
    from blastvox.export.volumes import frame_grids, grid_fields, system_voxel, volume_file

    live = [f for f, (alive, _) in enumerate(states) if alive.any()]
    if not live:
        return 0
    first, last = live[0], live[-1]
    voxel = system_voxel(size, w.options.volume_voxel_m)
    volume = prim_spec(scope, name, "Volume")
    fields = grid_fields(name)
    paths = {}
    for field in fields:
        asset = prim_spec(volume, field, "OpenVDBAsset")
        attr_spec(asset, "fieldName", _T.Token, field)
        attr_spec(asset, "fieldDataType", _T.Token, "float")
        attr_spec(asset, "fieldClass", _T.Token, "fogVolume" if field == "density" else "unknown")
        paths[field] = attr_spec(asset, "filePath", _T.Asset).path
        rel = Sdf.RelationshipSpec(volume, f"field:{field}")
        rel.targetPathList.explicitItems = [asset.path]
    extent = attr_spec(volume, "extent", _T.Float3Array).path
    visibility = attr_spec(volume, "visibility", _T.Token).path
    times = w.cache.frame_time.astype(np.float64)
    written = 0
    box = None
    w.volume_out.mkdir(parents=True, exist_ok=True)
    for f in range(first, last + 1):
        alive, x = states[f]
        age = (times[f] - birth[alive]) / lifetime
        try:
            grids = frame_grids(name, x[alive], size[alive], age, voxel)
        except ValueError as exc:  # cells too small for the shot: one line, no output
            raise BlastvoxError(f"{w.volume_out}: {name} particles at frame {f}: {exc}; "
                                f"use a larger --volume-voxel ([output] volume_voxel_m) or "
                                f"--particles spheres") from None
        target = volume_file(w.volume_out, name, f)
        try:
            written += write_vdb(target, grids)
        except OSError as exc:
            raise OutputError(f"{target}: cannot write ({exc.strerror or exc})") from None
        relative = f"./{w.volume_dir}/{target.name}"
        for field in fields:
            w.layer.SetTimeSample(paths[field], float(f), Sdf.AssetPath(relative))
        ijk = grids[0].ijk
        if len(ijk):
            box = np.stack([(ijk.min(axis=0) - 0.5) * voxel, (ijk.max(axis=0) + 0.5) * voxel])
        elif box is None:
            box = np.stack([x[alive].min(axis=0), x[alive].max(axis=0)]) if alive.any() \
                else np.zeros((2, 3))
        w.layer.SetTimeSample(extent, float(f), vec3f(box))
    if first > 0:
        w.layer.SetTimeSample(visibility, 0.0, "invisible")
    w.layer.SetTimeSample(visibility, float(first), "inherited")
    if last + 1 < w.frames:
        w.layer.SetTimeSample(visibility, float(last + 1), "invisible")
    bind(volume, name)
    return written
