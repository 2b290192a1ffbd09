"""Orienting the closed shells of one surface by how they nest.

A solid with a sealed cavity (a bunker, a tank, a hollow column) is one mesh
with two or more shells: the outer surface and, inside it, the cavity's
surface. Inside/outside then follows from the winding number over all shells
together, which is right only if every shell faces the right way: a shell at
even nesting depth (inside no other shell, or inside a cavity's shell) bounds
material and faces outward (positive signed volume), a shell at odd depth (a
cavity inside material) faces inward, into the cavity (negative signed volume).

:func:`orient_shells` makes it so, shell by shell. Authored inward cavity normals
are kept, outward ones (a common modelling defect: the cavity drawn as a second
box) are turned inward, separate bodies side by side are each turned outward, and
an entirely inverted mesh is turned right side out. Nesting is decided by signed
crossings of rays from a shell's vertices through the other shells, so it costs
about O(shells whose bounding box lies in another's x (faces of that one)). A shell
that pokes through another (overlapping parts, not a cavity) is not nested in it.
"""

from __future__ import annotations

import numpy as np
import trimesh

#: Ray directions of the inside test (generic, so rays rarely graze an edge exactly);
#: a point is inside a shell if most of them cross it a nonzero net number of times.
_RAYS = np.array([[0.5773502691896258, 0.5773502691896258, 0.5773502691896258],
                  [-0.2672612419124244, 0.5345224838248488, 0.8017837257372732],
                  [0.8164965809277261, -0.4082482904638631, 0.4082482904638631]])
#: Vertices of a shell tested against an enclosing candidate: the first one, then the
#: six extremes along the axes (all must be inside for the shell to count as nested).
_SAMPLES = 7


def shell_labels(mesh: trimesh.Trimesh) -> np.ndarray:
    """Shell (edge-connected component) of each triangle: (F,) int64 in [0, shells)."""
    return np.asarray(trimesh.graph.connected_component_labels(
        mesh.face_adjacency, node_count=len(mesh.faces)), dtype=np.int64)


def signed_volumes(triangles: np.ndarray, labels: np.ndarray, count: int) -> np.ndarray:
    """Signed volume (count,) m^3 of each shell; positive for outward-facing closed shells.

    triangles: (F, 3, 3) metres; labels: (F,) shell of each triangle. Each shell's
    volume is taken about its own first vertex, so distant shells keep precision.
    """
    first = np.zeros(count, dtype=np.int64)
    first[labels[::-1]] = np.arange(len(labels))[::-1]
    ref = triangles[first, 0]
    t = triangles - ref[labels][:, None, :]
    six = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2]))
    return np.bincount(labels, weights=six, minlength=count) / 6.0


def nesting_depth(triangles: np.ndarray, labels: np.ndarray, count: int,
                  closed: np.ndarray | None = None) -> np.ndarray:
    """How many other closed shells enclose each shell: (count,) int64.

    triangles: (F, 3, 3) metres; labels: (F,) shell of each triangle; closed:
    (count,) bool, the shells that may enclose others (default all). Shell A is
    enclosed by shell B if A's bounding box lies in B's and A's sample vertices
    (:data:`_SAMPLES`) all lie inside B.
    """
    depth = np.zeros(count, dtype=np.int64)
    closed = np.ones(count, dtype=bool) if closed is None else np.asarray(closed, dtype=bool)
    if count < 2 or not closed.any():
        return depth
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(count + 1))
    shells = [triangles[order[bounds[s]:bounds[s + 1]]] for s in range(count)]
    lo = np.array([s.reshape(-1, 3).min(axis=0) for s in shells])
    hi = np.array([s.reshape(-1, 3).max(axis=0) for s in shells])
    tol = 1e-9 * float(np.max(hi.max(axis=0) - lo.min(axis=0)))
    samples: dict[int, np.ndarray] = {}
    for b in np.flatnonzero(closed).tolist():
        inner = np.flatnonzero(np.all(lo >= lo[b] - tol, axis=1)
                               & np.all(hi <= hi[b] + tol, axis=1)
                               & np.any(hi - lo < hi[b] - lo[b] - tol, axis=1))
        inner = inner[inner != b]
        if inner.size == 0:
            continue
        frames = [_ray_frame(shells[b], ray) for ray in _RAYS]
        for a in inner.tolist():
            if a not in samples:
                samples[a] = _sample_points(shells[a])
            if all(_inside(frames, p) for p in samples[a]):
                depth[a] += 1
    return depth


def closed_shells(mesh: trimesh.Trimesh, labels: np.ndarray, count: int) -> np.ndarray:
    """Which shells are watertight and consistently wound: (count,) bool."""
    edges = np.asarray(mesh.edges).reshape(-1, 3, 2)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(count + 1))
    out = np.zeros(count, dtype=bool)
    for s in range(count):
        faces = order[bounds[s]:bounds[s + 1]]
        if len(faces) >= 4:
            tight, wound = trimesh.graph.is_watertight(edges[faces].reshape(-1, 2))
            out[s] = tight and wound
    return out


def orient_shells(mesh: trimesh.Trimesh) -> list[str]:
    """Turn each closed shell of ``mesh`` (in place) to face the way its nesting depth says.

    Open shells (holes left after repair) are left as they are: their signed volume
    says nothing reliable about their orientation. Returns what was done, for the
    surface report (empty if nothing changed).
    """
    labels = shell_labels(mesh)
    count = int(labels.max()) + 1 if len(labels) else 0
    if count == 0:
        return []
    triangles = np.asarray(mesh.triangles, dtype=np.float64)
    volume = signed_volumes(triangles, labels, count)
    closed = closed_shells(mesh, labels, count)
    depth = (nesting_depth(triangles, labels, count, closed) if closed.sum() > 1
             else np.zeros(count, dtype=np.int64))
    want = np.where(depth % 2 == 0, 1.0, -1.0)
    flip = closed & (volume != 0.0) & (np.sign(volume) != want)
    if not flip.any():
        return []
    faces = np.asarray(mesh.faces).copy()
    turn = flip[labels]
    faces[turn] = faces[turn][:, ::-1]
    mesh.faces = faces
    cavity = flip & (depth % 2 == 1)
    outward = int(flip.sum() - cavity.sum())
    done = []
    if outward:
        done.append(f"turned {outward} inverted shell(s) outward")
    if cavity.any():
        done.append(f"turned {int(cavity.sum())} cavity shell(s) inward")
    return done


def _sample_points(tris: np.ndarray) -> np.ndarray:
    """Up to :data:`_SAMPLES` distinct vertices of a shell: (P, 3) metres."""
    points = tris.reshape(-1, 3)
    pick = [0] + [int(i) for i in np.argmin(points, axis=0)] + [
        int(i) for i in np.argmax(points, axis=0)]
    return points[np.unique(np.asarray(pick[:_SAMPLES]))]


def _ray_frame(tris: np.ndarray, ray: np.ndarray) -> tuple:
    """A shell's triangles in a frame whose third axis is ``ray``, with per-triangle
    (u, v) bounds and the sign of the normal along the ray."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(ray[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(ray, helper)
    u /= np.linalg.norm(u)
    v = np.cross(ray, u)
    basis = np.stack([u, v, ray])  # rows
    local = tris @ basis.T  # (F, 3, 3)
    uv = local[:, :, :2]
    return basis, local, uv.min(axis=1), uv.max(axis=1)


def _inside(frames: list, point: np.ndarray) -> bool:
    """Is ``point`` inside the shell: a nonzero net crossing count for most rays."""
    votes = 0
    for basis, local, uv_lo, uv_hi in frames:
        p = basis @ point
        near = np.flatnonzero((uv_lo[:, 0] <= p[0]) & (uv_hi[:, 0] >= p[0])
                              & (uv_lo[:, 1] <= p[1]) & (uv_hi[:, 1] >= p[1]))
        crossings = 0
        if near.size:
            t = local[near]
            a = t[:, 0]
            ab, ac = t[:, 1] - a, t[:, 2] - a
            ap0, ap1 = p[0] - a[:, 0], p[1] - a[:, 1]
            # barycentric coordinates of p in the projected triangle
            d = ab[:, 0] * ac[:, 1] - ac[:, 0] * ab[:, 1]
            w1 = ap0 * ac[:, 1] - ac[:, 0] * ap1
            w2 = ab[:, 0] * ap1 - ap0 * ab[:, 1]
            with np.errstate(divide="ignore", invalid="ignore"):
                s1, s2 = w1 / d, w2 / d
            hit = (d != 0) & (s1 >= 0) & (s2 >= 0) & (s1 + s2 <= 1)
            z = a[:, 2] + s1 * ab[:, 2] + s2 * ac[:, 2]
            ahead = hit & (z > p[2])
            crossings = int(np.sign(d[ahead]).sum())
        votes += crossings != 0
    return 2 * votes > len(frames)
