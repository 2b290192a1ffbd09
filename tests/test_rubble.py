"""Rubble, not voxel soup (issue 17, item 3): a brick wall breached by a close charge.

A 3 x 0.3 x 2.5 m brick wall of 0.1 m voxels, founded on the ground, with TNT 1.5 m
in front of its face. Pressure-impulse fracture frees chunks along their boundaries;
a chunk of a material that crushes (brick: crush_pressure 7 MPa) comes apart only
as dust, and neither the blast nor a landing breaks it into voxels. So:

- at 5, 10 and 20 kg the wall is breached, at most half of the moving pieces are
  single voxels, and at least half of the volume that left the wall (dust included)
  is in pieces of 8 voxels or more;
- the pieces follow the scene's chunk size: larger chunks, fewer and larger pieces;
- dust is where the face pressure passes brick's crushing pressure, not everywhere
  the wave's impulse is large: 5 kg crushes nothing, 20 kg a central part.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from shapes import standing_box

from blastvox.cache import moved_pieces
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

CHUNKY_VOXELS = 8  #: the issue's "pieces of 8 voxels or more"


@pytest.fixture(scope="module")
def wall(tmp_path_factory) -> Path:
    return standing_box(tmp_path_factory.mktemp("rubble") / "wall.obj", (3.0, 0.3, 2.5))


def _shot(wall: Path, kg: float, chunk_size: float | None = None) -> dict:
    """Breach the wall; what moved: pieces (their voxel counts), dust and volumes."""
    model = voxelize([ObjectRequest(mesh=wall, voxel_size=(0.1,) * 3, material="brick",
                                    chunk_size=chunk_size)],
                     VoxelizeSettings(up_axis="Z", ground="auto", seed=1))
    cache = simulate(model, SimSettings(duration=1.5, seed=1, charges=(
        ChargeSpec((0.0, -1.65, 1.0), kg),)))
    a = cache.arrays
    volume = model.arrays["voxel_volume"].astype(np.float64)
    dust = a["voxel_destroyed_frame"] >= 0
    piece = a["voxel_piece"]
    size = np.bincount(piece[~dust], minlength=len(a["piece_mass"]))
    piece_volume = np.bincount(piece[~dust], weights=volume[~dust],
                               minlength=len(a["piece_mass"]))
    flying = moved_pieces(a) & (size > 0)
    moved_volume = piece_volume[flying].sum() + volume[dust].sum()
    return {"sizes": size[flying], "single": float(np.mean(size[flying] == 1)),
            "chunky": float(piece_volume[flying & (size >= CHUNKY_VOXELS)].sum()
                            / moved_volume),
            "moved": float(moved_volume / volume.sum()), "dust": int(dust.sum())}


@pytest.mark.parametrize("kg", [5.0, 10.0, 20.0])
def test_a_breached_brick_wall_throws_rubble_not_voxel_soup(wall, kg):
    shot = _shot(wall, kg)
    assert shot["moved"] > 0.5, shot  # breached: most of the wall leaves
    assert len(shot["sizes"]) >= 10, shot  # in many pieces, not one slab
    assert shot["single"] <= 0.5, shot
    assert shot["chunky"] >= 0.5, shot


def test_dust_is_where_the_face_pressure_crushes_brick(wall):
    assert _shot(wall, 5.0)["dust"] == 0  # 5 kg: nowhere above 7 MPa that long
    dust = _shot(wall, 20.0)["dust"]
    assert 0 < dust < 0.6 * 2250  # 20 kg: the middle of the wall, not all of it


def test_the_pieces_follow_the_scene_chunk_size(wall):
    sizes = [_shot(wall, 10.0, chunk_size)["sizes"] for chunk_size in (0.25, 0.4, 0.7)]
    counts = [len(s) for s in sizes]
    means = [float(s.mean()) for s in sizes]
    assert counts[0] > counts[1] > counts[2], counts
    assert means[0] < means[1] < means[2], means
