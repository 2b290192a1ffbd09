"""The order in which a step's fronts judge the voxels they cross
(:func:`blastvox.simulate.fracture.fracture_wave`).

A wave is judged in order of its arrival, so dust it makes opens the shielding grid for
the points behind it. When nothing the step does can depend on that order
(:func:`order_free`), the voxels are judged in order of their index instead: the same
bytes, read front to back through the model's arrays rather than scattered over the
front's shell.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.blast.face_load import face_params_at
from blastvox.geometry.transforms_nb import to_world_into
from blastvox.jit import helper, kernel
from blastvox.simulate.criteria import REFERENCE_THICKNESS, crushes, pi_exceeded


@helper
def crossing(point, charge_pos, reach_in, reach_out, c) -> float:
    """Distance to charge c if the front crosses ``point`` this step, else -1."""
    dx = point[0] - charge_pos[c, 0]
    dy = point[1] - charge_pos[c, 1]
    dz = point[2] - charge_pos[c, 2]
    r = math.sqrt(dx * dx + dy * dy + dz * dz)
    if r > reach_in[c] and r <= reach_out[c]:
        return r
    return -1.0


def wave_order(ids: np.ndarray, when: np.ndarray, free: bool) -> tuple[np.ndarray, np.ndarray]:
    """(order, rows) (K,) int64 for :func:`~blastvox.simulate.fracture.fracture_wave`:
    the crossed voxels ``ids`` (K,) ascending, in order of arrival (``when`` (K,) s;
    ties by index), or, when ``free`` (:func:`order_free`),
    in index order, which reads the model's arrays front to back instead of scattered
    over the shell (a million-voxel block's wave ran ~4x faster); rows: each one's row
    in ids."""
    if free:
        return ids, np.arange(len(ids))
    rows = np.argsort(when, kind="stable")
    return ids[rows], rows


@kernel
def order_free(front, parts, run_state, ids, exposure, ahead) -> bool:
    """Does :func:`~blastvox.simulate.fracture.fracture_wave` give the same bytes whatever
    the order it judges the crossed voxels ``ids`` (K,) in (their views ``ahead``, rows
    as ids)? Yes when one charge's front crosses them, none turns to dust or shatters
    (nothing then changes the grid, another voxel's alive flag or links but the link
    being judged), and no alive link joins two of a different body: a link is then
    judged once, when the second of its ends is, on values symmetric in its two ends
    (the geometric means, the thinner member, either end squeezed, both blocked) and
    its own yield. The first voxel that would dust or shatter in arrival order is
    judged on its view ahead, as here (no dust before it opened the grid), so a step
    that dusts any is caught. parts and run_state:
    :func:`~blastvox.simulate.fracture.fracture_wave`'s (pressure-impulse fracture)."""
    geometry, link_geometry, strength, _ = parts
    links, voxels, bodies, _, _ = run_state
    if front.position.shape[0] != 1:
        return False
    centre = np.empty(3)
    for i in range(len(ids)):
        v = ids[i]
        b = voxels.body[v]
        to_world_into(bodies.rot[b], bodies.pos[b], bodies.com[b], geometry.centroid[v],
                      centre)
        r = crossing(centre, front.position, front.inner, front.outer, 0)
        if r < 0.0:
            continue
        m = strength.material[v]
        depth, thick = ahead.depth[i, 0], ahead.thickness[i, 0]
        i0 = strength.voxel_impulse[m] * thick / REFERENCE_THICKNESS
        if depth <= 2.0 * geometry.contact_radius[v] and (
                pi_exceeded(ahead.peak[i, 0], ahead.impulse[i, 0], voxels.yield_pa[v], i0,
                            strength.pi_shape[m])
                or (not ahead.blocked[i, 0] and crushes(front, 0, r - depth, ahead.cosine[i, 0],
                                                        exposure, b, strength, m, thick))):
            return False
        for k in range(geometry.link_offsets[v], geometry.link_offsets[v + 1]):
            link = geometry.link_ids[k]
            w = (link_geometry.voxels[link, 1] if link_geometry.voxels[link, 0] == v
                 else link_geometry.voxels[link, 0])
            if links.alive[link] and voxels.alive[w] and voxels.body[w] != b:
                return False
    return True


@kernel
def arrivals(front, voxel_centroid, voxels, bodies, candidate, active):
    """The alive candidate voxels (candidate (N,) bool) of active bodies that a front
    crosses this step: (ids (K,) int64 ascending, the earliest crossing front's arrival
    time there (K,) s: its time of detonation plus the arrival time at that distance)."""
    n = voxel_centroid.shape[0]
    ids = np.empty(n, dtype=np.int64)
    when = np.empty(n)
    count = 0
    centre = np.empty(3)
    for v in range(n):
        if not candidate[v] or not voxels.alive[v]:
            continue
        b = voxels.body[v]
        if not active[b]:
            continue
        to_world_into(bodies.rot[b], bodies.pos[b], bodies.com[b], voxel_centroid[v], centre)
        first = np.inf
        for c in range(front.position.shape[0]):
            r = crossing(centre, front.position, front.inner, front.outer, c)
            if r >= 0.0:
                ta = face_params_at(front.table, front.burst[c], r, front.scale[c])[1]
                first = min(first, front.time[c] + ta)
        if first < np.inf:
            ids[count] = v
            when[count] = first
            count += 1
    return ids[:count], when[:count]
