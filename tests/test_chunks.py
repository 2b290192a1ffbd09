"""Chunks (issue 17, item 3): voxelize groups voxels into irregular chunks whose inner
links are stronger, so fracture runs along chunk boundaries.

The chunk ids are valid and deterministic, every chunk is connected through its
links and holds one material of one object, the mean chunk volume follows the chunk
size, chunk size 0 (or a material's below one voxel) leaves every voxel alone and
the link yields untouched, inner links are scaled by exactly chunk_bond_scale, and
a chunk size below one voxel or above the object is refused in one line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from bad_input import assert_clean_failure, run_blastvox, unchanged
from shapes import standing_box

from blastvox.errors import ContractError
from blastvox.materials import MaterialLibrary
from blastvox.model import VoxelModel
from blastvox.voxelize.chunks import statistics
from blastvox.voxelize.components import component_labels
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize
from blastvox.voxelize.regions import RegionRule


@pytest.fixture(scope="module")
def wall(tmp_path_factory) -> Path:
    """A 4 x 0.4 x 3 m wall standing on z = 0 (4,800 voxels of 0.1 m)."""
    return standing_box(tmp_path_factory.mktemp("chunks") / "wall.stl", (4.0, 0.4, 3.0))


def _model(mesh: Path, chunk_size: float | None = None, seed: int = 0,
           library: MaterialLibrary | None = None, rules: list | None = None,
           voxel_size: float = 0.1, jitter: float = 0.2) -> VoxelModel:
    request = ObjectRequest(mesh=mesh, voxel_size=(voxel_size,) * 3, jitter=jitter,
                            chunk_size=chunk_size, rules=rules or [])
    settings = VoxelizeSettings(up_axis="Z", seed=seed,
                                library=library or MaterialLibrary.builtin())
    return voxelize([request], settings)


def _inside(model: VoxelModel) -> np.ndarray:
    chunk, links = model.voxel_chunk, model.link_voxels
    return chunk[links[:, 0]] == chunk[links[:, 1]]


def test_chunk_ids_are_valid_and_deterministic(wall):
    first, again, other = _model(wall, 0.5), _model(wall, 0.5), _model(wall, 0.5, seed=7)
    chunk = first.voxel_chunk
    assert chunk.dtype == np.int32 and chunk.shape == (first.voxel_count,)
    count = int(chunk.max()) + 1
    assert set(np.unique(chunk).tolist()) == set(range(count))
    # numbered in order of their lowest voxel
    _, lowest = np.unique(chunk, return_index=True)
    assert np.all(np.diff(lowest) > 0)
    assert np.array_equal(chunk, again.voxel_chunk)
    assert np.array_equal(first.link_yield, again.link_yield)
    assert not np.array_equal(chunk, other.voxel_chunk)
    assert first.summary()["chunk_count"] == count


def test_every_chunk_is_connected_through_its_links(wall):
    model = _model(wall, 0.3)
    inside = _inside(model)
    parts = component_labels(model.link_voxels[inside], model.voxel_count)
    pairs = np.unique(np.stack([model.voxel_chunk, parts], axis=1), axis=0)
    assert len(pairs) == int(model.voxel_chunk.max()) + 1  # one component per chunk


@pytest.mark.parametrize("size", [0.3, 0.5, 0.8])
def test_the_mean_chunk_volume_follows_the_chunk_size(wall, size):
    model = _model(wall, size)
    stats = statistics(model.voxel_chunk, model.voxel_volume)
    assert stats["mean_volume_m3"] == pytest.approx(size**3, rel=0.3), stats
    assert stats["voxels_per_chunk"] > 1


def test_chunk_size_zero_leaves_every_voxel_alone_and_the_yields_untouched(wall):
    plain = _model(wall, 0.0)
    assert np.array_equal(plain.voxel_chunk, np.arange(plain.voxel_count))
    # a bond scale of 1 changes nothing either: the link yields are the unchunked ones
    library = MaterialLibrary.builtin().extended(
        {"concrete": {"chunk_bond_scale": 1.0}}, "test")
    unscaled = _model(wall, 0.5, library=library)
    assert int(unscaled.voxel_chunk.max()) + 1 < unscaled.voxel_count
    assert np.array_equal(plain.link_yield, unscaled.link_yield)
    assert np.array_equal(plain.voxel_yield, unscaled.voxel_yield)


def test_inner_links_are_scaled_by_exactly_the_bond_scale(wall):
    plain, chunked = _model(wall, 0.0), _model(wall, 0.5)
    scale = MaterialLibrary.builtin()["concrete"].chunk_bond_scale
    assert scale > 1.0
    inside = _inside(chunked)
    assert inside.any() and (~inside).any()
    assert np.array_equal(chunked.link_yield[inside], plain.link_yield[inside] * scale)
    assert np.array_equal(chunked.link_yield[~inside], plain.link_yield[~inside])


def test_a_material_chunk_size_below_one_voxel_means_single_voxel_chunks(wall):
    model = _model(wall, None, voxel_size=0.2)  # concrete's 0.5 m: chunks
    assert int(model.voxel_chunk.max()) + 1 < model.voxel_count
    library = MaterialLibrary.builtin().extended({"concrete": {"chunk_size": 0.15}}, "test")
    alone = _model(wall, None, voxel_size=0.2, library=library)  # no error
    assert np.array_equal(alone.voxel_chunk, np.arange(alone.voxel_count))


def test_chunks_keep_to_one_material_one_object_and_the_rules(tmp_path):
    # two blocks 0.3 m apart in one file: two objects
    left = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    right = left.copy()
    right.apply_translation((1.3, 0.0, 0.0))
    path = tmp_path / "blocks.stl"
    trimesh.util.concatenate([left, right]).export(path)
    rules = [RegionRule("halfspace", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), material="plaster"),
             RegionRule("box", (0.8, -1.0, -1.0), (2.0, 1.0, 1.0), chunk_size=0.0)]
    model = _model(path, 0.4, rules=rules)
    chunk = model.voxel_chunk
    for array in (model.voxel_object, model.voxel_material):
        assert len(np.unique(np.stack([chunk, array], axis=1), axis=0)) == int(chunk.max()) + 1
    # the right block lies in the chunk_size = 0 rule's box: every voxel alone
    right_block = model.voxel_centroid[:, 0] > 0.8
    assert len(np.unique(chunk[right_block])) == int(right_block.sum())
    assert len(np.unique(chunk[~right_block])) < int((~right_block).sum())


def test_a_file_without_chunks_loads_and_bad_ids_are_refused(wall, tmp_path):
    model = _model(wall, 0.5, jitter=0.0)
    model.save(tmp_path / "model.npz")
    with np.load(tmp_path / "model.npz", allow_pickle=False) as z:
        arrays = {k: z[k].copy() for k in z.files}
    older = {k: v for k, v in arrays.items() if k != "voxel_chunk"}
    np.savez(tmp_path / "older.npz", **older)
    loaded = VoxelModel.load(tmp_path / "older.npz")
    assert "voxel_chunk" not in loaded.arrays
    assert loaded.summary()["chunk_count"] == loaded.voxel_count
    for value, words in ((-1, "negative chunk index"), (model.voxel_count, "refers to chunk")):
        bad = dict(arrays)
        bad["voxel_chunk"] = arrays["voxel_chunk"].copy()
        bad["voxel_chunk"][3] = value
        np.savez(tmp_path / "bad.npz", **bad)
        with pytest.raises(ContractError, match=words):
            VoxelModel.load(tmp_path / "bad.npz")
    bad = dict(arrays, voxel_chunk=arrays["voxel_chunk"].astype(np.int64))
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(ContractError, match="voxel_chunk"):
        VoxelModel.load(tmp_path / "bad.npz")


# ----------------------------------------------------------------------- bad input


@pytest.fixture
def cube(tmp_path: Path) -> Path:
    """A closed 1 m cube standing on z = 0, as OBJ."""
    mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    mesh.apply_translation((0.0, 0.0, 0.5))
    path = tmp_path / "cube.obj"
    mesh.export(path)
    return path


def _refused(tmp_path: Path, args: tuple, names: list[str], inputs: list[Path],
             words: tuple[str, ...] = ()) -> str:
    with unchanged(tmp_path, inputs):
        outcome = run_blastvox(*args, cwd=tmp_path)
    line = assert_clean_failure(outcome, names, words=words, seconds=30)
    assert outcome.stdout == ""
    return line


@pytest.mark.parametrize(("value", "words"), [
    ("0.05", ("0.05 m is below one voxel (0.2 m)",)),
    ("1.5", ("1.5 m is above the object's largest extent (1 m)",)),
    ("nan", ("finite",)),
    ("-0.1", (">= 0",)),
])
def test_a_bad_chunk_size_flag_is_refused(tmp_path, cube, value, words):
    _refused(tmp_path, ("voxelize", "cube.obj", "-o", "m.npz", "--voxel-size", "0.2",
                        f"--chunk-size={value}", "-q"),
             ["cube.obj", "--chunk-size"], [cube], words=words)


@pytest.mark.parametrize(("text", "key", "words"), [
    ("chunk_size = 0.05", "objects[0].chunk_size", ("0.05 m is below one voxel (0.2 m)",)),
    ("chunk_size = 3.0", "objects[0].chunk_size", ("above the object's largest extent",)),
    ("chunk_size = -1.0", "objects[0].chunk_size", (">= 0",)),
    ("[[objects.rules]]\nbox = { min = [0, 0, 0], max = [1, 1, 1] }\nchunk_size = 0.1",
     "objects[0].rules[0].chunk_size", ("0.1 m is below one voxel (0.2 m)",)),
])
def test_a_bad_chunk_size_in_a_scene_is_refused(tmp_path, cube, text, key, words):
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[[objects]]\nmesh = "cube.obj"\nvoxel_size = 0.2\n{text}\n'
                     f'[output]\nmodel = "out/model.npz"\n')
    _refused(tmp_path, ("voxelize", "--scene", "scene.toml", "-q"),
             ["scene.toml", key], [cube, scene], words=words)


def test_chunk_size_flag_with_a_scene_is_refused(tmp_path, cube):
    scene = tmp_path / "scene.toml"
    scene.write_text('[[objects]]\nmesh = "cube.obj"\n[output]\nmodel = "m.npz"\n')
    _refused(tmp_path, ("voxelize", "--scene", "scene.toml", "--chunk-size", "0.5", "-q"),
             ["scene.toml", "--chunk-size"], [cube, scene], words=("per object",))


def test_chunk_size_from_the_command_line_and_a_scene(tmp_path, cube):
    assert run_blastvox("voxelize", "cube.obj", "-o", "flag.npz", "--voxel-size", "0.1",
                        "--chunk-size", "0.5", "-q", cwd=tmp_path).code == 0
    (tmp_path / "scene.toml").write_text(
        '[[objects]]\nmesh = "cube.obj"\nvoxel_size = 0.1\nchunk_size = 0.5\n'
        '[output]\nmodel = "scene.npz"\n')
    assert run_blastvox("voxelize", "--scene", "scene.toml", "-q", cwd=tmp_path).code == 0
    flag, scene = (VoxelModel.load(tmp_path / name) for name in ("flag.npz", "scene.npz"))
    assert np.array_equal(flag.voxel_chunk, scene.voxel_chunk)
    assert 4 <= int(flag.voxel_chunk.max()) + 1 <= 12  # about 1 / 0.5^3 = 8


@pytest.mark.parametrize("extents,size", [((0.2, 0.2, 3.0), 0.5), ((0.1, 0.1, 6.0), 0.4),
                                          ((3.0, 0.2, 0.2), 0.5)])
def test_a_slender_region_gets_chunks_about_chunk_size_long(tmp_path, extents, size):
    """By volume alone a 3 m column 0.2 m across (0.12 m^3 < 0.5^3) was one chunk, which
    a crushing material never breaks: a slender region gets round(L / size) chunks, each
    far shorter than the whole, and its volume term still rules a bulky one."""
    mesh = standing_box(tmp_path / "column.stl", extents)
    model = _model(mesh, size, voxel_size=0.05, jitter=0.0)
    length = max(extents)
    axis = int(np.argmax(extents))
    chunk, along = model.voxel_chunk, model.voxel_centroid[:, axis]
    assert int(chunk.max()) + 1 == round(length / size)
    spans = [np.ptp(along[chunk == c]) for c in range(int(chunk.max()) + 1)]
    assert max(spans) < 0.5 * length, spans


def test_a_blast_breaks_a_concrete_column_into_its_chunks(tmp_path):
    """The sweep's column: 0.2 x 0.2 x 3 m of concrete, 5 kg of TNT 1 m from its axis
    (reflected pressure about 21 MPa). It left as one intact piece; now the blast breaks
    the links between its chunks."""
    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings

    mesh = standing_box(tmp_path / "column.stl", (0.2, 0.2, 3.0))
    model = voxelize([ObjectRequest(mesh=mesh, voxel_size=(0.1,) * 3, material="concrete")],
                     VoxelizeSettings(up_axis="Z", ground="auto"))
    assert model.summary()["chunk_count"] >= 5
    cache = simulate(model, SimSettings(duration=0.1, charges=(ChargeSpec((1.0, 0.0, 1.5),
                                                                          5.0),)))
    assert cache.meta["broken_links"] > 0
    assert cache.piece_position.shape[1] >= 3
