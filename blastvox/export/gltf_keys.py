"""The pieces' animation channels of the glTF writer, keyframe-reduced.

With key tolerances (:class:`blastvox.export.options.ExportOptions`) each piece gets a
LINEAR ``translation`` and a LINEAR ``rotation`` sampler at the keys
:func:`blastvox.export.keys.reduce_keys` keeps: translations within the tolerance of
linear interpolation, rotations of slerp (the specification's) and of the normalised
lerp of the components (Blender's quaternion F-curves). Input (time) accessors are
shared by every sampler with the same key frames. Without tolerances (both 0) every
frame is keyed, as :mod:`blastvox.export.gltf` always did.

Why not CUBICSPLINE translations, which would follow a ballistic arc with two keys (the
velocity as tangents): Blender 5.0's importer ignores the tangents
(``io_scene_gltf2/blender/imp/animation_node.py``: ``values[1::3]``, "TODO manage
tangent?") and draws AUTO Bezier handles through the key values instead, so a flying
piece of the house shot missed its frames by up to 4 cm there. A CUBICSPLINE key also
stores three values, so at a frame a key it is no smaller than LINEAR.
"""

from __future__ import annotations

import numpy as np

from blastvox.export.gltf_buffer import FLOAT, _Builder, _f32, _floats
from blastvox.export.keys import reduce_keys


def piece_channels(b: _Builder, times: np.ndarray, position: np.ndarray,
                   rotation: np.ndarray, end: np.ndarray, tolerance_m: float,
                   tolerance_deg: float) -> list[tuple[tuple, tuple]]:
    """Each piece's translation and rotation sampler, keyframe-reduced: a list (P,) of
    ((input, output, interpolation) of the translation, the same of the rotation),
    accessors in ``b``. times (F,) float32 s, position (F, P, 3) float32 m, rotation
    (F, P, 4) float32 (x, y, z, w), sign continuous, end (P,) each piece's end frame
    (later frames are not keyed; it is scaled to 0 there)."""
    f_count, p_count = position.shape[:2]
    if not p_count or not f_count:
        return []
    live = np.minimum(np.maximum(end, 1), f_count)
    t64 = times.astype(np.float64)
    pos = np.ascontiguousarray(position.transpose(1, 0, 2))            # (P, F, 3)
    rot = np.ascontiguousarray(rotation.transpose(1, 0, 2))            # (P, F, 4)
    tr_keep = reduce_keys(t64, pos, None, live, tolerance_m, tolerance_deg)
    rot_keep = reduce_keys(t64, None, rot, live, tolerance_m, tolerance_deg)
    # shared input accessors: one per distinct set of key frames, in order of first use
    rows = np.concatenate([tr_keep, rot_keep])                          # (2P, F)
    packed = np.packbits(rows, axis=1)
    _, first, inverse = np.unique(packed, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")                            # by first use
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    distinct = rows[first[order]]                                       # (S, F)
    key_times = np.broadcast_to(times, distinct.shape)[distinct]
    counts = distinct.sum(axis=1)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    t_view = b.view(_f32(key_times))
    lo_hi = _floats(np.stack([key_times[starts], key_times[starts + counts - 1]], axis=1))
    inputs = [b.accessor(t_view, int(s) * 4, FLOAT, int(c), "SCALAR", [lo], [hi])
              for s, c, (lo, hi) in zip(starts.tolist(), counts.tolist(), lo_hi, strict=True)]
    set_of = rank[inverse.reshape(-1)]
    tr_view = b.view(_f32(pos[tr_keep]))
    rot_view = b.view(_f32(rot[rot_keep]))
    tr_count, rot_count = tr_keep.sum(axis=1), rot_keep.sum(axis=1)
    tr_start = np.r_[0, np.cumsum(tr_count)[:-1]].tolist()
    rot_start = np.r_[0, np.cumsum(rot_count)[:-1]].tolist()
    tr_count, rot_count = tr_count.tolist(), rot_count.tolist()
    return [((inputs[set_of[p]], b.accessor(tr_view, tr_start[p] * 12, FLOAT, tr_count[p],
                                            "VEC3"), "LINEAR"),
             (inputs[set_of[p_count + p]], b.accessor(rot_view, rot_start[p] * 16, FLOAT,
                                                      rot_count[p], "VEC4"), "LINEAR"))
            for p in range(p_count)]
