"""Files that point elsewhere (issue 36): what a mesh refers to is read under one
policy (blastvox.io.references): regular files only, inside the mesh's folder unless
``--references-anywhere``, never a device, a FIFO or a URL, size-capped. A refusal
is one line naming the mesh, the reference and the rule; nothing hangs, nothing is
written. Both ``voxelize`` and the shot keys of ``run``/``wedge`` hold to it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import trimesh
from bad_input import assert_clean_failure, run_blastvox

from blastvox.io.references import ReferencePolicy, ReferenceRefused
from blastvox.io.resources import mesh_resources


def _obj(folder: Path, mtllib: str, texture: str | None = None) -> Path:
    """A textured box OBJ in ``folder`` naming ``mtllib``; with ``texture``, a box.mtl
    beside it that names it (so ``mtllib`` should be box.mtl)."""
    box = trimesh.creation.box(extents=(1.0, 0.5, 1.0))
    path = folder / "box.obj"
    path.write_text(f"mtllib {mtllib}\nusemtl skin\n"
                    + trimesh.exchange.obj.export_obj(box, include_texture=False))
    if texture is not None:
        (folder / "box.mtl").write_text(f"newmtl skin\nKd 1 1 1\nmap_Kd {texture}\n")
    return path


def _voxelize(folder: Path, *extra: str):
    return run_blastvox("voxelize", "box.obj", "-o", "m.npz", "--voxel-size", "0.25",
                        "-q", *extra, cwd=folder)


@pytest.mark.parametrize("mtllib, words", [
    ("/dev/zero", ["/dev/zero", "not a regular file"]),
    ("../outside.mtl", ["outside.mtl", "outside the folder", "--references-anywhere"]),
    ("http://example.com/box.mtl", ["http://example.com/box.mtl", "URL"]),
])
def test_an_obj_whose_mtllib_points_elsewhere_is_refused(tmp_path, mtllib, words):
    """`mtllib /dev/zero` read until 4 GB of RSS; `../outside.mtl` and a URL were
    followed. Each is refused in one line naming the OBJ and the reference."""
    work = tmp_path / "shot"
    work.mkdir()
    (tmp_path / "outside.mtl").write_text("newmtl skin\nKd 1 0 0\n")
    _obj(work, mtllib)
    outcome = _voxelize(work)
    assert_clean_failure(outcome, ["box.obj"], words=words, seconds=30.0)
    assert not (work / "m.npz").exists()


def test_an_mtllib_that_is_a_fifo_does_not_hang(tmp_path):
    """An OBJ whose `mtllib` is a FIFO hung voxelize for 60 s+ (and Ctrl-C then exited
    0 with the output written): refused at once, before anything opens it."""
    _obj(tmp_path, "box.mtl")
    os.mkfifo(tmp_path / "box.mtl")
    outcome = _voxelize(tmp_path)
    assert_clean_failure(outcome, ["box.obj", "box.mtl"], words=["FIFO"], seconds=30.0)
    assert not (tmp_path / "m.npz").exists()


def test_a_texture_outside_the_folder_is_refused_unless_allowed(tmp_path):
    """An MTL's `map_Kd ../../etc/passwd`-style texture outside the mesh's folder is
    refused; --references-anywhere reads it (a real PNG there is used)."""
    work = tmp_path / "shot"
    work.mkdir()
    from PIL import Image

    Image.new("RGB", (4, 4), (200, 30, 30)).save(tmp_path / "skin.png")
    _obj(work, "box.mtl", "../skin.png")
    outcome = _voxelize(work)
    assert_clean_failure(outcome, ["box.obj", "skin.png"], words=["outside the folder"])
    assert _voxelize(work, "--references-anywhere").code == 0
    assert (work / "m.npz").is_file()


def test_a_symlink_to_a_device_is_refused(tmp_path):
    """A texture that is a symlink to /dev/zero, inside the folder, is judged by what
    it points to."""
    os.symlink("/dev/zero", tmp_path / "skin.png")
    _obj(tmp_path, "box.mtl", "skin.png")
    outcome = _voxelize(tmp_path)
    assert_clean_failure(outcome, ["box.obj", "skin.png"], words=["not a regular file"])


def test_a_missing_texture_still_only_warns(tmp_path):
    """A texture that is simply not there is the loader's to skip (the part keeps its
    base colour, with a warning), as before: not a refusal."""
    _obj(tmp_path, "box.mtl", "gone.png")
    assert _voxelize(tmp_path).code == 0


def test_shot_keys_do_not_read_what_the_policy_refuses(tmp_path):
    """run's staleness check and wedge's shot keys list a mesh's side files: a FIFO or
    a file outside the folder is left out, never opened (wedge --dry-run opened an
    MTL's `map_Kd ../../etc/passwd` to hash it)."""
    work = tmp_path / "shot"
    work.mkdir()
    (tmp_path / "secret.png").write_bytes(b"not yours")
    mesh = _obj(work, "box.mtl", "../secret.png")
    assert mesh_resources(mesh) == [mesh, work / "box.mtl"]
    (work / "box.mtl").unlink()
    os.mkfifo(work / "box.mtl")
    assert mesh_resources(mesh) == [mesh]


def test_the_policy_caps_the_size_before_reading(tmp_path):
    """A reference larger than the cap is refused from its size, unread."""
    (tmp_path / "big.bin").write_bytes(b"\0" * 2048)
    policy = ReferencePolicy(max_bytes=1024)
    with pytest.raises(ReferenceRefused, match="2,048 bytes"):
        policy.read(tmp_path / "scene.gltf", "big.bin")
    assert ReferencePolicy().read(tmp_path / "scene.gltf", "big.bin") == b"\0" * 2048


@pytest.mark.parametrize("uri, words", [
    ("/dev/zero", ["/dev/zero", "not a regular file"]),
    ("../../etc/passwd", ["../../etc/passwd", "outside the folder"]),
    ("https://example.com/box.bin", ["https://example.com/box.bin", "URL"]),
])
def test_a_gltf_whose_buffer_points_elsewhere_is_refused(tmp_path, uri, words):
    """A .gltf buffer uri /dev/zero, ../../etc/passwd or a URL: one line, exit 1."""
    import json

    trimesh.creation.box().export(tmp_path / "box.gltf")
    doc = json.loads((tmp_path / "box.gltf").read_text())
    doc["buffers"][0]["uri"] = uri
    (tmp_path / "box.gltf").write_text(json.dumps(doc))
    outcome = run_blastvox("voxelize", "box.gltf", "-o", "m.npz", "--voxel-size", "0.25",
                           "-q", cwd=tmp_path)
    assert_clean_failure(outcome, ["box.gltf"], words=words, seconds=30.0)
    assert not (tmp_path / "m.npz").exists()


@pytest.mark.parametrize("uri, words", [
    ("../../etc/passwd", ["outside the folder"]),
    ("/dev/zero", ["not a regular file"]),
])
def test_diff_of_a_gltf_does_not_read_what_its_buffers_point_at(tmp_path, uri, words):
    """`blastvox diff` of a .gltf whose buffer uri was ../../etc/passwd printed that file's
    bytes as accessor values; /dev/zero read until MemoryError. Now: one line naming the
    file, the reference and the rule, exit 2 (files that could not be compared)."""
    import json

    trimesh.creation.box().export(tmp_path / "a.gltf")
    doc = json.loads((tmp_path / "a.gltf").read_text())
    doc["buffers"][0]["uri"] = uri
    (tmp_path / "b.gltf").write_text(json.dumps(doc))
    outcome = run_blastvox("diff", "a.gltf", "b.gltf", cwd=tmp_path)
    assert outcome.code == 2, outcome.stderr
    lines = outcome.stderr.strip().splitlines()
    assert len(lines) == 1 and "b.gltf" in lines[0] and uri in lines[0], lines
    for word in words:
        assert word in lines[0], lines


def test_run_takes_references_anywhere_too(tmp_path):
    """The refusal names --references-anywhere; `run` takes it (it had no such flag), and
    then counts the texture outside among the voxelize stage's inputs."""
    work = tmp_path / "shot"
    work.mkdir()
    from PIL import Image

    Image.new("RGB", (4, 4), (200, 30, 30)).save(tmp_path / "skin.png")
    _obj(work, "box.mtl", "../skin.png")
    (work / "scene.toml").write_text(
        '[[objects]]\nmesh = "box.obj"\nvoxel_size = 0.25\n[[charges]]\n'
        'position = [0, -2, 0.5]\nmass_kg = 1\n[simulation]\nduration = 0.05\n'
        '[output]\nmodel = "o/m.npz"\ncache = "o/s.npz"\n')
    outcome = run_blastvox("run", "scene.toml", "-q", cwd=work)
    assert_clean_failure(outcome, ["box.obj", "skin.png", "--references-anywhere"],
                         words=["outside the folder"])
    assert run_blastvox("run", "scene.toml", "-q", "--references-anywhere", cwd=work).code == 0
    again = run_blastvox("run", "scene.toml", "--references-anywhere", cwd=work)
    assert "up to date" in again.stderr
    os.utime(tmp_path / "skin.png", (2e9, 2e9))  # the texture outside changed
    again = run_blastvox("run", "scene.toml", "--references-anywhere", cwd=work)
    assert "voxelize" in again.stderr, again.stderr


def _scene(folder: Path, mesh: str, model: str = "o/m.npz") -> None:
    """A one-object scene in ``folder`` naming ``mesh`` (TOML escapes allowed) and
    writing its model to ``model``."""
    (folder / "scene.toml").write_text(
        f'[[objects]]\nmesh = "{mesh}"\nvoxel_size = 0.25\n[[charges]]\n'
        'position = [0, -2, 0.5]\nmass_kg = 1\n[simulation]\nduration = 0.05\n'
        f'[output]\nmodel = "{model}"\ncache = "o/s.npz"\n')


def test_a_symlink_loop_or_a_nul_in_a_reference_is_one_line(tmp_path):
    """Found by a probe of hostile references (2026-11-29): an MTL or glTF buffer
    reference that is a symlink loop, or holds a NUL, ended `run` in a traceback
    (RuntimeError, ValueError from Path.resolve); voxelize too for a loop given on the
    command line. Each is now one line naming the file that refers to it."""
    _obj(tmp_path, "loop.mtl")
    os.symlink("loop.mtl", tmp_path / "loop.mtl")
    _scene(tmp_path, "box.obj")
    outcome = run_blastvox("run", "scene.toml", "-q", cwd=tmp_path)
    assert_clean_failure(outcome, ["box.obj", "loop.mtl"], words=["cannot be followed"])
    _obj(tmp_path, "bo\x00x.mtl")
    outcome = run_blastvox("run", "scene.toml", "-q", cwd=tmp_path)
    assert_clean_failure(outcome, ["box.obj"], words=["NUL"])
    os.symlink("itself.obj", tmp_path / "itself.obj")
    outcome = run_blastvox("voxelize", "itself.obj", "-o", "m.npz", "--voxel-size", "0.25",
                           "-q", cwd=tmp_path)
    assert_clean_failure(outcome, ["itself.obj"], words=["symbolic links"])
    assert not (tmp_path / "m.npz").exists() and not (tmp_path / "o").exists()


def test_a_nul_in_a_scenes_mesh_or_output_is_one_line(tmp_path):
    """A NUL in a scene's mesh path or [output] model ended in a ValueError traceback
    (os.stat: embedded null byte)."""
    _obj(tmp_path, "box.mtl")
    _scene(tmp_path, "bo\\u0000x.obj")
    outcome = run_blastvox("run", "scene.toml", "-q", cwd=tmp_path)
    assert_clean_failure(outcome, ["bo\\x00x.obj"], words=["not a valid file name"])
    _scene(tmp_path, "box.obj", model="o/m\\u0000.npz")
    outcome = run_blastvox("run", "scene.toml", "-q", cwd=tmp_path)
    assert_clean_failure(outcome, ["m\\x00.npz", "output.model"], words=["not a valid"])
    assert not (tmp_path / "o").exists()


def test_a_gltf_nested_past_the_stack_is_one_line(tmp_path):
    """A .gltf of 200,000 nested JSON arrays: run's staleness check ended in a
    RecursionError traceback (voxelize already refused it in one line)."""
    (tmp_path / "deep.gltf").write_text("[" * 200_000 + "]" * 200_000)
    _scene(tmp_path, "deep.gltf")
    outcome = run_blastvox("run", "scene.toml", "-q", cwd=tmp_path)
    assert_clean_failure(outcome, ["deep.gltf"])


def test_a_very_long_reference_is_named_with_its_mesh_and_shortened(tmp_path):
    """A 5,000-character mtllib gave a 5,041-character error naming only the MTL: the
    line now names the OBJ, the rule, and the reference cut to its ends."""
    _obj(tmp_path, "m" * 5000 + ".mtl")
    line = assert_clean_failure(_voxelize(tmp_path), ["box.obj", "..."],
                                words=["File name too long"])
    assert len(line) < 400, len(line)


def _png_header(width: int, height: int) -> bytes:
    """A PNG's signature, IHDR chunk (CRC right) claiming width x height RGB pixels,
    and IEND: no pixels."""
    import zlib

    body = b"IHDR" + width.to_bytes(4, "big") + height.to_bytes(4, "big") + b"\x08\x02\0\0\0"
    return (b"\x89PNG\r\n\x1a\n" + (13).to_bytes(4, "big") + body
            + zlib.crc32(body).to_bytes(4, "big")
            + b"\0\0\0\0IEND" + zlib.crc32(b"IEND").to_bytes(4, "big"))


@pytest.mark.parametrize("texture, words", [
    (b"a text file, not an image", ["not an image format"]),
    (_png_header(20000, 20000), ["pixels"]),  # 1.2 GB once inflated
])
def test_an_undecodable_texture_warns_as_a_missing_one_does(tmp_path, texture, words):
    """A texture that is there but that no image reader decodes (a text file named .png,
    a 20,000 x 20,000 PNG) was dropped without a word (exit 0, the asset untextured):
    it warns, naming the mesh, the texture and why, as a missing texture does."""
    _obj(tmp_path, "box.mtl", "skin.png")
    (tmp_path / "skin.png").write_bytes(texture)
    outcome = _voxelize(tmp_path)
    assert outcome.code == 0, outcome.stderr
    lines = [line for line in outcome.stderr.splitlines() if "skin.png" in line]
    assert len(lines) == 1 and "box.obj" in lines[0] and "warning" in lines[0], outcome.stderr
    for word in words:
        assert word in lines[0], lines


def test_names_print_whatever_the_file_systems_encoding(tmp_path):
    """Under `LC_ALL=C PYTHONUTF8=0` Python encodes file names as ASCII: a scene naming
    a Cyrillic mesh ended in a UnicodeEncodeError traceback inside `printable`."""
    import subprocess
    import sys

    _scene(tmp_path, "дом.obj")
    env = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0",
           "PYTHONIOENCODING": ""}
    done = subprocess.run([sys.executable, "-m", "blastvox", "run", "scene.toml", "-q"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
                          errors="replace")
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert "scene.toml" in lines[0] or ".obj" in lines[0], lines


def test_a_percent_encoded_gltf_uri_names_the_file_it_encodes(tmp_path):
    """glTF URIs are RFC 3986: Blender writes `my%20skin.png` for `my skin.png`. The URI
    was read as written, so a .gltf whose buffer or texture has a space in its name lost
    it. Now the decoded name is read (and counted among run's inputs); a URI that still
    escapes the folder once decoded is refused as before."""
    import json

    trimesh.creation.box().export(tmp_path / "box.gltf")
    doc = json.loads((tmp_path / "box.gltf").read_text())
    uri = doc["buffers"][0]["uri"]
    (tmp_path / uri).rename(tmp_path / "my buffer.bin")
    doc["buffers"][0]["uri"] = "my%20buffer.bin"
    (tmp_path / "box.gltf").write_text(json.dumps(doc))
    outcome = run_blastvox("voxelize", "box.gltf", "-o", "m.npz", "--voxel-size", "0.25",
                           "-q", cwd=tmp_path)
    assert outcome.code == 0, outcome.stderr
    assert tmp_path / "my buffer.bin" in mesh_resources(tmp_path / "box.gltf")
    doc["buffers"][0]["uri"] = "%2E%2E/%2E%2E/etc/passwd"
    (tmp_path / "box.gltf").write_text(json.dumps(doc))
    outcome = run_blastvox("voxelize", "box.gltf", "-o", "m2.npz", "--voxel-size", "0.25",
                           "-q", cwd=tmp_path)
    assert_clean_failure(outcome, ["box.gltf"], words=["outside the folder"])
    assert not (tmp_path / "m2.npz").exists()
