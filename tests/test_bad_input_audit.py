"""No file outside the folders the user named is opened (issue 36, "Done when").

Every reference class (an OBJ's mtllib and its textures, a .gltf's buffers and
images, a USD layer's sublayers, references, payloads and textures) points, in
each way the policy refuses (``../``, an absolute path, a symlink out of the
folder), at files in a folder the user never named. The commands run in one child
process with an audit hook (``sys.addaudithook``) recording every ``open`` and
directory listing Python makes; none may touch that folder, refused or not. USD
opens files in C++, where no audit hook sees: ``diff`` of USD files is watched
with strace instead (skipped where strace cannot run).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import trimesh

ROOT = Path(__file__).resolve().parents[1]

#: Runs each (cwd, argv) of the JSON list in argv[1] through the CLI's entry point
#: under an audit hook; prints, per command, its exit code and the paths it opened.
CHILD = r"""
import contextlib, io, json, os, sys

cases = json.loads(sys.argv[1])
seen = []

def hook(event, args):
    if event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
        seen.append(os.path.abspath(os.fsdecode(args[0])))
    elif event in ("os.listdir", "os.scandir") and args and args[0] is not None \
            and not isinstance(args[0], int):
        seen.append(os.path.abspath(os.fsdecode(args[0])))

from blastvox.cli.entry import run
import blastvox.cli.app  # noqa: imports before the hook counts
sys.addaudithook(hook)
report = []
for cwd, argv in cases:
    os.chdir(cwd)
    seen.clear()
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = run(argv)
    report.append({"argv": argv, "code": code, "stderr": err.getvalue(), "opened": list(seen)})
sys.stdout.write(json.dumps(report))
"""


def _obj(folder: Path, mtllib: str) -> None:
    box = trimesh.creation.box(extents=(1.0, 0.5, 1.0))
    (folder / "box.obj").write_text(f"mtllib {mtllib}\nusemtl skin\n"
                                    + trimesh.exchange.obj.export_obj(box,
                                                                      include_texture=False))


def _gltf(folder: Path, name: str, buffer: str | None = None, image: str | None = None) -> None:
    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh.creation.box()))
    doc = json.loads(files.pop("model.gltf"))
    for other, content in files.items():
        (folder / other).write_bytes(content)
    if buffer is not None:
        doc["buffers"][0]["uri"] = buffer
    if image is not None:
        doc["images"] = [{"uri": image}]
    (folder / name).write_text(json.dumps(doc))


@pytest.fixture
def folders(tmp_path: Path) -> tuple[Path, Path]:
    """(the folder the user names, a secret folder beside it that references point to)."""
    shot, secret = tmp_path / "shot", tmp_path / "secret"
    shot.mkdir()
    secret.mkdir()
    (secret / "box.mtl").write_text("newmtl skin\nKd 1 0 0\nmap_Kd skin.png\n")
    from PIL import Image

    Image.new("RGB", (4, 4), (9, 9, 9)).save(secret / "skin.png")
    _gltf(secret, "other.gltf")  # its gltf_buffer_*.bin are real buffers
    (secret / "layer.usda").write_text('#usda 1.0\ndef Xform "World" {}\n')
    return shot, secret


def _cases(shot: Path, secret: Path) -> list[tuple[str, list[str]]]:
    """Folders under ``shot``, each referring to ``secret`` one way, and the commands
    that read them."""
    cases: list[tuple[str, list[str]]] = []
    scene = ('[[objects]]\nmesh = "{mesh}"\nvoxel_size = 0.25\n[[charges]]\n'
             'position = [0, -2, 0.5]\nmass_kg = 1\n[simulation]\nduration = 0.05\n'
             '[output]\nmodel = "o/m.npz"\ncache = "o/s.npz"\n')
    ways = {
        "obj-mtllib-up": ("box.obj", lambda f: _obj(f, "../../secret/box.mtl")),
        "obj-mtllib-absolute": ("box.obj", lambda f: _obj(f, str(secret / "box.mtl"))),
        "obj-mtllib-symlink": ("box.obj", lambda f: (_obj(f, "box.mtl"), os.symlink(
            secret / "box.mtl", f / "box.mtl"))),
        "obj-texture-up": ("box.obj", lambda f: (_obj(f, "box.mtl"), (f / "box.mtl").write_text(
            "newmtl skin\nmap_Kd ../../secret/skin.png\n"))),
        "gltf-buffer-up": ("box.gltf", lambda f: _gltf(f, "box.gltf",
                                                       buffer="../../secret/gltf_buffer_0.bin")),
        "gltf-buffer-absolute": ("box.gltf", lambda f: _gltf(
            f, "box.gltf", buffer=str(secret / "gltf_buffer_0.bin"))),
        "gltf-image-up": ("box.gltf", lambda f: _gltf(f, "box.gltf",
                                                      image="../../secret/skin.png")),
    }
    for name, (mesh, make) in ways.items():
        folder = shot / name
        folder.mkdir()
        make(folder)
        (folder / "scene.toml").write_text(scene.format(mesh=mesh))
        cases += [(str(folder), ["voxelize", mesh, "-o", "m.npz", "--voxel-size", "0.25",
                                 "-q"]),
                  (str(folder), ["run", "scene.toml", "-q"]),
                  (str(folder), ["wedge", "scene.toml", "--vary", "seed=0,1", "--dry-run"])]
        if "buffer" in name:  # diff reads a .gltf's buffers (not its images)
            _gltf(folder, "a.gltf")
            cases.append((str(folder), ["diff", "a.gltf", mesh]))
    return cases


def test_no_reference_opens_a_file_outside_the_named_folders(folders) -> None:
    shot, secret = folders
    cases = _cases(shot, secret)
    done = subprocess.run([sys.executable, "-c", CHILD, json.dumps(cases)], cwd=shot,
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout)
    assert len(report) == len(cases)
    inside = str(secret.resolve()) + os.sep
    for case in report:
        if case["argv"][0] != "wedge":  # wedge --dry-run lists the shots, their keys
            assert case["code"] != 0, case  # made without what the policy refuses
            assert len(case["stderr"].strip().splitlines()) == 1, case
        touched = [p for p in case["opened"]
                   if (p + os.sep).startswith(inside) or os.path.realpath(p).startswith(inside)]
        assert not touched, (case["argv"], case["stderr"], touched)
        # and the folder named is where it read: the command did open something there
        assert any(p.startswith(str(shot)) for p in case["opened"]), case["argv"]


USD_WAYS = {
    "sublayer-up": ('subLayers = [@../../secret/layer.usda@]', "", ""),
    "reference-absolute": ("", "references = @{secret}/layer.usda@", ""),
    "payload-up": ("", "payload = @../../secret/layer.usda@", ""),
    "texture-up": ("", "", "    asset inputs:file = @../../secret/skin.png@\n"),
    "sublayer-symlink": ("subLayers = [@link.usda@]", "", ""),
}


@pytest.mark.skipif(shutil.which("strace") is None, reason="strace is not installed")
def test_usd_diff_opens_nothing_outside_in_cpp_either(folders) -> None:
    shot, secret = folders
    probe = subprocess.run(["strace", "-f", "-e", "trace=openat", "true"],
                           capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"strace cannot trace here ({probe.stderr.strip()[:80]})")
    for name, (layer_meta, prim_meta, body) in USD_WAYS.items():
        folder = shot / name
        folder.mkdir()
        head = f"#usda 1.0\n(\n    {layer_meta}\n)\n" if layer_meta else "#usda 1.0\n"
        meta = f" (\n    {prim_meta.format(secret=secret)}\n)" if prim_meta else ""
        (folder / "b.usda").write_text(head + f'def Xform "World"{meta}\n{{\n{body}}}\n')
        (folder / "a.usda").write_text('#usda 1.0\ndef Xform "World" {}\n')
        if name.endswith("symlink"):
            os.symlink(secret / "layer.usda", folder / "link.usda")
        log = folder / "strace.log"
        done = subprocess.run(["strace", "-f", "-qq", "-e", "trace=open,openat,openat2", "-o",
                               str(log), sys.executable, "-m", "blastvox", "diff", "a.usda",
                               "b.usda"], cwd=folder, capture_output=True, text=True,
                              timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert done.returncode == 2, (name, done.stderr[-2000:])
        assert len(done.stderr.strip().splitlines()) == 1, (name, done.stderr)
        opened = [line for line in log.read_text().splitlines() if str(secret) in line]
        assert not opened, (name, opened)
