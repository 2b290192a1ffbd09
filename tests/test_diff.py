"""``blastvox diff``: golden-file comparison of .npz, USD and glTF caches within tolerances.

A small real shot (a 1 x 0.5 x 1 m brick wall, 0.25 m voxels, an 80 kg charge 4 m in front
for 0.3 s, so the wall breaks and pieces fly off) is simulated twice: once as the golden
shot and once with the charge moved 0.1 m sideways (the "real change": the same pieces
break off and turn to dust in the same frames, so the files have the same structure,
but the surviving pieces fly differently). Both are exported to .usda, .usdc,
.glb and .gltf. Perturbed copies are made by editing one value in the file's own data: an
npz array rewritten with write_npz, one USD time sample edited through Sdf, one float in
the glTF binary buffer.
"""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from blastvox.cache import SimCache
from blastvox.diff import Difference, DiffError, diff_files
from blastvox.export.api import export
from blastvox.io.npz import META_KEY, write_npz

FORMATS = ("npz", "usda", "usdc", "glb", "gltf")
EXPORTS = ("usda", "usdc", "glb", "gltf")


@pytest.fixture(scope="module")
def shots(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Path]]:
    """{"base"/"moved": {format: path}} plus "model": {"npz": VoxelModel path}."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("diff_shot")
    trimesh.creation.box(extents=(1.0, 0.5, 1.0)).export(tmp / "wall.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "wall.stl", voxel_size=(0.25,) * 3,
                                    material="brick")], VoxelizeSettings(up_axis="Z"))
    model.save(tmp / "model.npz")
    out: dict[str, dict[str, Path]] = {"model": {"npz": tmp / "model.npz"}}
    # "moved": the charge moved, so the debris flies visibly differently; collisions off,
    # as their impact dust would differ between the two and change the exports' layout
    for name, x, kg in (("base", 0.0, 80.0), ("moved", 0.1, 80.0)):
        cache = simulate(model, SimSettings(duration=0.3, fps=24, collisions=False,
                                            charges=(ChargeSpec((x, -4.0, 0.5), kg),)))
        folder = tmp / name
        folder.mkdir()
        out[name] = {"npz": folder / "sim.npz"}
        cache.save(out[name]["npz"])
        for fmt in EXPORTS:
            out[name][fmt] = folder / f"shot.{fmt}"
            export(cache, out[name][fmt])
    base = SimCache.load(out["base"]["npz"])
    moved = SimCache.load(out["moved"]["npz"])
    assert base.piece_count == moved.piece_count
    assert np.array_equal(base.piece_end_frame, moved.piece_end_frame), \
        "the same pieces must vanish in the same frames, so the exports have the same layout"
    assert (base.piece_end_frame == base.frame_count).any(), "some piece must survive"
    assert np.abs(base.piece_position - moved.piece_position).max() > 0.01, \
        "the moved charge must change the motion"
    return out


def run_diff(*args: Any) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "blastvox", "diff", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


def copy_shot(path: Path, folder: Path) -> Path:
    """Copy ``path`` (and a .gltf's .bin, a USD file's textures) into ``folder``; the
    copy's path."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(path, folder / path.name)
    if path.suffix == ".gltf":
        shutil.copy(path.with_suffix(".bin"), folder / path.with_suffix(".bin").name)
    textures = path.parent / f"{path.stem}_textures"
    if path.suffix.startswith(".usd") and textures.is_dir():
        shutil.copytree(textures, folder / textures.name, dirs_exist_ok=True)
    return folder / path.name


# ----------------------------------------------------------------------------- perturbations

def perturb_npz(path: Path, dest: Path, delta: float) -> str:
    """Add ``delta`` to one float64 value (piece_pivot[1, 2]); the array's name."""
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(arrays.pop(META_KEY).tobytes().decode("utf-8"))
    pivot = arrays["piece_pivot"].copy()
    assert pivot.dtype == np.float64
    pivot[1, 2] += delta
    assert pivot[1, 2] != arrays["piece_pivot"][1, 2]
    arrays["piece_pivot"] = pivot
    write_npz(dest, arrays, meta)
    return "piece_pivot"


def perturb_usd(path: Path, dest: Path, delta: float) -> tuple[str, float]:
    """Add ``delta`` to x of one float3 translate time sample (an offset from the piece's
    ``xformOp:translate:start``; not the first); the prim path and the time code."""
    from pxr import Gf, Sdf

    copy = copy_shot(path, dest.parent)
    layer = Sdf.Layer.FindOrOpen(str(copy))
    pieces = [spec.path for obj in layer.GetPrimAtPath("/Shot").nameChildren
              for spec in obj.nameChildren if spec.name.startswith("piece_")]
    for prim in map(str, pieces):
        attr = Sdf.Path(prim + ".xformOp:translate")
        times = layer.ListTimeSamplesForPath(attr)
        if len(times) >= 2:
            t = times[1]
            v = layer.QueryTimeSample(attr, t)
            layer.SetTimeSample(attr, t, Gf.Vec3f(v[0] + delta, v[1], v[2]))
            assert layer.Save()
            return prim, t
    raise AssertionError("no piece with translate samples")


def _glb_chunks(data: bytes) -> tuple[dict[str, Any], int]:
    json_len = struct.unpack_from("<I", data, 12)[0]
    return json.loads(data[20:20 + json_len]), 20 + json_len + 8


def perturb_gltf(path: Path, dest: Path, delta: float) -> tuple[str, int]:
    """Change one float of an animation output (a key after the first) by ``delta`` (a
    small value: float32 moves by 1e-9 only near 0); the sampler's JSON path and the key."""
    copy = copy_shot(path, dest.parent)
    if copy.suffix == ".glb":
        data = bytearray(copy.read_bytes())
        doc, bin_start = _glb_chunks(bytes(data))
    else:
        doc = json.loads(copy.read_text())
        data = bytearray(copy.with_suffix(".bin").read_bytes())
        bin_start = 0
    anim = doc["animations"][0]
    width = {"VEC3": 3, "VEC4": 4}
    for s, sampler in enumerate(anim["samplers"]):
        acc = doc["accessors"][sampler["output"]]
        n = width[acc["type"]]
        view = doc["bufferViews"][acc["bufferView"]]
        base = bin_start + view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        values = np.frombuffer(bytes(data[base:base + acc["count"] * n * 4]), "<f4")
        cubic = sampler["interpolation"] == "CUBICSPLINE"  # (in-tangent, value, out-tangent)
        t_acc = doc["accessors"][sampler["input"]]
        t_base = (bin_start + doc["bufferViews"][t_acc["bufferView"]].get("byteOffset", 0)
                  + t_acc.get("byteOffset", 0))
        times = np.frombuffer(bytes(data[t_base:t_base + t_acc["count"] * 4]), "<f4")
        for i in range(n, len(values)):
            row = i // n
            if cubic and row % 3 != 1:
                continue
            old = values[i]
            new = np.float32(np.float64(old) + delta)
            if abs(float(new) - float(old) - delta) < 0.1 * delta:
                data[base + 4 * i:base + 4 * i + 4] = struct.pack("<f", new)
                target = copy if copy.suffix == ".glb" else copy.with_suffix(".bin")
                target.write_bytes(bytes(data))
                key = row // 3 if cubic else row  # reported as its frame: time x fps
                fps = doc["scenes"][0]["extras"]["fps"]
                return f"animations[0].samplers[{s}].output", round(float(times[key]) * fps)
    raise AssertionError("no float32 animation value that a change of delta moves by delta")


def perturb(fmt: str, shots: dict[str, dict[str, Path]], folder: Path,
            delta: float) -> tuple[Path, str, str]:
    """A perturbed copy of the base shot: (path, what the output names, the frame text)."""
    src = shots["base"][fmt]
    if fmt == "npz":
        dest = folder / "sim.npz"
        folder.mkdir(parents=True, exist_ok=True)
        return dest, perturb_npz(src, dest, delta), ""
    if fmt in ("usda", "usdc"):
        prim, t = perturb_usd(src, folder / src.name, delta)
        return folder / src.name, prim, f"@ frame {int(t)}"
    where, key = perturb_gltf(src, folder / src.name, delta)
    return folder / src.name, where, f"@ frame {key}"


# ----------------------------------------------------------------------------- exit codes

@pytest.mark.parametrize("fmt", FORMATS)
def test_identical_files_exit_0(shots: dict[str, dict[str, Path]], fmt: str,
                                tmp_path: Path) -> None:
    path = shots["base"][fmt]
    result = run_diff(path, path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout == "" and result.stderr == ""
    copy = copy_shot(path, tmp_path / "copy")
    result = run_diff(copy, path, "-v")
    assert (result.returncode, result.stdout.strip()) == (0, "same"), result.stderr


@pytest.mark.parametrize("fmt", FORMATS)
def test_tiny_perturbation_within_default_tolerance(shots: dict[str, dict[str, Path]], fmt: str,
                                                    tmp_path: Path) -> None:
    path, where, frame = perturb(fmt, shots, tmp_path / "perturbed", 1e-9)
    changed = path.with_suffix(".bin") if fmt == "gltf" else path
    original = shots["base"][fmt].with_suffix(changed.suffix)
    assert changed.read_bytes() != original.read_bytes()
    result = run_diff(path, shots["base"][fmt])
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout == ""

    result = run_diff(path, shots["base"][fmt], "--atol", "0", "--rtol", "0")
    assert result.returncode == 1, result.stdout + result.stderr
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1, result.stdout
    assert where in lines[0] and frame in lines[0], lines[0]
    assert "A=" in lines[0] and "B=" in lines[0]


@pytest.mark.parametrize("fmt", FORMATS)
def test_real_change_exit_1_names_path_and_frame(shots: dict[str, dict[str, Path]],
                                                 fmt: str) -> None:
    result = run_diff(shots["base"][fmt], shots["moved"][fmt], "--limit", "200")
    assert result.returncode == 1, result.stdout + result.stderr
    lines = result.stdout.strip().splitlines()
    assert 1 <= len(lines) <= 200
    if fmt == "npz":
        wanted = [ln for ln in lines if ln.startswith("piece_position ")]
        assert any(ln.startswith("charge_position ") for ln in lines), result.stdout
    elif fmt in ("usda", "usdc"):
        wanted = [ln for ln in lines if ln.startswith("/Shot/") and "/piece_" in ln
                  and "xformOp:translate" in ln]
    else:
        wanted = [ln for ln in lines if ln.startswith("animations[0].samplers[")
                  and ".output" in ln]
    assert wanted, result.stdout
    assert all(" @ frame " in ln for ln in wanted), wanted


def test_limit_caps_the_output(shots: dict[str, dict[str, Path]]) -> None:
    result = run_diff(shots["base"]["usda"], shots["moved"]["usda"], "-n", "3")
    assert result.returncode == 1
    assert len(result.stdout.strip().splitlines()) == 3
    assert "--limit" in result.stderr and len(result.stderr.strip().splitlines()) == 1


def _one_line_error(result: subprocess.CompletedProcess[str]) -> str:
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("blastvox: error: "), result.stderr
    return lines[0]


def test_missing_file_exit_2(shots: dict[str, dict[str, Path]], tmp_path: Path) -> None:
    line = _one_line_error(run_diff(shots["base"]["glb"], tmp_path / "nope.glb"))
    assert "nope.glb" in line and "no such file" in line
    line = _one_line_error(run_diff(tmp_path / "nope.npz", shots["base"]["npz"]))
    assert "nope.npz" in line


def test_a_json_that_is_no_gltf_cannot_be_compared(shots: dict[str, dict[str, Path]],
                                                    tmp_path: Path) -> None:
    """'{}' named .gltf has no asset.version: exit 2 (it was "same" against itself)."""
    empty = tmp_path / "empty.gltf"
    empty.write_text("{}")
    for other in (empty, shots["base"]["gltf"]):
        line = _one_line_error(run_diff(empty, other))
        assert "empty.gltf" in line and "asset.version" in line


@pytest.mark.parametrize(("a", "b"), [("glb", "usda"), ("npz", "gltf"), ("usdc", "npz")])
def test_different_kinds_exit_2(shots: dict[str, dict[str, Path]], a: str, b: str) -> None:
    line = _one_line_error(run_diff(shots["base"][a], shots["base"][b]))
    assert "different kinds" in line


def test_model_vs_cache_exit_2(shots: dict[str, dict[str, Path]]) -> None:
    line = _one_line_error(run_diff(shots["model"]["npz"], shots["base"]["npz"]))
    assert "VoxelModel" in line and "SimCache" in line


@pytest.mark.parametrize("fmt", FORMATS)
def test_unreadable_file_exit_2(shots: dict[str, dict[str, Path]], fmt: str,
                                tmp_path: Path) -> None:
    bad = tmp_path / f"bad.{fmt}"
    data = shots["base"][fmt].read_bytes()
    bad.write_bytes(data[:len(data) // 3])
    line = _one_line_error(run_diff(bad, shots["base"][fmt]))
    assert "bad." in line


def test_unknown_suffix_exit_2(shots: dict[str, dict[str, Path]], tmp_path: Path) -> None:
    other = tmp_path / "mesh.obj"
    other.write_text("v 0 0 0\n")
    line = _one_line_error(run_diff(other, shots["base"]["npz"]))
    assert "unknown format" in line


def test_negative_tolerance_exit_2(shots: dict[str, dict[str, Path]]) -> None:
    path = shots["base"]["npz"]
    _one_line_error(run_diff(path, path, "--atol", "-1"))


# ----------------------------------------------------------------------------- library

def test_usda_equals_usdc_and_glb_equals_gltf(shots: dict[str, dict[str, Path]]) -> None:
    assert diff_files(shots["base"]["usda"], shots["base"]["usdc"]) == []
    assert diff_files(shots["base"]["glb"], shots["base"]["gltf"]) == []


def test_difference_fields_and_format(shots: dict[str, dict[str, Path]], tmp_path: Path) -> None:
    path, prim, frame = perturb("usdc", shots, tmp_path / "p", 1e-3)
    diffs = diff_files(path, shots["base"]["usdc"])
    assert len(diffs) == 1
    d = diffs[0]
    assert isinstance(d, Difference)
    assert (d.path, d.attribute) == (prim, "xformOp:translate")
    assert d.frame == float(frame.split()[-1])
    assert len(d.value_a) == 3 and len(d.value_b) == 3
    assert abs(d.value_a[0] - d.value_b[0] - 1e-3) < 1e-6  # float3: within its spacing
    line = d.format()
    assert "\n" not in line and prim in line and frame in line


def test_npz_difference_names_array_and_frame(shots: dict[str, dict[str, Path]],
                                              tmp_path: Path) -> None:
    with np.load(shots["base"]["npz"], allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(arrays.pop(META_KEY).tobytes().decode("utf-8"))
    position = arrays["piece_position"].copy()
    position[4, 2, 1] += 0.5
    arrays["piece_position"] = position
    meta["tool_version"] = "99.0"  # ignored
    write_npz(tmp_path / "sim.npz", arrays, meta)
    diffs = diff_files(tmp_path / "sim.npz", shots["base"]["npz"])
    assert len(diffs) == 1
    d = diffs[0]
    assert (d.path, d.frame) == ("piece_position", 4)
    assert "[2, 1]" in d.note
    assert d.value_a[1] == pytest.approx(d.value_b[1] + 0.5)


def test_limit_and_tolerances(shots: dict[str, dict[str, Path]]) -> None:
    a, b = shots["base"]["glb"], shots["moved"]["glb"]
    assert len(diff_files(a, b, limit=2)) == 2
    everything = diff_files(a, b, limit=None)
    assert len(everything) > 2
    assert diff_files(a, b, atol=1e3, rtol=0.0, limit=None) == []


def test_library_errors_are_exit_code_2(shots: dict[str, dict[str, Path]],
                                        tmp_path: Path) -> None:
    with pytest.raises(DiffError) as info:
        diff_files(tmp_path / "missing.usda", shots["base"]["usda"])
    assert info.value.exit_code == 2
    with pytest.raises(DiffError):
        diff_files(shots["base"]["glb"], shots["base"]["npz"])
    with pytest.raises(DiffError):
        diff_files(shots["base"]["npz"], shots["base"]["npz"], atol=-1.0)


def test_a_usd_s_texture_is_compared_by_content(shots: dict[str, dict[str, Path]],
                                                tmp_path: Path) -> None:
    """Two USD files naming the same damage texture differ when the PNG beside one of them
    changed or is missing (the look of every fracture face; diff said "same")."""
    base = shots["base"]["usdc"]
    copies = [copy_shot(base, tmp_path / name) for name in ("a", "b")]
    assert run_diff(*copies).returncode == 0
    texture = next((tmp_path / "b" / f"{base.stem}_textures").glob("*.png"))
    texture.write_bytes(texture.read_bytes() + b"\0")
    result = run_diff(*copies)
    assert result.returncode == 1 and "asset content" in result.stdout, result.stdout
    texture.unlink()
    result = run_diff(*copies)
    assert result.returncode == 1 and 'B="missing"' in result.stdout, result.stdout
