"""Multi-part assets: touching parts held by weaker links (part_bond), per-object anchoring.

A glTF with two boxes as separate nodes, touching face to face, voxelizes into one
object whose links between the boxes carry ``part_bond`` times the material's
strength. Under gravity a block held to a founded wall by a weak part bond falls
off (the stress solver breaks the bond), and held by a weld it stays. An object
with ``anchored = false`` has no foundations: it stands on the ground as a free
body. Bad values are one line naming the flag or key.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.model import VoxelModel
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

SIZE = 0.25  # m


def _two_boxes(path: Path) -> Path:
    """A founded wall (1 x 1 x 2 m, on z = 0) and a 0.5 m block on its side at the top,
    as two glTF nodes that touch on the plane x = 0.5."""
    wall = trimesh.creation.box(extents=(1.0, 1.0, 2.0))
    wall.apply_translation((0.0, 0.0, 1.0))
    block = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    block.apply_translation((0.75, 0.0, 1.75))
    scene = trimesh.Scene()
    scene.add_geometry(wall, node_name="wall", geom_name="wall")
    scene.add_geometry(block, node_name="block", geom_name="block")
    scene.export(path)
    return path


def _model(path: Path, part_bond: float = 1.0, anchored: bool = True) -> VoxelModel:
    return voxelize([ObjectRequest(mesh=path, voxel_size=(SIZE,) * 3, material="concrete",
                                   chunk_size=0.0, part_bond=part_bond, anchored=anchored)],
                    VoxelizeSettings(up_axis="Z", ground=0.0))


@pytest.fixture(scope="module")
def mesh(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _two_boxes(tmp_path_factory.mktemp("parts") / "parts.glb")


def _ratios(model: VoxelModel) -> tuple[np.ndarray, np.ndarray]:
    """Link yield over the material mean, for links across the two boxes and inside one."""
    a = model.arrays
    lv = a["link_voxels"]
    ratio = a["link_yield"] / a["material_link_yield_mean"][a["voxel_material"][lv[:, 0]]]
    x = a["voxel_centroid"][:, 0]
    across = (x[lv[:, 0]] < 0.5) != (x[lv[:, 1]] < 0.5)
    return ratio[across], ratio[~across]


def test_touching_parts_are_one_object_held_by_part_bond_links(mesh: Path) -> None:
    welded = _model(mesh)
    assert len(welded.meta["objects"]) == 1  # the parts touch: one connected object
    across, inside = _ratios(welded)
    assert len(across) == 4  # the block's 2 x 2 voxel face on the wall
    rel = float(welded.arrays["material_link_yield_var"][0]
                / welded.arrays["material_link_yield_mean"][0])
    for ratios in (across, inside):
        assert np.all((ratios >= 1 - rel - 1e-12) & (ratios <= 1 + rel + 1e-12))
    weak_across, weak_inside = _ratios(_model(mesh, part_bond=0.2))
    np.testing.assert_allclose(weak_across, 0.2 * across)  # same seed: same perturbation
    np.testing.assert_array_equal(weak_inside, inside)


@pytest.mark.parametrize(("part_bond", "falls"), [(1.0, False), (1e-4, True)])
def test_a_weak_part_bond_lets_the_block_fall_off(mesh: Path, part_bond: float,
                                                  falls: bool) -> None:
    """Gravity alone: 300 kg hanging on 0.25 m^2 of concrete (12 kPa of shear) holds when
    welded (concrete's shear strength is MPa) and tears off at 1e-4 of it."""
    cache = simulate(_model(mesh, part_bond=part_bond),
                     SimSettings(duration=1.0, fps=10.0, charges=()))
    block = cache.model.arrays["voxel_centroid"][:, 0] > 0.5
    piece = np.unique(cache.voxel_piece[block])
    drop = cache.piece_position[0, piece, 2] - cache.piece_position[-1, piece, 2]
    if falls:
        assert drop.min() > 1.0, drop  # fell most of the 1.5 m to the ground
    else:
        assert np.abs(drop).max() < 0.02, drop
        assert cache.piece_count == 1


@pytest.mark.parametrize("anchored", [True, False])
def test_anchoring_is_a_per_object_choice(mesh: Path, anchored: bool) -> None:
    model = _model(mesh, anchored=anchored)
    founded = model.arrays["voxel_foundation"]
    bottom = model.arrays["voxel_centroid"][:, 2] < SIZE
    if anchored:
        assert founded[bottom].all() and not founded[~bottom].any()
    else:
        assert not founded.any()
    cache = simulate(model, SimSettings(duration=1.0, fps=10.0, charges=()))
    moved = np.abs(cache.piece_position[-1] - cache.piece_position[0]).max()
    assert moved < 0.02  # a free body standing on its base stays where it stands


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "blastvox", *args], capture_output=True,
                          text=True, timeout=120)


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf"])
def test_a_bad_part_bond_is_one_line(mesh: Path, tmp_path: Path, value: str) -> None:
    out = tmp_path / "m.npz"
    done = _cli("voxelize", str(mesh), "-o", str(out), "--part-bond", value)
    assert done.returncode in (1, 2), done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "--part-bond" in lines[0], done.stderr
    assert not out.exists()


def test_scene_keys_reach_the_model(mesh: Path, tmp_path: Path) -> None:
    scene = tmp_path / "scene.toml"
    scene.write_text(f'up_axis = "Z"\nground = 0.0\n[[objects]]\nmesh = "{mesh}"\n'
                     f"voxel_size = {SIZE}\nchunk_size = 0.0\npart_bond = 0.5\n"
                     "anchored = false\n[output]\nmodel = \"m.npz\"\n")
    done = _cli("voxelize", "--scene", str(scene), "-q")
    assert done.returncode == 0, done.stderr
    model = VoxelModel.load(tmp_path / "m.npz")
    assert not model.arrays["voxel_foundation"].any()
    assert model.meta["settings"]["objects"][0]["part_bond"] == 0.5
    scene.write_text(scene.read_text().replace("part_bond = 0.5", "part_bond = -2"))
    done = _cli("voxelize", "--scene", str(scene), "-q")
    assert done.returncode == 1
    assert "objects[0].part_bond" in done.stderr and len(done.stderr.strip().splitlines()) == 1
