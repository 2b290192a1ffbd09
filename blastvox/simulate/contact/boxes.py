"""Box-box contact of two voxels of different bodies (:func:`box_contact`): separating
axes over the face normals, then the incident face clipped to the reference face, as
Bullet's and ODE's box-box tests do, for up to four contact points."""

from __future__ import annotations

import math

import numpy as np

from blastvox.jit import helper
from blastvox.simulate.contact.ground import pick_four


@helper
def box_contact(rot, half, pair, centres, ahead, work) -> bool:
    """Do the boxes of voxels pair[1] (of body pair[0], centre centres[0], m) and pair[3]
    (body pair[2], centres[1]) touch, or come within ``ahead`` (m)? rot (B, 3, 3): the
    bodies' rotations; half (N, 3): the boxes' half extents (m) along their rest axes.
    If so the patch is in work[2] (:func:`_manifold`; [15] > 0: on box a's face). work:
    scratch (3, 3), (3, 8, 3), (32,). Separating axes: the six face normals and the
    nine edge-edge axes; where an edge-edge axis separates the boxes clearly more than
    any face's (two boxes crossing edge to edge), the contact is one point between
    the two edges (:func:`_edge_contact`, as ODE's and Bullet's box-box tests). Left
    to the faces, such a pair got no contact while the incident face's corners lay
    outside the reference face, then one a quarter of a voxel deep once a corner
    crossed into it (the building's rubble: a 10 m/s chip 0.5 voxels "deep")."""
    cross, poly, patch = work
    ba, va, bb, vb = pair[0], pair[1], pair[2], pair[3]
    dx, dy, dz = (centres[1, 0] - centres[0, 0], centres[1, 1] - centres[0, 1],
                  centres[1, 2] - centres[0, 2])
    for k in range(3):
        for m in range(3):
            cross[k, m] = (rot[ba, 0, k] * rot[bb, 0, m] + rot[ba, 1, k] * rot[bb, 1, m]
                           + rot[ba, 2, k] * rot[bb, 2, m])
    sa, ka, sb, kb = -np.inf, 0, -np.inf, 0
    for k in range(3):
        s = (abs(dx * rot[ba, 0, k] + dy * rot[ba, 1, k] + dz * rot[ba, 2, k]) - half[va, k]
             - half[vb, 0] * abs(cross[k, 0]) - half[vb, 1] * abs(cross[k, 1])
             - half[vb, 2] * abs(cross[k, 2]))
        if s > sa:
            sa, ka = s, k
        s = (abs(dx * rot[bb, 0, k] + dy * rot[bb, 1, k] + dz * rot[bb, 2, k]) - half[vb, k]
             - half[va, 0] * abs(cross[0, k]) - half[va, 1] * abs(cross[1, k])
             - half[va, 2] * abs(cross[2, k]))
        if s > sb:
            sb, kb = s, k
    smallest = min(half[va, 0], half[va, 1], half[va, 2], half[vb, 0], half[vb, 1],
                   half[vb, 2])
    slop = 1e-3 * smallest
    ahead += slop
    if max(sa, sb) > ahead:
        return False
    se, edge = _edge_axes(rot, half, pair, dx, dy, dz, cross)
    if se > ahead:
        return False
    if se > max(sa, sb) + EDGE_MARGIN * smallest:
        return _edge_contact(rot, half, pair, centres, edge, poly[0], patch)
    on_a = not sb > sa + slop  # a's face unless b's separates clearly more: stable
    kept = _manifold(rot, half, pair, centres, 0 if on_a else 1, ka if on_a else kb, poly,
                     ahead, patch, pair[4:])
    patch[15] = 1.0 if on_a else -1.0
    return kept > 0


#: An edge-edge axis makes the contact only where it separates the boxes by more than
#: the faces' best axis plus this fraction of the smallest half extent: faces are
#: preferred (a patch of up to four points carries a stack; ODE's fudge factor).
EDGE_MARGIN = 0.05


@helper
def _edge_axes(rot, half, pair, dx, dy, dz, cross):
    """The largest separation (m) of boxes pair[1] (body pair[0]) and pair[3] (body
    pair[2]) along the nine axes ua_i x ub_j (centres d = (dx, dy, dz) apart, m; cross
    (3, 3): ua_k . ub_m), and its axis as 3 i + j (-1: every pair of edges parallel,
    separation -inf)."""
    ba, va, bb, vb = pair[0], pair[1], pair[2], pair[3]
    best, axis = -np.inf, -1
    for i in range(3):
        for j in range(3):
            lx = rot[ba, 1, i] * rot[bb, 2, j] - rot[ba, 2, i] * rot[bb, 1, j]
            ly = rot[ba, 2, i] * rot[bb, 0, j] - rot[ba, 0, i] * rot[bb, 2, j]
            lz = rot[ba, 0, i] * rot[bb, 1, j] - rot[ba, 1, i] * rot[bb, 0, j]
            size = math.sqrt(lx * lx + ly * ly + lz * lz)
            if size < 1e-6:  # parallel edges: a face axis decides
                continue
            # |ua_k . L| and |ub_m . L| (L unnormalised) are entries of cross
            i1, i2, j1, j2 = (i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3
            ra = half[va, i1] * abs(cross[i2, j]) + half[va, i2] * abs(cross[i1, j])
            rb = half[vb, j1] * abs(cross[i, j2]) + half[vb, j2] * abs(cross[i, j1])
            s = (abs(dx * lx + dy * ly + dz * lz) - ra - rb) / size
            if s > best:
                best, axis = s, 3 * i + j
    return best, axis


@helper
def _edge_contact(rot, half, pair, centres, edge, ends, patch) -> bool:
    """One contact point between the edge of box a along its axis edge // 3 and the edge
    of box b along its axis edge % 3 that face each other across their axis L = ua x ub
    (:func:`_edge_axes`): the midpoint of their closest points, its separation along L
    (m, negative: overlap), into patch (see :func:`_manifold`; normal L from a to b, on
    a's side). ends (>= 2, 3): scratch."""
    ba, va, bb, vb = pair[0], pair[1], pair[2], pair[3]
    i, j = edge // 3, edge % 3
    ux, uy, uz = rot[ba, 0, i], rot[ba, 1, i], rot[ba, 2, i]
    wx, wy, wz = rot[bb, 0, j], rot[bb, 1, j], rot[bb, 2, j]
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    size = math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / size, ny / size, nz / size
    dx, dy, dz = (centres[1, 0] - centres[0, 0], centres[1, 1] - centres[0, 1],
                  centres[1, 2] - centres[0, 2])
    if dx * nx + dy * ny + dz * nz < 0.0:
        nx, ny, nz = -nx, -ny, -nz
    pa, pb = ends[0], ends[1]
    for a in range(3):
        pa[a], pb[a] = centres[0, a], centres[1, a]
    for k in range(3):  # the edges nearest each other: a's towards b, b's towards a
        sa = 1.0 if rot[ba, 0, k] * nx + rot[ba, 1, k] * ny + rot[ba, 2, k] * nz > 0.0 else -1.0
        sb = 1.0 if rot[bb, 0, k] * nx + rot[bb, 1, k] * ny + rot[bb, 2, k] * nz > 0.0 else -1.0
        for a in range(3):
            if k != i:
                pa[a] += sa * half[va, k] * rot[ba, a, k]
            if k != j:
                pb[a] -= sb * half[vb, k] * rot[bb, a, k]
    # closest points of pa + s u and pb + t w, s and t within the edges' half lengths
    rx, ry, rz = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
    uw = ux * wx + uy * wy + uz * wz
    ur, wr = ux * rx + uy * ry + uz * rz, wx * rx + wy * ry + wz * rz
    d = 1.0 - uw * uw
    s = (ur - uw * wr) / d if d > 1e-12 else 0.0
    s = min(max(s, -half[va, i]), half[va, i])
    t = min(max(s * uw - wr, -half[vb, j]), half[vb, j])
    s = min(max(ur + t * uw, -half[va, i]), half[va, i])
    gap = 0.0
    for a in range(3):
        qa = pa[a] + s * (ux if a == 0 else uy if a == 1 else uz)
        qb = pb[a] + t * (wx if a == 0 else wy if a == 1 else wz)
        gap += (qb - qa) * (nx if a == 0 else ny if a == 1 else nz)
        patch[a] = 0.5 * (qa + qb)
        patch[16 + a] = patch[a]
    tx, ty, tz = ux - (ux * nx + uy * ny + uz * nz) * nx, uy - (ux * nx + uy * ny + uz * nz) \
        * ny, uz - (ux * nx + uy * ny + uz * nz) * nz
    tn = math.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx / tn, ty / tn, tz / tn
    patch[3], patch[4], patch[5] = nx, ny, nz
    patch[6], patch[7], patch[8] = tx, ty, tz
    patch[9], patch[10], patch[11] = ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx
    patch[12], patch[13], patch[14], patch[15] = gap, 0.0, 1.0, 1.0
    patch[28] = gap
    return True


@helper
def _manifold(rot, half, pair, centres, ref, k, poly, ahead, patch, picks) -> int:
    """Clip the face of the other box (``ref`` 0: box a is the reference, 1: b; see
    :func:`_box_contact`) that faces the reference box's face across its axis k to that
    face; keep the points within ``ahead`` (m) of it, or a quarter of the face's smaller
    half extent, four at most (the deepest, the
    farthest from it, and the farthest on either side of the line through both). patch
    (32,) receives: their centre (3, m), the reference normal towards the other box (3),
    the reference face's axes t1 (3) and t2 (3), the smallest separation (m), the
    lever of twisting friction (m, 0.54 times the points' mean distance from their
    centre: 0.765 h, the mean lever of a square of half side h, from its corners),
    how many points, [16:28] the points (m, midway between the faces), [28:32] their
    separations (m). Returns how many points were kept (0: no contact)."""
    br, vr, bi, vi = pair[2 * ref], pair[2 * ref + 1], pair[2 - 2 * ref], pair[3 - 2 * ref]
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    t1x, t1y, t1z = rot[br, 0, k1], rot[br, 1, k1], rot[br, 2, k1]
    t2x, t2y, t2z = rot[br, 0, k2], rot[br, 1, k2], rot[br, 2, k2]
    nx, ny, nz = rot[br, 0, k], rot[br, 1, k], rot[br, 2, k]
    dx, dy, dz = (centres[1 - ref, 0] - centres[ref, 0], centres[1 - ref, 1] - centres[ref, 1],
                  centres[1 - ref, 2] - centres[ref, 2])
    if dx * nx + dy * ny + dz * nz < 0.0:
        nx, ny, nz = -nx, -ny, -nz
    m, best = 0, -1.0
    for c in range(3):
        dot = abs(nx * rot[bi, 0, c] + ny * rot[bi, 1, c] + nz * rot[bi, 2, c])
        if dot > best:
            m, best = c, dot
    m1, m2 = (m + 1) % 3, (m + 2) % 3
    # the incident face's normal opposes the reference's
    side = -half[vi, m] if nx * rot[bi, 0, m] + ny * rot[bi, 1, m] + nz * rot[bi, 2, m] > 0.0 \
        else half[vi, m]
    # incident face centre and half edges, in (t1, t2, n) coordinates of the reference face
    fx = dx + side * rot[bi, 0, m] - half[vr, k] * nx
    fy = dy + side * rot[bi, 1, m] - half[vr, k] * ny
    fz = dz + side * rot[bi, 2, m] - half[vr, k] * nz
    ex, ey, ez = half[vi, m1] * rot[bi, 0, m1], half[vi, m1] * rot[bi, 1, m1], \
        half[vi, m1] * rot[bi, 2, m1]
    gx, gy, gz = half[vi, m2] * rot[bi, 0, m2], half[vi, m2] * rot[bi, 1, m2], \
        half[vi, m2] * rot[bi, 2, m2]
    for a in range(3):
        ux, uy, uz = (t1x, t1y, t1z) if a == 0 else ((t2x, t2y, t2z) if a == 1 else (nx, ny, nz))
        base = fx * ux + fy * uy + fz * uz
        e1 = ex * ux + ey * uy + ez * uz
        e2 = gx * ux + gy * uy + gz * uz
        poly[0, 0, a] = base + e1 + e2
        poly[0, 1, a] = base - e1 + e2
        poly[0, 2, a] = base - e1 - e2
        poly[0, 3, a] = base + e1 - e2
    h1, h2 = half[vr, k1], half[vr, k2]
    n = 4
    inside = True
    for i in range(4):
        inside &= abs(poly[0, i, 0]) <= h1 and abs(poly[0, i, 1]) <= h2
    if not inside:
        n = _clip(poly, 0, n, 0, 1.0, h1, 1)
        n = _clip(poly, 1, n, 0, -1.0, h1, 0)
        n = _clip(poly, 0, n, 1, 1.0, h2, 1)
        n = _clip(poly, 1, n, 1, -1.0, h2, 0)
    kept = 0
    keep = max(ahead, 0.25 * min(h1, h2))  # near points too: a turn the solve starts
    for i in range(n):                     # may swing them down within the step
        if poly[0, i, 2] <= keep:
            for a in range(3):
                poly[2, kept, a] = poly[0, i, a]
            kept += 1
    if kept == 0:
        return 0
    used = pick_four(poly[2], kept, picks)
    hk = half[vr, k]
    c1 = c2 = cs = 0.0
    gap = np.inf
    for i in range(used):
        p1, p2, s = poly[2, picks[i], 0], poly[2, picks[i], 1], poly[2, picks[i], 2]
        c1, c2, cs, gap = c1 + p1 / used, c2 + p2 / used, cs + s / used, min(gap, s)
        patch[16 + 3 * i] = centres[ref, 0] + (hk + 0.5 * s) * nx + p1 * t1x + p2 * t2x
        patch[17 + 3 * i] = centres[ref, 1] + (hk + 0.5 * s) * ny + p1 * t1y + p2 * t2y
        patch[18 + 3 * i] = centres[ref, 2] + (hk + 0.5 * s) * nz + p1 * t1z + p2 * t2z
        patch[28 + i] = s
    spread = 0.0
    for i in range(used):
        spread += math.sqrt((poly[2, picks[i], 0] - c1) ** 2
                            + (poly[2, picks[i], 1] - c2) ** 2) / used
    patch[0] = centres[ref, 0] + (hk + 0.5 * cs) * nx + c1 * t1x + c2 * t2x
    patch[1] = centres[ref, 1] + (hk + 0.5 * cs) * ny + c1 * t1y + c2 * t2y
    patch[2] = centres[ref, 2] + (hk + 0.5 * cs) * nz + c1 * t1z + c2 * t2z
    patch[3], patch[4], patch[5] = nx, ny, nz
    patch[6], patch[7], patch[8] = t1x, t1y, t1z
    patch[9], patch[10], patch[11] = t2x, t2y, t2z
    patch[12], patch[13], patch[14] = gap, 0.54 * spread, used
    return used


@helper
def _clip(poly, src, n, axis, sign, limit, dst) -> int:
    """Sutherland-Hodgman: the convex polygon poly[src, :n] (rows (t1, t2, depth)) cut to
    sign * coordinate ``axis`` <= limit, into poly[dst]; returns its vertex count."""
    out = 0
    di = sign * poly[src, 0, axis] - limit
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        dj = sign * poly[src, j, axis] - limit
        if di <= 0.0:
            poly[dst, out, 0], poly[dst, out, 1] = poly[src, i, 0], poly[src, i, 1]
            poly[dst, out, 2] = poly[src, i, 2]
            out += 1
        if (di <= 0.0) != (dj <= 0.0):
            t = di / (di - dj)
            for a in range(3):
                poly[dst, out, a] = poly[src, i, a] + t * (poly[src, j, a] - poly[src, i, a])
            out += 1
        di = dj
    return out
