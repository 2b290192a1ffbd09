"""Rubble faces (blastvox.export.rubble): fracture faces reshaped for the look only.

Checked on real meshes of ../shared/meshes (their copies in tests/data) voxelized
as the CLI does (the Khronos Duck and the fan disk, conform, nearly
every voxel on their curved surfaces, and a cube-voxel wall with a hole), cut into
pieces the way fracture cuts them (Voronoi cells of voxels): the pieces stay
closed and still fit together at rest (their volumes add up to the intact
model's), the outside keeps its planes and its area, no triangle folds over,
the fracture faces stop being axis-aligned steps, and the result is the same
bytes whatever the order of the triangles.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from blastvox.export.pieces import piece_meshes
from blastvox.export.rubble import ROUGHNESS, roughen
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

MESHES = Path(__file__).resolve().parent / "data"  # copies of ../shared/meshes


def _shattered(mesh: str, resolution: int, shape: str, pieces: int, seed: int) -> SimpleNamespace:
    """A model of ``mesh`` cut into ``pieces`` Voronoi cells of its voxels, at rest: what
    piece_meshes reads of a SimCache."""
    model = voxelize([ObjectRequest(mesh=MESHES / mesh, resolution=resolution,
                                    material="concrete", shape=shape)],
                     VoxelizeSettings(up_axis="Z", ground=None))
    centroid = model.arrays["voxel_centroid"]
    rng = np.random.default_rng(seed)
    seeds = centroid[rng.choice(len(centroid), pieces, replace=False)]
    piece = np.argmin(((centroid[:, None] - seeds[None]) ** 2).sum(-1), axis=1)
    mass = model.arrays["voxel_mass"]
    total = np.bincount(piece, weights=mass, minlength=pieces)
    pivot = np.stack([np.bincount(piece, weights=mass * centroid[:, k], minlength=pieces)
                      for k in range(3)], axis=1) / total[:, None]
    return SimpleNamespace(model=model, voxel_piece=piece.astype(np.int32), piece_pivot=pivot,
                           piece_count=pieces)


@pytest.fixture(scope="module", params=[("Duck.glb", 14, "conform"),
                                        ("fandisk.obj", 10, "conform"),
                                        ("wallhole.obj", 20, "cube")],
                ids=["conform-duck", "conform-fandisk", "cube-wall"])
def shattered(request: pytest.FixtureRequest) -> SimpleNamespace:
    mesh, resolution, shape = request.param
    return _shattered(mesh, resolution, shape, pieces=12, seed=3)


def _edge(shattered: SimpleNamespace) -> float:
    """The model's voxel edge (m), as piece_meshes takes it."""
    return float(np.median(np.cbrt(shattered.model.arrays["voxel_volume"])))


def _doubled_normals(t: np.ndarray) -> np.ndarray:
    """Normals (T, 3) of triangles (T, 3, 3), twice their area long."""
    return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def _area(t: np.ndarray) -> float:
    """Total area (m^2) of triangles (T, 3, 3)."""
    return float(np.linalg.norm(_doubled_normals(t), axis=1).sum() / 2)


def _sorted_rows(t: np.ndarray) -> np.ndarray:
    """Triangles (T, 3, 3) as sorted opaque rows: the same set in any order compares equal."""
    return np.sort(np.ascontiguousarray(t).reshape(len(t), -1).view(np.dtype((np.void, 72)))
                   .ravel())


def _volumes(meshes) -> np.ndarray:
    """Signed volume (m^3) of each piece's closed mesh (P,), rest frame."""
    r = meshes.rest
    tet = np.einsum("ij,ij->i", r[:, 0], np.cross(r[:, 1], r[:, 2])) / 6.0
    return np.add.reduceat(tet, meshes.offsets[:-1]) if len(tet) else np.zeros(0)


def _open_length(meshes, p: int) -> float:
    """Length (m) of piece p's sides that no side of it runs back along (0: closed)."""
    tris = meshes.rest[meshes.offsets[p]:meshes.offsets[p + 1]].reshape(-1, 3)
    points, ids = np.unique(tris, axis=0, return_inverse=True)
    c = ids.reshape(-1, 3)
    edges = {tuple(e) for e in np.concatenate([c[:, [0, 1]], c[:, [1, 2]], c[:, [2, 0]]]).tolist()}
    return sum(float(np.linalg.norm(points[a] - points[b])) for a, b in edges
               if (b, a) not in edges)


def test_pieces_stay_closed_and_still_fit(shattered):
    voxel = piece_meshes(shattered, "Z", "voxel")
    rough = piece_meshes(shattered, "Z", "rough")
    # the same triangles, moved (a few that two merged points make empty are dropped)
    assert 0.99 * len(voxel.vertices) <= len(rough.vertices) <= len(voxel.vertices)
    # a closed piece stays closed; where the input's own triangulation leaves a seam
    # (a T-junction of the conform cells), it stays about as long
    for p in range(shattered.piece_count):
        before, after = _open_length(voxel, p), _open_length(rough, p)
        assert after <= 1.5 * before + 1e-9 * _edge(shattered), (p, before, after)
    # every fracture face is shared by two pieces, which move it together: the volumes
    # still add up to the intact model's
    v_voxel, v_rough = _volumes(voxel), _volumes(rough)
    assert v_rough.sum() == pytest.approx(v_voxel.sum(), rel=1e-6)
    # a piece gains or loses no more than its fracture faces sweep moving ROUGHNESS edges
    r = voxel.rest
    area = np.linalg.norm(np.cross(r[:, 1] - r[:, 0], r[:, 2] - r[:, 0]), axis=1) / 2
    fracture_area = np.add.reduceat(area * voxel.damage, voxel.offsets[:-1])
    assert np.all(np.abs(v_rough - v_voxel) <= ROUGHNESS * _edge(shattered) * fracture_area)


def test_outside_keeps_its_planes_and_area(shattered):
    voxel = piece_meshes(shattered, "Z", "voxel")
    triangles = voxel.rest
    out = roughen(triangles, voxel.damage, _edge(shattered))
    whole = ~voxel.damage
    before, after = triangles[whole], out[whole]
    normal = np.cross(before[:, 1] - before[:, 0], before[:, 2] - before[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    off_plane = np.abs(np.einsum("ikj,ij->ik", after - before[:, :1], normal))
    assert off_plane.max() < 1e-4 * _edge(shattered)  # planes in float32 are planar to 1e-7
    assert _area(after) == pytest.approx(_area(triangles[~voxel.damage]), rel=2e-5)
    # and it moved where a crack meets a flat face: outlines are no longer staircases
    assert np.abs(after - before).max() > 0.05 * _edge(shattered)


def test_no_triangle_folds_over(shattered):
    """No triangle turns over, but slivers (height under 1 % of the longest side: their
    normal is rounding noise and they draw nothing), which may, and stay slivers."""
    voxel = piece_meshes(shattered, "Z", "voxel")
    out = roughen(voxel.rest, voxel.damage, _edge(shattered))
    new, old = _doubled_normals(out), _doubled_normals(voxel.rest)
    cos = np.einsum("ij,ij->i", new, old) / (np.linalg.norm(new, axis=1)
                                               * np.linalg.norm(old, axis=1) + 1e-300)
    rest = voxel.rest
    longest = np.max(np.linalg.norm(rest - np.roll(rest, 1, axis=1), axis=2), axis=1)
    sliver = np.linalg.norm(old, axis=1) < 1e-2 * longest ** 2
    drawn = np.linalg.norm(new, axis=1) > 0  # points closer than 1e-5 edges are one
    assert cos[~sliver & drawn].min() > 0.0
    area = np.linalg.norm(new, axis=1)
    assert area[cos <= 0].sum() < 1e-3 * area.sum()


def test_fracture_faces_are_not_steps(shattered):
    """Most of the fracture area no longer faces along an axis (a voxel step)."""
    axis_aligned = {}
    for mode in ("voxel", "rough"):
        m = piece_meshes(shattered, "Z", mode)
        area = np.linalg.norm(np.cross(m.rest[:, 1] - m.rest[:, 0],
                                       m.rest[:, 2] - m.rest[:, 0]), axis=1)
        aligned = np.abs(m.normals).max(axis=1) > np.cos(np.radians(5.0))
        axis_aligned[mode] = area[m.damage & aligned].sum() / area[m.damage].sum()
    assert axis_aligned["voxel"] > 0.99  # cell faces (cube voxels, conform cell faces)
    # a crack through a member one or two cells thick under a curved surface keeps its
    # cell face: its corners are on the curve, which they do not leave (the duck and
    # the fan disk at 10-16 voxels across are mostly such cells)
    conform = shattered.model.arrays["conform_voxels"].size > 0
    assert axis_aligned["rough"] < (0.6 if conform else 0.3), axis_aligned


def test_same_bytes_whatever_the_order(shattered):
    voxel = piece_meshes(shattered, "Z", "voxel")
    out = roughen(voxel.rest, voxel.damage, _edge(shattered), seed=7)
    again = roughen(voxel.rest, voxel.damage, _edge(shattered), seed=7)
    assert out.tobytes() == again.tobytes()
    order = np.random.default_rng(0).permutation(len(voxel.rest))
    shuffled = roughen(voxel.rest[order], voxel.damage[order], _edge(shattered), seed=7)
    assert np.array_equal(_sorted_rows(shuffled), _sorted_rows(out))
    other = roughen(voxel.rest, voxel.damage, _edge(shattered), seed=8)
    assert not np.array_equal(other, out)


def test_nothing_to_roughen():
    tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    assert np.array_equal(roughen(tri, np.array([False]), 0.2), tri)
    with pytest.raises(ValueError, match="fracture_faces"):
        piece_meshes(SimpleNamespace(), "Y", "smooth")


def test_export_cli_draws_rubble_unless_asked_for_voxel_faces(shattered_slab, tmp_path):
    """`blastvox export` writes rubble faces by default and cell faces with
    --fracture-faces voxel; read back with trimesh: as many triangles, most of them
    no longer facing along an axis; the same bytes twice."""
    import subprocess
    import sys

    import trimesh

    sim = tmp_path / "sim.npz"
    shattered_slab.save(sim)
    faces = {}
    for mode in ("rough", "voxel", "rough"):
        out = tmp_path / f"{mode}.glb"
        first = out.read_bytes() if out.exists() else None
        done = subprocess.run([sys.executable, "-m", "blastvox", "export", str(sim), "-o",
                               str(out), "--fracture-faces", mode, "-q"],
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        if first is not None:
            assert out.read_bytes() == first
        scene = trimesh.load(out, force="scene")
        faces[mode] = sum(len(g.faces) for g in scene.geometry.values())
        normals = np.concatenate([g.face_normals for g in scene.geometry.values()])
        faces[mode + " aligned"] = float(np.mean(np.abs(normals).max(axis=1) > 0.9962))
    assert 0.99 * faces["voxel"] <= faces["rough"] <= faces["voxel"]
    assert faces["voxel aligned"] > 0.99 > 0.8 > faces["rough aligned"]
    help_text = subprocess.run([sys.executable, "-m", "blastvox", "export", "--help"],
                               capture_output=True, text=True, timeout=60).stdout
    assert "--fracture-faces" in help_text
