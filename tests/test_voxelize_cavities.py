"""Voxelize keeps sealed cavities hollow and merges conform slivers (issue 17, item 4).

A closed 6 x 6 x 3 m bunker with 0.5 m walls is one mesh of two shells, the
outer box and the cavity's box; its solid volume is 6*6*3 - 5*5*2 = 58 m^3. The
cavity shell may be authored facing inward (correct), facing outward (a common
defect), or the whole mesh may be inverted: all three voxelize to the same
hollow solid. Conform slivers (cells the surface barely grazes) are merged into
a neighbour, conserving volume, mass, centroid and inertia exactly.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.geometry.voxel_faces import FACE_OFFSETS
from blastvox.model import VoxelModel, check_model
from blastvox.voxelize.mass import soup_mass_properties
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize
from blastvox.voxelize.shells import nesting_depth, orient_shells, shell_labels, signed_volumes
from blastvox.voxelize.slivers import MIN_CONFORM_FRACTION

DATA = Path(__file__).parent / "data"
BUNKER_VOLUME = 6.0 * 6.0 * 3.0 - 5.0 * 5.0 * 2.0  # m^3
OUTER = (np.zeros(3), np.array([6.0, 6.0, 3.0]))
INNER = (np.array([0.5, 0.5, 0.5]), np.array([5.5, 5.5, 2.5]))


def _box(lo, hi) -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=np.asarray(hi) - np.asarray(lo))
    box.apply_translation(0.5 * (np.asarray(lo) + np.asarray(hi)))
    return box


def bunker(tmp_path: Path, variant: str, extra: list[trimesh.Trimesh] = ()) -> Path:
    """The bunker as one STL: cavity normals "inward" (correct), "outward" (the defect),
    or the whole correct mesh "inverted"."""
    outer, inner = _box(*OUTER), _box(*INNER)
    if variant != "outward":
        inner.invert()
    mesh = trimesh.util.concatenate([outer, inner, *extra])
    if variant == "inverted":
        mesh.invert()
    path = tmp_path / f"bunker_{variant}.stl"
    mesh.export(path)
    return path


def run(path: Path, fraction: float = MIN_CONFORM_FRACTION, warn=None, **kw) -> VoxelModel:
    model = voxelize([ObjectRequest(mesh=path, **kw)],
                     VoxelizeSettings(up_axis="Z", min_conform_fraction=fraction), warn=warn)
    check_model("model.npz", model.arrays, model.meta)
    return model


def expected_cells(model: VoxelModel, size: float) -> set[tuple[int, int, int]]:
    """Lattice cells whose centre lies in the bunker's walls (analytic)."""
    origin = np.asarray(model.meta["objects"][0]["lattice_origin_m"])
    counts = np.ceil((OUTER[1] - origin) / size).astype(int) + 1
    ijk = np.stack(np.meshgrid(*(np.arange(c) for c in counts), indexing="ij"), -1).reshape(-1, 3)
    centre = origin + (ijk + 0.5) * size
    in_outer = np.all((centre > OUTER[0]) & (centre < OUTER[1]), axis=1)
    in_inner = np.all((centre > INNER[0]) & (centre < INNER[1]), axis=1)
    return set(map(tuple, ijk[in_outer & ~in_inner].tolist()))


@pytest.mark.parametrize("variant", ["inward", "outward", "inverted"])
@pytest.mark.parametrize("size", [0.25, 0.5, 0.45])  # 0.45: walls off the lattice
def test_bunker_cavity_stays_hollow(tmp_path, variant, size):
    model = run(bunker(tmp_path, variant), voxel_size=(size,) * 3)
    want = expected_cells(model, size)
    assert set(map(tuple, model.voxel_ijk.tolist())) == want  # walls full, cavity empty
    volume = model.voxel_volume.sum()
    assert volume == pytest.approx(len(want) * size ** 3, rel=1e-9)
    assert volume == pytest.approx(BUNKER_VOLUME, rel=0.10)
    assert len(model.meta["objects"]) == 1


@pytest.mark.parametrize("variant", ["inward", "outward"])
def test_conform_bunker_keeps_its_cavity(tmp_path, variant):
    model = run(bunker(tmp_path, variant), voxel_size=(0.35,) * 3, shape="conform")
    assert model.voxel_volume.sum() == pytest.approx(BUNKER_VOLUME, rel=1e-9)
    centroid = model.voxel_centroid
    assert not np.any(np.all((centroid > INNER[0]) & (centroid < INNER[1]), axis=1))
    # the cavity's surface is conform surface, facing into the cavity
    tri = model.conform_triangles[model.conform_tag == 6]
    centre = tri.mean(axis=1)
    on_cavity = np.all((centre > INNER[0] - 1e-9) & (centre < INNER[1] + 1e-9), axis=1)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    mid = 0.5 * (INNER[0] + INNER[1])
    assert on_cavity.any()
    assert np.all(np.einsum("ij,ij->i", normal[on_cavity], mid - centre[on_cavity]) > 0)


def test_a_block_inside_the_cavity_is_solid_again(tmp_path):
    # nesting depth 2: a 1 m cube floating in the cavity, authored inward-facing
    block = _box((2.5, 2.5, 1.0), (3.5, 3.5, 2.0))
    block.invert()
    model = run(bunker(tmp_path, "outward", [block]), voxel_size=(0.25,) * 3)
    assert model.voxel_volume.sum() == pytest.approx(BUNKER_VOLUME + 1.0, rel=1e-9)
    assert len(model.meta["objects"]) == 2  # the block does not touch the walls


def test_shell_orientation_follows_nesting():
    outer, inner, block, apart = (_box(*OUTER), _box(*INNER),
                                  _box((2.5, 2.5, 1.0), (3.5, 3.5, 2.0)),
                                  _box((10.0, 0.0, 0.0), (11.0, 1.0, 1.0)))
    apart.invert()  # a separate body, inside out
    mesh = trimesh.util.concatenate([outer, inner, block, apart])
    done = orient_shells(mesh)
    labels = shell_labels(mesh)
    count = int(labels.max()) + 1
    volume = signed_volumes(np.asarray(mesh.triangles), labels, count)
    depth = nesting_depth(np.asarray(mesh.triangles), labels, count)
    assert sorted(depth.tolist()) == [0, 0, 1, 2]
    assert np.all(np.sign(volume) == np.where(depth % 2 == 0, 1.0, -1.0))
    assert mesh.volume == pytest.approx(BUNKER_VOLUME + 2.0)
    assert done == ["turned 1 inverted shell(s) outward", "turned 1 cavity shell(s) inward"]
    assert orient_shells(mesh) == []  # idempotent


def test_multibody_and_plain_meshes_are_unchanged(tmp_path):
    model = run(DATA / "multibody.stl", resolution=24)
    assert len(model.meta["objects"]) == 2
    # both bodies in one part, each inside out: the same voxels
    bodies = list(trimesh.load(DATA / "multibody.stl").geometry.values())
    for body in bodies:
        body.invert()
    trimesh.util.concatenate(bodies).export(tmp_path / "inverted.stl")
    again = run(tmp_path / "inverted.stl", resolution=24)
    assert len(again.meta["objects"]) == 2
    np.testing.assert_array_equal(again.voxel_ijk, model.voxel_ijk)
    np.testing.assert_allclose(again.voxel_volume, model.voxel_volume, rtol=1e-6)  # float32 STL
    box = tmp_path / "box.stl"
    _box((0, 0, 0), (2.0, 1.0, 1.5)).export(box)
    cube = run(box, voxel_size=(0.25,) * 3)
    assert cube.voxel_count == 8 * 4 * 6
    assert cube.voxel_volume.sum() == pytest.approx(3.0, rel=1e-12)


def _ball(tmp_path: Path) -> Path:
    ball = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    ball.apply_translation((0.03, -0.07, 1.0))
    path = tmp_path / "ball.stl"
    ball.export(path)
    return path


def _inertia_about(model: VoxelModel, point: np.ndarray) -> np.ndarray:
    """Total inertia tensor (3, 3) kg m^2 of the model about ``point``."""
    d = model.voxel_centroid - point
    m = model.voxel_mass
    shift = (np.einsum("ij,ij->i", d, d)[:, None, None] * np.eye(3)
             - d[:, :, None] * d[:, None, :]) * m[:, None, None]
    return (model.voxel_inertia + shift).sum(axis=0)


def test_conform_slivers_merge_into_neighbours(tmp_path):
    path = _ball(tmp_path)
    size = 0.25
    cell = size ** 3
    raw = run(path, fraction=0.0, voxel_size=(size,) * 3, shape="conform")
    merged = run(path, voxel_size=(size,) * 3, shape="conform")
    assert np.count_nonzero(raw.voxel_volume < 0.02 * cell) >= 8  # the clip makes slivers
    assert merged.voxel_volume.min() >= MIN_CONFORM_FRACTION * cell
    assert merged.voxel_count < raw.voxel_count
    # volume, mass, centre of mass and inertia conserved
    mesh_volume = trimesh.load(path).volume
    assert merged.voxel_volume.sum() == pytest.approx(raw.voxel_volume.sum(), rel=1e-9)
    assert merged.voxel_volume.sum() == pytest.approx(mesh_volume, rel=1e-9)
    assert merged.voxel_mass.sum() == pytest.approx(raw.voxel_mass.sum(), rel=1e-9)
    com = (raw.voxel_mass[:, None] * raw.voxel_centroid).sum(0) / raw.voxel_mass.sum()
    com2 = (merged.voxel_mass[:, None] * merged.voxel_centroid).sum(0) / merged.voxel_mass.sum()
    np.testing.assert_allclose(com2, com, atol=1e-9)
    np.testing.assert_allclose(_inertia_about(merged, com), _inertia_about(raw, com),
                               rtol=1e-9, atol=1e-9 * np.abs(_inertia_about(raw, com)).max())
    # each merged voxel's triangles still close its volume: faces between members are gone
    volume, _, _ = soup_mass_properties(merged.conform_triangles, merged.conform_offsets)
    np.testing.assert_allclose(volume, merged.voxel_volume[merged.conform_voxels], rtol=1e-9)
    area = np.linalg.norm(np.cross(merged.conform_triangles[:, 1] - merged.conform_triangles[:, 0],
                                   merged.conform_triangles[:, 2] - merged.conform_triangles[:, 0]),
                          axis=1).sum()
    area_raw = np.linalg.norm(np.cross(raw.conform_triangles[:, 1] - raw.conform_triangles[:, 0],
                                       raw.conform_triangles[:, 2] - raw.conform_triangles[:, 0]),
                              axis=1).sum()
    assert area < area_raw  # shared faces between members removed
    # a cell-face triangle faces its tag's direction, also those of absorbed members
    tri, tags = merged.conform_triangles, merged.conform_tag
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    on_face = tags < 6
    along = np.einsum("ij,ij->i", normal[on_face], FACE_OFFSETS[tags[on_face]])
    np.testing.assert_allclose(along, np.linalg.norm(normal[on_face], axis=1), rtol=1e-6)
    # the intact object exposes just the mesh's surface: no contact lost a link
    owner = np.repeat(merged.conform_voxels, np.diff(merged.conform_offsets))
    exposed = ~on_face
    exposed[on_face] = (merged.voxel_boundary[owner[on_face]] >> tags[on_face]) & 1 == 1
    half_area = 0.5 * np.linalg.norm(normal, axis=1)
    assert half_area[exposed].sum() == pytest.approx(trimesh.load(path).area, rel=1e-6)
    # the ball still stands on its foundation, and is one object
    assert len(merged.meta["objects"]) == 1
    assert merged.arrays["voxel_foundation"].any()
    # every voxel is linked to the rest
    linked = np.zeros(merged.voxel_count, dtype=bool)
    linked[merged.link_voxels.ravel()] = True
    assert linked.all()


def test_a_lone_sliver_is_dropped_and_reported(tmp_path):
    crumb = _box((3.0, 0.0, 0.0), (3.05, 0.05, 0.05))  # 1.25e-4 m^3, 0.8 % of a cell
    mesh = trimesh.util.concatenate([_box((0, 0, 0), (1.0, 1.0, 1.0)), crumb])
    path = tmp_path / "crumb.stl"
    mesh.export(path)
    warnings: list[str] = []
    model = run(path, warn=warnings.append, voxel_size=(0.25,) * 3, shape="conform")
    assert model.voxel_volume.sum() == pytest.approx(1.0, rel=1e-9)
    assert len(model.meta["objects"]) == 1
    assert len(warnings) == 1 and "dropped 1 conform sliver" in warnings[0]
    kept = run(path, fraction=0.0, voxel_size=(0.25,) * 3, shape="conform")
    assert len(kept.meta["objects"]) == 2
