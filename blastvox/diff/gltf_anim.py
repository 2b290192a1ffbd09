"""``blastvox diff`` of glTF animations by their values at the frames, not by their keys.

Exports keep only the keys a tolerance needs (:mod:`blastvox.export.keys`), so two
files of nearly the same motion can key different frames, with accessors of other
counts and indices. Each channel is therefore compared by evaluating both files'
samplers, as glTF defines them (STEP, LINEAR with slerp for rotations, CUBICSPLINE
Hermite splines, normalised for rotations), at every key time of either file (all
channels' inputs together: the shot's frames), and the animations' accessors and
sampler indices are left out of the value-by-value comparison.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from blastvox.diff.common import _Collector


def animation_accessors(doc: dict[str, Any]) -> set[int]:
    """The indices of the accessors animation samplers use (inputs and outputs)."""
    used: set[int] = set()
    for anim in doc.get("animations", []) if isinstance(doc.get("animations"), list) else []:
        for sampler in anim.get("samplers", []) if isinstance(anim, dict) else []:
            if isinstance(sampler, dict):
                used.update(v for v in (sampler.get("input"), sampler.get("output"))
                            if isinstance(v, int))
    return used


def without_animation_keys(doc: dict[str, Any], used: set[int]) -> dict[str, Any]:
    """``doc`` for the value-by-value comparison: its animation accessors left out of
    ``accessors`` and each animation reduced to its channels' targets."""
    out = dict(doc)
    if isinstance(doc.get("accessors"), list):
        out["accessors"] = [a for i, a in enumerate(doc["accessors"]) if i not in used]
    if isinstance(doc.get("animations"), list):
        out["animations"] = [{"name": anim.get("name"),
                              "channels": [c.get("target") for c in anim.get("channels", [])
                                           if isinstance(c, dict)]}
                             if isinstance(anim, dict) else anim
                             for anim in doc["animations"]]
    return out


def sample(times: np.ndarray, values: np.ndarray, interpolation: str, at: np.ndarray,
           rotation: bool) -> np.ndarray:
    """A glTF sampler's value (len(at), n) at the times ``at`` (s): input ``times`` (K,),
    output ``values`` (K, n) or, CUBICSPLINE, (3 K, n) (in-tangent, value, out-tangent);
    held before the first and after the last key."""
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    values = np.asarray(values, dtype=np.float64).reshape(len(values), -1)
    k = len(times)
    cubic = interpolation == "CUBICSPLINE"
    v = values[1::3] if cubic else values
    if k == 0 or len(v) < k:
        return np.full((len(at), values.shape[1]), np.nan)
    i = np.clip(np.searchsorted(times, at, side="right") - 1, 0, k - 1)
    if k == 1 or interpolation == "STEP":
        return v[i]
    j = np.minimum(i + 1, k - 1)
    span = times[j] - times[i]
    u = np.where(span > 0, (np.clip(at, times[0], times[-1]) - times[i])
                 / np.where(span > 0, span, 1.0), 0.0)[:, None]
    if cubic:
        u2, u3 = u * u, u * u * u
        out = ((2 * u3 - 3 * u2 + 1) * v[i] + (u3 - 2 * u2 + u) * span[:, None] * values[2::3][i]
               + (-2 * u3 + 3 * u2) * v[j] + (u3 - u2) * span[:, None] * values[0::3][j])
    elif rotation:
        a, b = v[i], v[j]
        dot = np.sum(a * b, axis=1, keepdims=True)
        b = np.where(dot < 0, -b, b)
        theta = np.arccos(np.clip(np.abs(dot), 0.0, 1.0))
        s = np.sin(theta)
        small = s < 1e-9
        wa = np.where(small, 1 - u, np.sin((1 - u) * theta) / np.where(small, 1.0, s))
        wb = np.where(small, u, np.sin(u * theta) / np.where(small, 1.0, s))
        out = wa * a + wb * b
    else:
        out = (1 - u) * v[i] + u * v[j]
    if rotation:
        norm = np.linalg.norm(out, axis=1, keepdims=True)
        out = out / np.where(norm > 0, norm, 1.0)
    return out


def diff_animations(doc_a: dict[str, Any], doc_b: dict[str, Any],
                    accessor_a: Callable[[int], np.ndarray],
                    accessor_b: Callable[[int], np.ndarray], out: _Collector) -> None:
    """Compare the channels of each animation (matched by target node and path) by their
    sampled values at every key time of either file; a difference names A's sampler
    output and the channel (``piece_00003.translation``) and the frame (time x the
    scene's ``extras.fps``, or the time's index)."""
    anims_a = [a for a in doc_a.get("animations", []) if isinstance(a, dict)]
    anims_b = [a for a in doc_b.get("animations", []) if isinstance(a, dict)]
    channels_a = [_channels(doc_a, a) for a in anims_a]
    channels_b = [_channels(doc_b, b) for b in anims_b]
    cache_a: dict[int, np.ndarray] = {}
    cache_b: dict[int, np.ndarray] = {}

    def read(get: Callable[[int], np.ndarray], cache: dict[int, np.ndarray], i: int):
        if i not in cache:
            cache[i] = get(i)
        return cache[i]

    inputs = [read(accessor_a, cache_a, s["input"]) for ch in channels_a for s in ch.values()]
    inputs += [read(accessor_b, cache_b, s["input"]) for ch in channels_b for s in ch.values()]
    at = (np.unique(np.concatenate([np.asarray(t, np.float64).reshape(-1) for t in inputs]))
          if inputs else np.zeros(0))
    fps = _fps(doc_a)
    frames = np.rint(at * fps).astype(np.int64) if fps else np.arange(len(at))
    for a, (ch_a, ch_b) in enumerate(zip(channels_a, channels_b, strict=False)):
        for key, sa in ch_a.items():
            sb = ch_b.get(key)
            if sb is None:
                continue
            rotation = key[1] == "rotation"
            va = sample(read(accessor_a, cache_a, sa["input"]),
                        read(accessor_a, cache_a, sa["output"]), sa["interpolation"], at,
                        rotation)
            vb = sample(read(accessor_b, cache_b, sb["input"]),
                        read(accessor_b, cache_b, sb["output"]), sb["interpolation"], at,
                        rotation)
            if rotation:  # q and -q are the same rotation
                flip = np.sum(va * vb, axis=1) < 0
                vb[flip] = -vb[flip]
            out.arrays(va, vb, f"animations[{a}].samplers[{sa['index']}].output",
                       f"{key[0]}.{key[1]}", frame_axis=True, frames=frames)


def _channels(doc: dict[str, Any], anim: dict[str, Any]) -> dict[tuple[str, str], dict]:
    """(target node name, path) -> {"index", "input", "output", "interpolation"} of the
    channel's sampler (the first channel of each target)."""
    nodes = doc.get("nodes", []) if isinstance(doc.get("nodes"), list) else []
    samplers = anim.get("samplers", [])
    out: dict[tuple[str, str], dict] = {}
    for channel in anim.get("channels", []):
        try:
            node, path = channel["target"].get("node"), channel["target"]["path"]
            name = nodes[node].get("name") or f"nodes[{node}]"
            s = int(channel["sampler"])
            sampler = samplers[s]
            entry = {"index": s, "input": int(sampler["input"]),
                     "output": int(sampler["output"]),
                     "interpolation": sampler.get("interpolation", "LINEAR")}
        except (KeyError, IndexError, TypeError, ValueError, AttributeError):
            continue
        out.setdefault((str(name), str(path)), entry)
    return out


def _fps(doc: dict[str, Any]) -> float | None:
    try:
        fps = doc["scenes"][doc.get("scene", 0)]["extras"]["fps"]
    except (KeyError, IndexError, TypeError):
        return None
    return float(fps) if isinstance(fps, int | float) and fps > 0 else None
