"""The pieces' animation channels of the glTF writer, keyframe-reduced.

With key tolerances (:class:`blastvox.export.options.ExportOptions`) each piece gets:

* a CUBICSPLINE ``translation`` sampler (LINEAR for a piece with one key): keys where
  :func:`blastvox.export.keys.reduce_keys` (cubic Hermite mode) needs them, each key's
  in- and out-tangent its velocity (m/s, the derivative of the quadratic through the
  frame and its neighbours: exact for a ballistic arc, whose flight then needs two keys);
* a LINEAR ``rotation`` sampler at its reduced keys (slerp, and Blender's normalised
  lerp of the components, within the rotation tolerance).

Input (time) accessors are shared by every sampler with the same key frames. Without
tolerances (both 0) every frame is keyed LINEAR, as :mod:`blastvox.export.gltf` always did.
"""

from __future__ import annotations

import numpy as np

from blastvox.export.gltf_buffer import FLOAT, _Builder, _f32, _floats
from blastvox.export.keys import reduce_keys


def key_tangents(times: np.ndarray, position: np.ndarray, live: np.ndarray) -> np.ndarray:
    """(P, F, 3) float32: the derivative (per second) of ``position`` (P, F, 3) at each frame
    time (F,) s: of the quadratic through the frame and its two neighbours, or, at a
    piece's first and last live frame (``live`` (P,) frames), through the frame and the
    two after or before it (two frames: their slope; one: 0). Exact for a quadratic."""
    p_count, f_count = position.shape[:2]
    out = np.zeros((p_count, f_count, 3), dtype=np.float64)
    if f_count < 2:
        return out.astype(np.float32)
    x = position.astype(np.float64)
    t = times.astype(np.float64)
    k = np.arange(f_count)
    n = np.minimum(np.maximum(np.asarray(live, dtype=np.int64), 1), f_count)[:, None]
    # the three frames of each (piece, frame)'s quadratic: centred, clamped to 0..n-1
    i0 = np.clip(np.minimum(k[None] - 1, n - 3), 0, None)
    i0 = np.minimum(i0, np.maximum(n - 3, 0))
    three = n >= 3
    i1, i2 = i0 + 1, i0 + 2
    p = np.arange(p_count)[:, None]
    tk = t[np.broadcast_to(k[None], i0.shape)]
    if f_count >= 3:
        j0, j1, j2 = (np.minimum(i, f_count - 1) for i in (i0, i1, i2))
        t0, t1, t2 = t[j0], t[j1], t[j2]
        with np.errstate(divide="ignore", invalid="ignore"):
            w0 = ((tk - t1) + (tk - t2)) / ((t0 - t1) * (t0 - t2))
            w1 = ((tk - t0) + (tk - t2)) / ((t1 - t0) * (t1 - t2))
            w2 = ((tk - t0) + (tk - t1)) / ((t2 - t0) * (t2 - t1))
        quad = (w0[..., None] * x[p, j0] + w1[..., None] * x[p, j1]
                + w2[..., None] * x[p, j2])
        out = np.where(three[..., None], np.nan_to_num(quad), out)
    two = n[:, 0] == 2
    if two.any():
        span = t[1] - t[0]
        slope = (x[two, 1] - x[two, 0]) / span if span > 0 else np.zeros((two.sum(), 3))
        out[two] = slope[:, None, :]
    out[k[None] >= n] = 0.0
    return out.astype(np.float32) + np.float32(0.0)


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
    tangent = key_tangents(times, pos, live)
    tr_keep = reduce_keys(t64, pos, None, live, tolerance_m, tolerance_deg, tangent)
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
    # translation: (in-tangent, value, out-tangent) per key; rotation: the value
    tan = tangent[tr_keep]
    cubic = np.ascontiguousarray(np.stack([tan, pos[tr_keep], tan], axis=1))   # (K, 3, 3)
    tr_view = b.view(_f32(cubic))
    rot_view = b.view(_f32(rot[rot_keep]))
    tr_count, rot_count = tr_keep.sum(axis=1), rot_keep.sum(axis=1)
    tr_start = np.r_[0, np.cumsum(tr_count)[:-1]].tolist()
    rot_start = np.r_[0, np.cumsum(rot_count)[:-1]].tolist()
    # a piece with one translation key (CUBICSPLINE needs two): LINEAR, the value alone
    single = tr_count == 1
    one_view = b.view(_f32(pos[single, np.argmax(tr_keep[single], axis=1)])) if single.any() \
        else -1
    one_start = (np.cumsum(single) - 1).tolist()
    single, tr_count, rot_count = single.tolist(), tr_count.tolist(), rot_count.tolist()
    out = []
    for p in range(p_count):
        if single[p]:
            translation = (inputs[set_of[p]],
                           b.accessor(one_view, one_start[p] * 12, FLOAT, 1, "VEC3"), "LINEAR")
        else:
            translation = (inputs[set_of[p]], b.accessor(tr_view, tr_start[p] * 36, FLOAT,
                                                         3 * tr_count[p], "VEC3"),
                           "CUBICSPLINE")
        out.append((translation, (inputs[set_of[p_count + p]], b.accessor(
            rot_view, rot_start[p] * 16, FLOAT, rot_count[p], "VEC4"), "LINEAR")))
    return out
