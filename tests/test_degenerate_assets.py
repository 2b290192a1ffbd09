"""A real asset's defects through the whole shot, as an artist runs it: the CLI in a
subprocess, what it prints checked line by line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import trimesh


def test_zero_area_faces_export_without_library_warnings(data_dir: Path,
                                                         tmp_path: Path) -> None:
    # wallhole.obj has 11 zero-area faces (and names an .mtl that is not there): the
    # source look's barycentric coordinates divided by their zero areas, and numpy's
    # RuntimeWarnings reached the artist's terminal
    mesh = trimesh.load(data_dir / "wallhole.obj", force="mesh")
    assert (mesh.area_faces == 0.0).sum() > 0
    (tmp_path / "scene.toml").write_text(
        f'up_axis = "Y"\nground = "auto"\n[[objects]]\nmesh = "{data_dir / "wallhole.obj"}"\n'
        'voxel_size = 0.5\nmaterial = "brick"\n'
        '[[charges]]\nposition = [5, 5, 5]\nmass_kg = 4.0\n'
        '[simulation]\nduration = 0.5\n'
        '[output]\nmodel = "model.npz"\ncache = "sim.npz"\nexport = ["shot.glb", "shot.usdc"]\n')
    done = subprocess.run([sys.executable, "-m", "blastvox", "run", "scene.toml"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    for word in ("Warning", "site-packages", "Traceback"):  # blastvox's own lines only
        assert word not in done.stderr, done.stderr
    glb = trimesh.load(tmp_path / "shot.glb", force="scene")
    assert all(np.isfinite(g.vertices).all() for g in glb.geometry.values())
