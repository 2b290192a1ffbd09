"""blastvox.geometry: the NumPy faces against each other, against the numba faces and
against closed forms (quaternions, rigid transforms, up-axis frames, voxel face tables)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from blastvox.geometry import frames, quaternion, quaternion_nb, transforms, voxel_faces

FINITE = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
QUATS = arrays(np.float64, 4, elements=st.floats(-1.0, 1.0)).filter(
    lambda q: np.linalg.norm(q) > 1e-3).map(quaternion.normalize)
VECS = arrays(np.float64, 3, elements=FINITE)


def _py(func):
    """The plain Python function of a numba helper (itself when JIT is disabled)."""
    return getattr(func, "py_func", func)


def _random_quats(n: int, seed: int = 0) -> np.ndarray:
    return quaternion.normalize(np.random.default_rng(seed).normal(size=(n, 4)))


# ----------------------------------------------------------------------------- quaternions

@given(QUATS)
def test_to_matrix_is_matrix_into_bit_for_bit(q):
    m = np.full((3, 3), np.nan)
    _py(quaternion_nb.matrix_into)(q, m)
    assert quaternion.to_matrix(q).tobytes() == m.tobytes()


def test_to_matrix_is_a_rotation_and_broadcasts():
    q = _random_quats(60).reshape(3, 5, 4, 4)
    m = quaternion.to_matrix(q)
    assert m.shape == (3, 5, 4, 3, 3)
    eye = np.broadcast_to(np.eye(3), m.shape)
    np.testing.assert_allclose(m @ np.swapaxes(m, -1, -2), eye, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-14)


def test_closed_forms():
    half = math.sqrt(0.5)
    quarter_z = np.array([half, 0.0, 0.0, half])  # +90 degrees about z
    np.testing.assert_allclose(quaternion.to_matrix(quarter_z),
                               [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(quaternion.rotate(quarter_z, [1.0, 0.0, 0.0]), [0, 1, 0],
                               atol=1e-15)
    np.testing.assert_allclose(quaternion.multiply(quarter_z, quarter_z),
                               [0.0, 0.0, 0.0, 1.0], atol=1e-15)  # 180 degrees about z
    # half-turns have trace -1: the branch that does not divide by the trace
    for m, q in (([[-1, 0, 0], [0, 1, 0], [0, 0, -1]], [0, 0, 1, 0]),
                 ([[1, 0, 0], [0, -1, 0], [0, 0, -1]], [0, 1, 0, 0]),
                 ([[-1, 0, 0], [0, -1, 0], [0, 0, 1]], [0, 0, 0, 1])):
        got = quaternion.from_matrix(np.array(m, dtype=float))
        np.testing.assert_allclose(np.abs(got), q, atol=1e-15)
    np.testing.assert_array_equal(quaternion.from_matrix(np.eye(3)), [1.0, 0, 0, 0])
    np.testing.assert_array_equal(quaternion.normalize([0.0, 0.0, 3.0, 4.0]), [0, 0, 0.6, 0.8])


def test_rotation_vector_closed_forms():
    half = math.sqrt(0.5)
    np.testing.assert_allclose(quaternion.rotation_vector(np.array([half, 0.0, 0.0, half])),
                               [0.0, 0.0, math.pi / 2], atol=1e-15)  # +90 degrees about z
    # -q is the same rotation; a half-turn is pi about its axis either way
    np.testing.assert_allclose(quaternion.rotation_vector(np.array([-half, 0.0, -half, 0.0])),
                               [0.0, math.pi / 2, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.abs(quaternion.rotation_vector(np.array([0.0, 1, 0, 0]))),
                               [math.pi, 0, 0], atol=1e-15)
    np.testing.assert_array_equal(quaternion.rotation_vector(np.array([1.0, 0, 0, 0])), 0.0)
    tiny = np.array([1.0, 1e-14, 0.0, 0.0])  # angle 2e-14: no division by ~0
    np.testing.assert_allclose(quaternion.rotation_vector(tiny), [2e-14, 0, 0], rtol=1e-12)


@given(QUATS)
def test_rotation_vector_round_trip(q):
    q = quaternion.normalize(q)
    v = quaternion.rotation_vector(q)
    angle = np.linalg.norm(v)
    assert angle <= math.pi + 1e-12
    back = np.concatenate([[math.cos(angle / 2)],
                           (v / angle * math.sin(angle / 2)) if angle > 0 else np.zeros(3)])
    np.testing.assert_allclose(np.abs(back @ q), 1.0, atol=1e-9)  # the same rotation


@given(QUATS)
def test_matrix_quaternion_round_trip(q):
    back = quaternion.from_matrix(quaternion.to_matrix(q))
    assert abs(np.linalg.norm(back) - 1.0) < 1e-14
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-12  # q and -q: one turn
    np.testing.assert_allclose(quaternion.to_matrix(back), quaternion.to_matrix(q),
                               atol=1e-12)


def test_from_matrix_stacks_and_all_branches():
    q = _random_quats(2002, seed=1)  # with the 4 below: 2006 = 2 x 17 x 59
    # near half-turns about each axis (trace close to -1) and near the identity
    extra = quaternion.normalize(np.concatenate([
        np.eye(4)[1:] + 1e-9 * np.random.default_rng(2).normal(size=(3, 4)), np.eye(4)[:1]]))
    q = np.concatenate([q, extra]).reshape(-1, 17, 4)
    back = quaternion.from_matrix(quaternion.to_matrix(q))
    assert back.shape == q.shape
    same_sign = np.sign(np.einsum("...i,...i->...", back, q))[..., None]
    np.testing.assert_allclose(back * same_sign, q, atol=1e-12)


@given(QUATS, QUATS, VECS)
def test_multiply_rotate_conjugate_agree_with_matrices(a, b, v):
    ab = quaternion.multiply(a, b)
    np.testing.assert_allclose(quaternion.to_matrix(ab),
                               quaternion.to_matrix(a) @ quaternion.to_matrix(b), atol=1e-12)
    scale = 1.0 + np.abs(v).max()
    np.testing.assert_allclose(quaternion.rotate(a, v), quaternion.to_matrix(a) @ v,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(quaternion.multiply(a, quaternion.conjugate(a)),
                               [1.0, 0.0, 0.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(quaternion.rotate(quaternion.conjugate(a),
                                                 quaternion.rotate(a, v)), v,
                               atol=1e-12 * scale)


def test_multiply_and_rotate_broadcast():
    q = _random_quats(12).reshape(3, 4, 4)
    one = _random_quats(1, seed=3)[0]
    v = np.random.default_rng(4).normal(size=(3, 4, 8, 3))
    np.testing.assert_array_equal(quaternion.multiply(one, q),
                                  quaternion.multiply(np.broadcast_to(one, q.shape), q))
    np.testing.assert_array_equal(quaternion.rotate(q[:, :, None, :], v),
                                  quaternion.rotate(np.repeat(q[:, :, None, :], 8, axis=2), v))


def test_sign_continuous():
    rng = np.random.default_rng(5)
    keys = _random_quats(40 * 6, seed=6).reshape(40, 6, 4)
    flips = np.where(rng.random((40, 6, 1)) < 0.5, -1.0, 1.0)
    out = quaternion.sign_continuous(keys * flips)
    assert out.shape == keys.shape
    assert np.all(np.einsum("fpi,fpi->fp", out[1:], out[:-1]) >= 0)
    np.testing.assert_array_equal(np.abs(out), np.abs(keys))  # the same rotations
    np.testing.assert_array_equal(out[0], (keys * flips)[0])  # the first key is kept
    flat = quaternion.sign_continuous((keys * flips)[:, 0])  # (F, 4) works too
    np.testing.assert_array_equal(flat, out[:, 0])
    one = keys[:1]
    assert quaternion.sign_continuous(one) is one


def test_integrate_closed_form():
    """integrate: the exact exponential map, a turn of |omega| dt about omega."""
    q = np.array([1.0, 0.0, 0.0, 0.0])
    _py(quaternion_nb.integrate)(q, 0.0, 0.0, 2.0, 0.25)  # 0.5 rad about z
    np.testing.assert_allclose(q, [math.cos(0.25), 0.0, 0.0, math.sin(0.25)], atol=1e-16)


# ----------------------------------------------------------------------------- transforms

def test_rest_to_world_and_back():
    rng = np.random.default_rng(7)
    q = _random_quats(5, seed=8)
    p, c = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    x = rng.normal(size=(5, 10, 3))
    world = transforms.rest_to_world(x, p[:, None], q[:, None], c[:, None])
    by_matrix = np.einsum("bij,bkj->bki", quaternion.to_matrix(q), x - c[:, None]) + p[:, None]
    np.testing.assert_allclose(world, by_matrix, atol=1e-12)
    np.testing.assert_allclose(transforms.world_to_rest(world, p[:, None], q[:, None],
                                                        c[:, None]), x, atol=1e-12)
    local = x - c[:, None]  # piece-local points: no centre
    np.testing.assert_allclose(transforms.rest_to_world(local, p[:, None], q[:, None]), world,
                               atol=1e-12)
    np.testing.assert_allclose(transforms.world_to_rest(world, p[:, None], q[:, None]), local,
                               atol=1e-12)


@pytest.mark.parametrize("model_up, export_up", [("Z", "Y"), ("Y", "Z"), ("Y", "Y")])
def test_change_frame_moves_world_points_with_the_frame(model_up, export_up):
    """C (p + R x) = p' + R' (C x): a piece looks the same after a change of frame."""
    rng = np.random.default_rng(9)
    pos = rng.normal(size=(6, 4, 3)).astype(np.float32)
    ori = _random_quats(24, seed=10).reshape(6, 4, 4).astype(np.float32)
    local = rng.normal(size=(4, 3))
    change = frames.frame_change(model_up, export_up)
    new_pos, new_ori = transforms.change_frame(pos, ori, change)
    assert new_pos.dtype == new_ori.dtype == np.float64
    before = transforms.rest_to_world(local, pos.astype(np.float64), quaternion.normalize(ori))
    after = transforms.rest_to_world(local @ change.T, new_pos, new_ori)
    np.testing.assert_allclose(after, before @ change.T, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(new_ori, axis=-1), 1.0, atol=1e-15)


# ----------------------------------------------------------------------------- frames

def test_up_axes():
    assert [frames.up_index(a) for a in "XYZ"] == [0, 1, 2]
    assert [frames.up_name(i) for i in range(3)] == ["X", "Y", "Z"]
    np.testing.assert_array_equal(frames.up_vector("Z"), [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(frames.gravity_vector("Y"), [0.0, -9.81, 0.0])
    np.testing.assert_array_equal(frames.gravity_vector("Z", 3.5), [0.0, 0.0, -3.5])
    for bad in ("", "y", "XY", "W"):
        with pytest.raises(ValueError):
            frames.up_index(bad)


def test_frame_change():
    for a in frames.UP_AXES:
        for b in frames.UP_AXES:
            c = frames.frame_change(a, b)
            np.testing.assert_array_equal(c @ frames.up_vector(a), frames.up_vector(b))
            np.testing.assert_array_equal(c @ frames.frame_change(b, a), np.eye(3))
            assert np.linalg.det(c) == pytest.approx(1.0)
    # Z-up -> Y-up: (x, y, z) -> (x, z, -y), Blender's exporters' convention
    np.testing.assert_array_equal(frames.frame_change("Z", "Y") @ [1.0, 2.0, 3.0], [1, 3, -2])
    frames.frame_change("Z", "Y")[0, 0] = 7.0  # a copy: the table stays as it was
    assert frames.frame_change("Z", "Y")[0, 0] == 1.0
    with pytest.raises(ValueError):
        frames.frame_change("X", "Y")


def test_frame_change_quaternions_keep_their_bits():
    """The exports' frame-change quaternions, bit for bit as exports before the shared
    module computed them (their last bits reach every exported orientation)."""
    want = {("Z", "Y"): ["0x1.6a09e667f3bcdp-1", "-0x1.6a09e667f3bccp-1", "0x0.0p+0",
                         "0x0.0p+0"],
            ("Y", "Z"): ["0x1.6a09e667f3bcdp-1", "0x1.6a09e667f3bccp-1", "0x0.0p+0",
                         "0x0.0p+0"],
            ("Y", "Y"): ["0x1.0000000000000p+0", "0x0.0p+0", "0x0.0p+0", "0x0.0p+0"]}
    for (a, b), bits in want.items():
        got = quaternion.from_matrix(frames.frame_change(a, b))
        assert [float(x).hex() for x in got] == bits


# ----------------------------------------------------------------------------- voxel faces

def _volume(points: np.ndarray, triangles: np.ndarray) -> float:
    """Signed volume enclosed by triangles (T, 3) of point ids (positive: outward)."""
    a, b, c = (points[triangles[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def test_face_tables():
    vf = voxel_faces
    corners = vf.CORNER_OFFSETS.astype(float)
    assert vf.CORNER_OFFSETS.shape == (vf.CORNER_COUNT, 3)
    assert vf.FACE_CORNERS.shape == (vf.FACE_COUNT, 4)
    np.testing.assert_array_equal(vf.CORNER_OFFSETS @ [1, 2, 4], np.arange(8))
    for f in range(vf.FACE_COUNT):
        axis, side = divmod(f, 2)
        quad = corners[vf.FACE_CORNERS[f]]
        assert np.all(quad[:, axis] == side)  # the face's corners lie on its side
        normal = np.cross(quad[2] - quad[0], quad[3] - quad[1])  # counter-clockwise
        np.testing.assert_array_equal(np.sign(normal), vf.FACE_OFFSETS[f])
        assert vf.OPPOSITE_FACE[f] == f ^ 1
        np.testing.assert_array_equal(vf.FACE_OFFSETS[vf.OPPOSITE_FACE[f]], -vf.FACE_OFFSETS[f])
    assert np.all(np.bincount(vf.FACE_CORNERS.ravel()) == 3)  # each corner on three faces
    assert vf.SURFACE_TAG == vf.SURFACE_BIT == vf.FACE_COUNT == 6


def test_hex_triangles_close_the_cube_outward():
    ids = np.arange(8)[None] * 3 + 5  # any increasing global ids
    points = np.zeros((ids.max() + 1, 3))
    points[ids[0]] = voxel_faces.CORNER_OFFSETS
    tris = voxel_faces.hex_triangles(ids)
    assert tris.shape == (1, 12, 3)
    assert _volume(points, tris[0]) == pytest.approx(1.0)
    # triangles 2f and 2f + 1 lie on face f
    for f in range(6):
        on = points[tris[0, 2 * f:2 * f + 2]].reshape(-1, 3)[:, f // 2]
        assert np.all(on == f % 2)


def test_shared_faces_split_the_same_way():
    """The two voxels on either side of a face see its corners in opposite order (and
    possibly rotated); face_triangles gives both the same two triangles."""
    rng = np.random.default_rng(11)
    for _ in range(200):
        quad = rng.choice(100, size=4, replace=False)
        seen_from_behind = np.roll(quad[::-1], rng.integers(4))
        mine = {frozenset(t) for t in voxel_faces.face_triangles(quad).tolist()}
        theirs = {frozenset(t) for t in voxel_faces.face_triangles(seen_from_behind).tolist()}
        assert mine == theirs


def test_vtk_cell_faces_are_outward():
    vtk = voxel_faces.VTK_CELL_FACES
    hex_points = voxel_faces.CORNER_OFFSETS[voxel_faces.VTK_HEXAHEDRON_CORNERS].astype(float)
    np.testing.assert_array_equal(hex_points[:4, 2], 0.0)  # VTK: bottom, then top
    assert _volume(hex_points, vtk["hexahedron"]) == pytest.approx(1.0)
    # the same six faces as FACE_CORNERS (as sets of voxel corners)
    corners = voxel_faces.VTK_HEXAHEDRON_CORNERS[vtk["hexahedron"]].reshape(6, 6)
    assert ({frozenset(f) for f in corners.tolist()}
            == {frozenset(f) for f in voxel_faces.FACE_CORNERS.tolist()})
    tet_points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert _volume(tet_points, vtk["tetra"]) == pytest.approx(1.0 / 6.0)


def test_one_home():
    """The voxelizer and the VoxelModel contract use the shared tables themselves."""
    from blastvox import model
    from blastvox.export import pieces
    from blastvox.voxelize import conform, lattice

    assert model.SURFACE_BIT is voxel_faces.SURFACE_BIT
    assert conform.SURFACE_TAG is voxel_faces.SURFACE_TAG
    assert lattice.FACE_CORNERS is voxel_faces.FACE_CORNERS
    assert lattice.face_triangles is voxel_faces.face_triangles
    assert pieces.frame_change is frames.frame_change


@settings(max_examples=50)
@given(QUATS, VECS)
def test_quaternion_faces_agree_on_rotating_points(q, v):
    """rotate (quaternion), to_matrix @ v and matrix_into's matrix @ v are one rotation."""
    m = np.empty((3, 3))
    _py(quaternion_nb.matrix_into)(q, m)
    scale = 1.0 + np.abs(v).max()
    np.testing.assert_allclose(quaternion.rotate(q, v), m @ v, atol=1e-12 * scale)
    np.testing.assert_allclose(transforms.rest_to_world(v, np.zeros(3), q), m @ v,
                               atol=1e-12 * scale)


# ------------------------------------------------------------------- exact products

@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, (5, 3), elements=FINITE), arrays(np.float64, (3, 3), elements=FINITE),
       VECS)
def test_exact_products_are_numpys_in_a_fixed_order(p, m, v):
    """exact.dot, norm, matvec and vecmat are the products numpy's BLAS gives, summed
    left to right one rounded operation at a time: bit for bit the plain Python sums."""
    from blastvox.geometry import exact

    def sum3(a, b):
        return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2]

    assert exact.dot(v, v) == sum3(v, v)
    assert exact.norm(v) == math.sqrt(sum3(v, v))
    np.testing.assert_array_equal(exact.dot(p, v), [sum3(row, v) for row in p])
    np.testing.assert_array_equal(exact.matvec(m, v), [sum3(row, v) for row in m])
    np.testing.assert_array_equal(exact.vecmat(p, m), [[sum3(row, m[:, j]) for j in range(3)]
                                                       for row in p])
    np.testing.assert_array_equal(exact.matvec(m, p), [[sum3(m[i], row) for i in range(3)]
                                                       for row in p])
    scale = 1e-12 * (1.0 + np.abs(p).max()) * (1.0 + np.abs(m).max())
    np.testing.assert_allclose(exact.vecmat(p, m), p @ m, rtol=1e-12, atol=scale)
    np.testing.assert_allclose(exact.matvec(m, p), p @ m.T, rtol=1e-12, atol=scale)


def test_exact_products_broadcast_stacks_of_matrices():
    from blastvox.geometry import exact

    rng = np.random.default_rng(3)
    rot, vec = rng.normal(size=(4, 3, 3)), rng.normal(size=(4, 3))
    np.testing.assert_allclose(exact.matvec(rot, vec), np.einsum("kij,kj->ki", rot, vec))
    np.testing.assert_allclose(exact.vecmat(vec, rot), np.einsum("ki,kij->kj", vec, rot))
    assert exact.dot(rot[0], vec[0]).shape == (3,)
