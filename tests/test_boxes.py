"""Box-box contact of two voxels (blastvox.simulate.contact.boxes): faces resting on
faces give a patch of four points; boxes crossing edge to edge give one point between
the edges, at their true separation."""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import pytest

from blastvox.simulate.contact.boxes import box_contact


@nb.njit(cache=False)
def _contact(rot, half, centres, ahead):
    pair = np.array([0, 0, 1, 1, 0, 0, 0, 0], dtype=np.int64)
    work = (np.empty((3, 3)), np.empty((3, 8, 3)), np.zeros(32))
    hit = box_contact(rot, half, pair, centres, ahead, work)
    return hit, work[2]


def _turn(axis: int, degrees: float) -> np.ndarray:
    """Rotation matrix (3, 3) by ``degrees`` about world axis 0, 1 or 2."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


HALF = np.full((2, 3), 0.5)  # two unit cubes


def test_a_cube_resting_on_a_cube_gets_a_four_point_patch():
    rot = np.stack([np.eye(3), np.eye(3)])
    hit, patch = _contact(rot, HALF, np.array([[0.0, 0.0, 0.0], [0.2, 0.1, 1.001]]), 0.01)
    assert hit and int(patch[14]) == 4
    assert np.allclose(patch[3:6] * patch[15], (0.0, 0.0, 1.0))
    assert patch[12] == pytest.approx(0.001, abs=1e-9)


@pytest.mark.parametrize("overlap", [0.01, 0.002, -0.004])
def test_cubes_crossing_edge_to_edge_touch_at_one_point_at_their_true_separation(overlap):
    """A turned 45 degrees about x (its top an edge along x), b 45 degrees about y (its
    bottom an edge along y), b above a: the edges cross at right angles, ``overlap``
    deep (negative: apart). Face axes alone saw no contact there until a corner crossed
    a face, then one a quarter of a cube deep."""
    rot = np.stack([_turn(0, 45.0), _turn(1, 45.0)])
    top = math.sqrt(0.5)  # half the cube's face diagonal
    centres = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0 * top - overlap]])
    hit, patch = _contact(rot, HALF, centres, 0.01)
    assert hit and int(patch[14]) == 1
    normal = patch[3:6] * patch[15]
    assert np.allclose(normal, (0.0, 0.0, 1.0), atol=1e-9)
    assert patch[12] == pytest.approx(-overlap, abs=1e-9)
    assert np.allclose(patch[0:3], (0.0, 0.0, top - 0.5 * overlap), atol=1e-9)


def test_cubes_whose_edges_pass_apart_beyond_the_lookahead_do_not_touch():
    rot = np.stack([_turn(0, 45.0), _turn(1, 45.0)])
    centres = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0 * math.sqrt(0.5) + 0.05]])
    hit, _ = _contact(rot, HALF, centres, 0.01)
    assert not hit
