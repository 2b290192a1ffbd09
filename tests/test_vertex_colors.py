"""Vertex and face colours (issue 16, item 1: PLY colours) become a baked texture.

The input is an icosphere written as PLY by trimesh, red above its equator and
blue below (per vertex), read back through the same loader as any PLY. The bake
must hold each triangle's corner colours exactly at the corners' UVs; the model
must carry the texture; the outside faces of the voxelized ball, sampled in that
texture at their exported UVs, must be red on top and blue underneath.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from blastvox.export.pieces import piece_meshes
from blastvox.export.uv import face_uvs
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize
from blastvox.voxelize.vertex_colors import bake, corner_colors

RED, BLUE = (220, 30, 20, 255), (20, 40, 230, 255)


def colored_ball(path: Path) -> Path:
    """A unit icosphere (centre 0) as PLY: red vertices above z = 0, blue below."""
    ball = trimesh.creation.icosphere(subdivisions=2)
    colors = np.where((ball.vertices[:, 2] > 0)[:, None], RED, BLUE).astype(np.uint8)
    ball.visual = trimesh.visual.ColorVisuals(ball, vertex_colors=colors)
    ball.export(path)
    return path


def _sample(png: bytes, uv: np.ndarray) -> np.ndarray:
    """Nearest texels (..., 4) of ``png`` at ``uv`` (..., 2), v up."""
    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))
    height, width = image.shape[:2]
    x = np.clip((uv[..., 0] * width).astype(int), 0, width - 1)
    y = np.clip(((1.0 - uv[..., 1]) * height).astype(int), 0, height - 1)
    return image[y, x]


def test_the_bake_holds_each_corner_s_colour_at_its_uv() -> None:
    rng = np.random.default_rng(3)
    corners = rng.integers(0, 256, (50, 3, 4), dtype=np.uint8)
    corners[..., 3] = 255
    uv, png = bake(corners)
    assert uv.shape == (50, 3, 2) and (uv > 0).all() and (uv < 1).all()
    assert np.array_equal(_sample(png, uv), corners)
    assert Image.open(io.BytesIO(png)).mode == "RGB"  # opaque: no alpha channel
    assert bake(corners)[1] == png  # byte-deterministic
    corners[0, 0, 3] = 128
    assert Image.open(io.BytesIO(bake(corners)[1])).mode == "RGBA"


def test_one_colour_for_everything_is_no_look_and_face_colours_fill_their_triangle() -> None:
    box = trimesh.creation.box()
    assert corner_colors(box.visual, box.faces) is None  # trimesh's default: no colours
    box.visual = trimesh.visual.ColorVisuals(box, vertex_colors=np.tile(RED, (8, 1)))
    assert corner_colors(box.visual, box.faces) is None  # one colour: nothing to bake
    faces = np.tile(BLUE, (12, 1)).astype(np.uint8)
    faces[0] = RED
    box.visual = trimesh.visual.ColorVisuals(box, face_colors=faces)
    corners = corner_colors(box.visual, box.faces)
    assert corners.shape == (12, 3, 4)
    assert (corners[0] == RED).all() and (corners[1:] == BLUE).all()


@pytest.fixture(scope="module")
def ball(tmp_path_factory: pytest.TempPathFactory):
    tmp = tmp_path_factory.mktemp("colors")
    model = voxelize([ObjectRequest(mesh=colored_ball(tmp / "ball.ply"),
                                    voxel_size=(0.25,) * 3, shape="conform",
                                    material="concrete")], VoxelizeSettings(up_axis="Z"))
    return model, simulate(model, SimSettings(duration=0.05, fps=20.0, charges=()))


def test_a_coloured_ply_keeps_its_colours_on_the_pieces(ball) -> None:
    model, cache = ball
    assert [t["name"] for t in model.textures] == ["ball_0"]
    meshes = piece_meshes(cache, "Z")
    look = face_uvs(cache, meshes)
    outside = ~meshes.damage
    assert (look.texture[outside] == 0).all()
    colors = _sample(model.texture_file(0), look.uv).astype(float)  # (T, 3, 4)
    height = meshes.rest[..., 2] - np.mean(model.arrays["surface_triangles"][..., 2])
    top = outside & (height.min(axis=1) > 0.3)
    bottom = outside & (height.max(axis=1) < -0.3)
    assert top.sum() > 20 and bottom.sum() > 20
    assert np.abs(colors[top] - RED).max() <= 2
    assert np.abs(colors[bottom] - BLUE).max() <= 2


def test_the_same_ply_gives_the_same_model(ball, tmp_path: Path) -> None:
    model, _ = ball
    again = voxelize([ObjectRequest(mesh=colored_ball(tmp_path / "ball.ply"),
                                    voxel_size=(0.25,) * 3, shape="conform",
                                    material="concrete")], VoxelizeSettings(up_axis="Z"))
    assert again.texture_file(0) == model.texture_file(0)
    for name in ("surface_uv", "surface_triangles", "voxel_centroid"):
        assert np.array_equal(again.arrays[name], model.arrays[name]), name
