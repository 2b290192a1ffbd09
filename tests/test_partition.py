"""A large contact island cut in parts that threads sweep side by side
(blastvox.simulate.contact.partition): every row once, parts that share no body, rows
in support order, a cut across the ground."""

from __future__ import annotations

import numba as nb
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from blastvox.simulate.contact.partition import PARTS, cut_island


@nb.njit(cache=False)
def _cut(ends, rs, es, ids, pos, up):
    return cut_island(ends, rs, es, ids, pos, up)


def _pile(seed: int, bodies: int, rows: int):
    """A random island: bodies scattered over a 10 x 4 m floor, 3 m high (z up); rows
    between two bodies, or a body and something immovable (-1), in a random order."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform((0.0, 0.0, 0.0), (10.0, 4.0, 3.0), size=(bodies + 3, 3))
    ids = np.arange(3, bodies + 3)  # solve index e is body e + 3
    ends = rng.integers(0, bodies, size=(rows, 2))
    ends[rng.random(rows) < 0.2, 1] = -1
    rs = rng.permutation(rows)
    return ends, rs, np.arange(bodies), ids, pos


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), bodies=st.integers(2, 300), rows=st.integers(1, 900))
def test_every_row_is_in_one_part_or_the_seam_and_parts_share_no_body(seed, bodies, rows):
    ends, rs, es, ids, pos = _pile(seed, bodies, rows)
    start, grouped = _cut(ends, rs, es, ids, pos, np.array([0.0, 0.0, 1.0]))
    assert start[0] == 0 and start[-1] == len(rs) and np.all(np.diff(start) >= 0)
    assert sorted(grouped.tolist()) == sorted(rs.tolist())
    rank = {r: q for q, r in enumerate(rs.tolist())}
    owner = {}
    for p in range(PARTS + 1):
        group = grouped[start[p]:start[p + 1]]
        assert [rank[r] for r in group] == sorted(rank[r] for r in group)  # support order
        for r in group:
            moving = {e for e in ends[r] if e >= 0}
            if p < PARTS:  # a part's rows touch its bodies only
                for e in moving:
                    assert owner.setdefault(e, p) == p
            else:  # the seam's rows join bodies of two parts
                assert len(moving) == 2
    for r in grouped[start[PARTS]:]:
        a, b = ends[r]
        assert owner.get(a, -1) != owner.get(b, -2)


def test_the_cut_runs_across_the_ground_along_the_longer_side_and_halves_the_rows():
    """Bodies spread 10 m along x, 4 m along y and 3 m up: the parts are slabs along x
    (never along the up axis, even when it spreads most), with about half the row ends
    each."""
    ends, rs, es, ids, pos = _pile(7, 400, 1200)
    for up, axis in (((0.0, 0.0, 1.0), 0), ((1.0, 0.0, 0.0), 1)):
        start, grouped = _cut(ends, rs, es, ids, pos, np.array(up))
        part = {}
        for p in range(PARTS):
            for r in grouped[start[p]:start[p + 1]]:
                for e in ends[r]:
                    if e >= 0:
                        part[e] = p
        coordinate = {p: [pos[ids[e], axis] for e, q in part.items() if q == p]
                      for p in range(PARTS)}
        assert max(coordinate[0]) <= min(coordinate[1])  # slabs along the cut axis
        counts = np.diff(start)
        assert abs(counts[0] - counts[1]) < 0.15 * len(rs)
        assert counts[PARTS] < 0.9 * len(rs)
