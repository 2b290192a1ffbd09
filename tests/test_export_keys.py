"""Keyframe reduction (blastvox/export/keys.py): every frame of a reduced file, read back
with pxr (USD interpolates itself) and with a glTF reader written here (LINEAR: lerp and
slerp, CUBICSPLINE: Hermite, as the glTF specification defines them), is within the
tolerance of the unreduced file's transform, and exact at the keys it keeps (Blender 5.0
imports CUBICSPLINE without its tangents, so the exports write LINEAR keys only).

The cache is synthetic: pieces at rest before they break, flying ballistically and
tumbling, one bouncing, all settled for the last frames, some vanishing part-way.
"""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd  # noqa: E402

from blastvox.cache import _REQUIRED, SimCache  # noqa: E402
from blastvox.export.api import ExportOptions, export  # noqa: E402
from blastvox.export.gltf import bench_cache  # noqa: E402
from blastvox.export.keys import KEY_TOLERANCE_DEG, KEY_TOLERANCE_M, reduce_keys  # noqa: E402
from blastvox.export.pieces import piece_objects, piece_parts  # noqa: E402
from blastvox.export.usd_specs import piece_prim_paths  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FRAMES, REST, SETTLED = 40, 6, 30
EXACT = ExportOptions(key_tolerance_m=0.0, key_tolerance_deg=0.0)
#: slack for float32 storage and the readers' own float arithmetic
SLACK_M, SLACK_DEG = 2e-6, 2e-3


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> SimCache:
    base = bench_cache(pieces=27, frames=FRAMES, fps=24.0, seed=3)
    pos = base.piece_position.astype(np.float64)
    ori = base.piece_orientation.astype(np.float64)
    pos, ori = pos - pos[REST] + pos[0], ori.copy()
    # at rest until REST (then the same arcs, starting there), settled from SETTLED on
    shift = np.arange(FRAMES) - REST
    idx = np.clip(shift, 0, None)
    pos, ori = pos[idx], ori[idx]
    pos[SETTLED:], ori[SETTLED:] = pos[SETTLED], ori[SETTLED]
    # piece 0 bounces at frame 15: its height is mirrored about the frame's
    pos[15:SETTLED, 0, 2] = 2 * pos[15, 0, 2] - pos[15:SETTLED, 0, 2]
    pos[SETTLED:, 0] = pos[SETTLED - 1, 0]
    arrays = {**base.arrays, "piece_position": pos.astype(np.float32),
              "piece_orientation": ori.astype(np.float32)}
    sizes = {"F": FRAMES, "N": base.model.voxel_count, "X": 1, "P": base.piece_count}
    for name, (dtype, shape) in _REQUIRED.items():  # the rest: none of them (Q, ...: 0)
        if name not in arrays:
            fill = -1 if name.endswith("_frame") else (1 if name == "shock_opacity" else 0)
            arrays[name] = np.full([sizes.get(d, 0) if isinstance(d, str) else d
                                    for d in shape], fill, dtype=dtype)
    path = tmp_path_factory.mktemp("keys") / "sim.npz"
    SimCache(arrays=arrays, model=base.model, meta=base.meta).save(path)
    return SimCache.load(path)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles (degrees) of the rotations between unit quaternions a and b (..., 4)."""
    dot = np.abs(np.sum(a * b, axis=-1) / np.linalg.norm(a, axis=-1)
                 / np.linalg.norm(b, axis=-1))
    return np.degrees(2.0 * np.arccos(np.clip(dot, 0.0, 1.0)))


# ----------------------------------------------------------------------------- USD

def _usd_frames(path: Path, cache: SimCache) -> tuple[np.ndarray, np.ndarray, int]:
    """Translate (P, F, 3) and orient (P, F, 4) (w, x, y, z) of every piece at every
    frame, as USD interpolates them, and the number of transform samples."""
    stage = Usd.Stage.Open(str(path))
    paths = piece_prim_paths(piece_objects(cache), piece_parts(cache))
    t = np.zeros((cache.piece_count, FRAMES, 3))
    q = np.zeros((cache.piece_count, FRAMES, 4))
    samples = 0
    for p, prim_path in enumerate(paths):
        prim = stage.GetPrimAtPath(prim_path)
        translate, orient = prim.GetAttribute("xformOp:translate"), prim.GetAttribute(
            "xformOp:orient")
        start = np.asarray(prim.GetAttribute("xformOp:translate:start").Get(), dtype=np.float64)
        samples += len(translate.GetTimeSamples()) + len(orient.GetTimeSamples())
        for f in range(FRAMES):
            t[p, f] = start + np.asarray(translate.Get(f), dtype=np.float64)
            o = orient.Get(f)
            q[p, f] = [o.GetReal(), *o.GetImaginary()]
    return t, q, samples


def _usd_within(exact: tuple, reduced: tuple, end: np.ndarray, tol_m: float, tol_deg: float
                ) -> bool:
    live = np.arange(FRAMES)[None] < end[:, None]
    dt = np.linalg.norm(reduced[0] - exact[0], axis=-1)
    da = _angle_deg(reduced[1], exact[1])
    return bool(np.all(dt[live] <= tol_m + SLACK_M) and np.all(da[live] <= tol_deg + SLACK_DEG))


def test_usd_reduced_keys_within_tolerance_at_every_frame(cache: SimCache, tmp_path: Path
                                                           ) -> None:
    export(cache, tmp_path / "exact.usdc", EXACT)
    export(cache, tmp_path / "reduced.usdc")
    exact = _usd_frames(tmp_path / "exact.usdc", cache)
    reduced = _usd_frames(tmp_path / "reduced.usdc", cache)
    end = np.minimum(cache.piece_end_frame, FRAMES)
    assert _usd_within(exact, reduced, end, KEY_TOLERANCE_M, KEY_TOLERANCE_DEG)
    # the exact export already keeps only the ends of rests; spins need fewer keys now
    assert reduced[2] < 0.8 * exact[2], (reduced[2], exact[2])
    # exact at the keys it keeps
    stage = Usd.Stage.Open(str(tmp_path / "reduced.usdc"))
    for prim in stage.Traverse():
        attr = prim.GetAttribute("xformOp:translate")
        if prim.GetName().startswith("piece_") and attr:
            p = int(prim.GetName()[6:])
            start = np.asarray(prim.GetAttribute("xformOp:translate:start").Get())
            for f in attr.GetTimeSamples():
                assert np.array_equal(start + np.asarray(attr.Get(f), dtype=np.float64),
                                      exact[0][p, int(f)])
    # the check has teeth: a key dropped from a moving piece breaks it
    layer = stage.GetRootLayer()
    paths = piece_prim_paths(piece_objects(cache), piece_parts(cache))
    path = max((stage.GetPrimAtPath(p).GetAttribute("xformOp:translate") for p in paths),
               key=lambda a: len(a.GetTimeSamples())).GetPath()
    times = layer.ListTimeSamplesForPath(path)
    layer.EraseTimeSample(path, times[len(times) // 2])
    layer.Export(str(tmp_path / "dropped.usdc"))
    dropped = _usd_frames(tmp_path / "dropped.usdc", cache)
    assert not _usd_within(exact, dropped, end, KEY_TOLERANCE_M, KEY_TOLERANCE_DEG)


# ----------------------------------------------------------------------------- glTF

def _read_glb(path: Path) -> tuple[dict, bytes]:
    data = path.read_bytes()
    json_len = struct.unpack_from("<I", data, 12)[0]
    return json.loads(data[20:20 + json_len]), data[28 + json_len:]


def _accessor(doc: dict, blob: bytes, i: int) -> np.ndarray:
    acc = doc["accessors"][i]
    view = doc["bufferViews"][acc["bufferView"]]
    n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return np.frombuffer(blob, "<f4", acc["count"] * n, start).reshape(acc["count"], n
                                                                       ).astype(np.float64)


def _interpolate(t: np.ndarray, v: np.ndarray, kind: str, at: float, rotation: bool,
                 slerp: bool = True) -> np.ndarray:
    """The glTF specification's sampler interpolation at time ``at``."""
    keys = v[1::3] if kind == "CUBICSPLINE" else v
    t = t.reshape(-1)
    if at <= t[0] or len(t) == 1:
        return keys[0]
    if at >= t[-1]:
        return keys[-1]
    k = int(np.searchsorted(t, at, side="right")) - 1
    td = t[k + 1] - t[k]
    u = (at - t[k]) / td
    if kind == "CUBICSPLINE":
        b_k, a_k1 = v[3 * k + 2], v[3 * (k + 1)]
        out = ((2 * u**3 - 3 * u**2 + 1) * keys[k] + td * (u**3 - 2 * u**2 + u) * b_k
               + (-2 * u**3 + 3 * u**2) * keys[k + 1] + td * (u**3 - u**2) * a_k1)
    elif rotation and slerp:
        a, b = keys[k], keys[k + 1]
        d = float(np.dot(a, b))
        b = -b if d < 0 else b
        theta = np.arccos(min(abs(d), 1.0))
        if theta < 1e-9:
            out = (1 - u) * a + u * b
        else:
            out = (np.sin((1 - u) * theta) * a + np.sin(u * theta) * b) / np.sin(theta)
    else:  # LINEAR; for a rotation without slerp: Blender's per-component F-curves
        out = (1 - u) * keys[k] + u * keys[k + 1]
    return out / np.linalg.norm(out) if rotation else out


def _gltf_frames(path: Path, cache: SimCache, slerp: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, int, dict]:
    doc, blob = _read_glb(path)
    times = cache.frame_time.astype(np.float32).astype(np.float64)
    t = np.zeros((cache.piece_count, FRAMES, 3))
    q = np.zeros((cache.piece_count, FRAMES, 4))
    keys = 0
    anim = doc["animations"][0]
    for channel in anim["channels"]:
        node, what = channel["target"]["node"], channel["target"]["path"]
        if node >= cache.piece_count or what == "scale":
            continue
        sampler = anim["samplers"][channel["sampler"]]
        tin = _accessor(doc, blob, sampler["input"])
        out = _accessor(doc, blob, sampler["output"])
        keys += len(tin)
        target = t if what == "translation" else q
        for f in range(FRAMES):
            target[node, f] = _interpolate(tin, out, sampler["interpolation"], times[f],
                                           what == "rotation", slerp)
    return t, q, keys, doc


def test_gltf_reduced_keys_within_tolerance_at_every_frame(cache: SimCache, tmp_path: Path
                                                            ) -> None:
    export(cache, tmp_path / "exact.glb", EXACT)
    export(cache, tmp_path / "reduced.glb")
    exact = _gltf_frames(tmp_path / "exact.glb", cache)
    end = np.minimum(cache.piece_end_frame, FRAMES)
    for slerp in (True, False):  # the specification's slerp, and Blender's F-curves
        reduced = _gltf_frames(tmp_path / "reduced.glb", cache, slerp)
        assert _usd_within(exact, reduced, end, KEY_TOLERANCE_M, KEY_TOLERANCE_DEG), slerp
    assert reduced[2] < 0.8 * exact[2], (reduced[2], exact[2])
    doc = reduced[3]
    assert {s["interpolation"] for s in doc["animations"][0]["samplers"]} <= {"LINEAR", "STEP"}
    # a dropped key (here: every key of piece 1's rotation but its first and last) is caught
    data = (tmp_path / "reduced.glb").read_bytes()
    rot = next(c for c in doc["animations"][0]["channels"]
               if c["target"] == {"node": 1, "path": "rotation"})
    sampler = doc["animations"][0]["samplers"][rot["sampler"]]
    acc = doc["accessors"][sampler["output"]]
    assert acc["count"] > 2
    tin = doc["accessors"][sampler["input"]]
    # keep the accessor counts but move the first key's value to every other key
    blob_start = len(data) - len(_read_glb(tmp_path / "reduced.glb")[1])
    view = doc["bufferViews"][acc["bufferView"]]
    start = blob_start + view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    broken = bytearray(data)
    for k in range(1, acc["count"] - 1):
        broken[start + 16 * k:start + 16 * k + 16] = data[start:start + 16]
    (tmp_path / "broken.glb").write_bytes(bytes(broken))
    assert tin["count"] == acc["count"]
    bad = _gltf_frames(tmp_path / "broken.glb", cache)
    assert not _usd_within(exact, bad, end, KEY_TOLERANCE_M, KEY_TOLERANCE_DEG)


def test_reduction_is_deterministic(cache: SimCache, tmp_path: Path) -> None:
    for suffix in (".usdc", ".glb"):
        for run in "ab":
            (tmp_path / run).mkdir(exist_ok=True)
            export(cache, tmp_path / run / f"shot{suffix}")
        assert (tmp_path / "a" / f"shot{suffix}").read_bytes() == \
            (tmp_path / "b" / f"shot{suffix}").read_bytes()


def test_reduce_keys_keeps_what_linear_interpolation_needs() -> None:
    """A parabola sampled at 10 frames: linear keys every frame at a 0.1 mm tolerance
    (it misses by g dt^2 / 2 if one is skipped), at 1 cm every other frame; a constant:
    one key; a steady spin: its ends and a few keys between (the normalised lerp)."""
    t = np.arange(10) / 24.0
    arc = np.zeros((1, 10, 3))
    arc[0, :, 2] = 5.0 * t - 4.905 * t**2
    live = np.array([10])
    assert reduce_keys(t, arc, None, live, 1e-4, 0.1).sum() == 10
    assert reduce_keys(t, arc, None, live, 1e-2, 0.1).sum() == 6
    assert reduce_keys(t, np.ones((1, 10, 3)), None, live, 1e-4, 0.1).tolist() == [
        [True] + [False] * 9]
    half = 0.5 * np.radians(30.0) * np.arange(10)  # 30 degrees a frame about z
    spin = np.stack([np.cos(half), 0 * half, 0 * half, np.sin(half)], axis=-1)[None]
    assert np.flatnonzero(reduce_keys(t, None, spin, live, 1e-4, 0.1)[0]).tolist() != []
    keep = reduce_keys(t, None, spin, live, 1e-4, 0.1)[0]
    # slerp is exact, but keys stay within 180 degrees of quaternion (a dot >= 0) and
    # Blender's normalised lerp must be within 0.1 degree too: more than two keys
    assert keep[0] and keep[-1] and keep.sum() < 10


def test_cli_key_tolerance(cache: SimCache, tmp_path: Path) -> None:
    sim = tmp_path / "sim.npz"
    cache.save(sim)
    for args, name in ((["--key-tolerance", "0", "--key-angle-tolerance", "0"], "exact"),
                       ([], "default")):
        result = subprocess.run([sys.executable, "-m", "blastvox", "export", str(sim), "-o",
                                 str(tmp_path / f"{name}.glb"), "-q", *args],
                                capture_output=True, text=True, cwd=ROOT)
        assert result.returncode == 0, result.stderr
    exact, _ = _read_glb(tmp_path / "exact.glb")
    default, _ = _read_glb(tmp_path / "default.glb")
    first = exact["animations"][0]["samplers"][0]
    assert exact["accessors"][first["input"]]["count"] == FRAMES
    assert len(default["accessors"]) != len(exact["accessors"])
    result = subprocess.run([sys.executable, "-m", "blastvox", "export", str(sim), "-o",
                             str(tmp_path / "bad.glb"), "--key-tolerance", "-1"],
                            capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 2 and "key-tolerance" in result.stderr


def test_cli_velocity_primvars(cache: SimCache, tmp_path: Path) -> None:
    sim = tmp_path / "sim.npz"
    cache.save(sim)
    for name, args in (("plain", []), ("lean", ["--no-velocity-primvars"])):
        result = subprocess.run([sys.executable, "-m", "blastvox", "export", str(sim), "-o",
                                 str(tmp_path / f"{name}.usdc"), "-q", *args],
                                capture_output=True, text=True, cwd=ROOT)
        assert result.returncode == 0, result.stderr
    paths = piece_prim_paths(piece_objects(cache), piece_parts(cache))
    stages = [Usd.Stage.Open(str(tmp_path / f"{n}.usdc")) for n in ("plain", "lean")]
    plain, lean = (stage.GetPrimAtPath(paths[0]) for stage in stages)
    assert plain.GetAttribute("primvars:blastvox:velocity").GetTimeSamples()
    assert not lean.GetAttribute("primvars:blastvox:velocity")
    assert not lean.GetAttribute("primvars:blastvox:angularVelocity")
    # the transforms are the same
    for f in range(FRAMES):
        assert plain.GetAttribute("xformOp:translate").Get(f) == \
            lean.GetAttribute("xformOp:translate").Get(f)
