"""Load paths: the stress solver on the link graph of founded structures.

A founded (fixed) body carries its own weight through its links to its
foundation voxels. The solve runs on a coarse graph, like NVIDIA Blast's stress
solver on its support chunks: voxels are grouped into nodes (the connected
voxels of one chunk within one cell of a grid k voxels wide, k chosen so that a
body has at most :data:`TARGET_NODES` cells; foundation voxels apart), and the
alive links between two nodes form one interface. An interface along a chunk
boundary is a staircase of voxel faces: each face counts with its area projected
across the interface's direction (its vector area), so the section is the
member's whatever the steps. Each node is a rigid element with six
degrees of freedom (translation and rotation about its centre of mass); each
interface is a set of springs at its area centroid, the rigid-body-spring model
of Kawai (1978, "New discrete models and their application to seismic response
analysis of structures", Nucl. Eng. Des. 48): normal k_n = sum(E a) / L, shear
k_s = k_n / (2 (1 + nu)), bending sum(E (a y y' + a^2/12)) / L over the
interface's links at offsets y from its centroid (the section's second moment,
parallel axis theorem), torsion the same with the polar moment. A single link
(k = 1) is a beam of its own square face (I = a^2 / 12, J = 0.1406 a^2).

Under gravity the structure is in static equilibrium: K q = f, with f the
nodes' weights and q = 0 at foundation nodes; K is symmetric positive definite
and solved directly (SuperLU, :mod:`scipy.sparse`). Each link of an interface
then takes beam theory's stresses over the section:

    sigma_n = E (delta_n + (phi x y) . d) / L         (axial and section bending)
    sigma_t = sigma_n + E |phi_perp| s / (2 L)        (plus its own face's bending)
    sigma_c = -sigma_n + E |phi_perp| s / (2 L)
    tau = V / A + G |phi . d| (|y| + s / 2) / L       (shear and torsion)

with s = sqrt(a) the link's side. A link whose stress passes its material's
tensile, compressive or shear strength (:class:`blastvox.materials.Material`)
breaks. For a statically determinate structure (a cantilever, a column) the
stresses are exact statics at any k. Links inside a node are not checked: cracks
run along node boundaries, as Blast's run along its chunks' bonds.

Breaking is event by event (sequentially linear analysis, Rots et al. 2008,
"Sequentially linear analysis of fracture of quasi-brittle materials"): each
solve breaks only the links within :data:`EVENT_BAND` of the worst overload, and
the body is solved again on the next step, so a crack grows across a section
and an undermined structure comes down progressively. Only bodies whose voxels
or links changed are solved again.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from blastvox.geometry import exact
from blastvox.jit import helper, kernel
from blastvox.simulate.springs import LinkSprings, SpringTable, has_limits
from blastvox.simulate.springs import link_springs as link_springs

if TYPE_CHECKING:
    from blastvox.simulate.contact.loads import SustainedLoads

#: Poisson's ratio of the shear springs (concrete 0.2; the solve is not sensitive to it).
POISSON = 0.2
#: Torsion constant of a square section over a^2 (J = 0.1406 s^4; Roark, Table 10.7).
TORSION_J = 0.1406
#: Each solve breaks the overloaded links whose utilization is within this fraction
#: of the worst: one crack front per step, not every link past its limit at once.
EVENT_BAND = 0.8
#: Most nodes of one solve: the grid cell k (voxels) grows until the solve has at most
#: this many (the cost of the sparse solve grows faster than linearly with it).
TARGET_NODES = 300


class Graph(NamedTuple):
    """The coarse graph of one solve.

    node (N,) int64: each voxel's node (-1 outside the solve); node_mass (M,) kg,
    node_com (M, 3) m, node_fixed (M,) bool; pair (K, 2) the nodes of each
    interface (first < second); centroid (K, 3) m, direction (K, 3) unit first to
    second, area (K,) m^2, length (K,) m: distance between the node centres along
    the direction; trans, rot (K, 3, 3): translational (N/m) and rotational
    (N m/rad) spring tensors; links (J,) the alive links across interfaces and
    link_interface (J,), link_sign (J,) +1 if the link points first to second,
    link_facing (J,) the cosine between the link's face normal (first to second) and
    its interface's direction, clipped to [0, 1]: how much of its face lies across it."""

    node: np.ndarray
    node_mass: np.ndarray
    node_com: np.ndarray
    node_fixed: np.ndarray
    pair: np.ndarray
    centroid: np.ndarray
    direction: np.ndarray
    area: np.ndarray
    length: np.ndarray
    trans: np.ndarray
    rot: np.ndarray
    links: np.ndarray
    link_interface: np.ndarray
    link_sign: np.ndarray
    link_facing: np.ndarray


def cell_size(voxel_count: int) -> int:
    """Grid cell k (voxels per side) for a solve of ``voxel_count`` voxels."""
    return max(1, math.ceil((voxel_count / TARGET_NODES) ** (1.0 / 3.0) - 1e-9))


def coarse_graph(springs: LinkSprings, link_voxels: np.ndarray, voxel_in: np.ndarray,
                 fixed: np.ndarray, link_alive: np.ndarray, voxel_key: np.ndarray,
                 mass: np.ndarray, centroid: np.ndarray) -> Graph:
    """Group the voxels flagged in voxel_in (N,) into nodes by ``voxel_key`` (N, 6)
    (body, foundation flag, chunk, cell i, j, k; int32, :func:`node_key`) and
    connectivity, and the alive links between nodes into interfaces. mass (N,) kg and
    centroid (N, 3) m of the voxels."""
    n = len(voxel_in)
    m = int(np.count_nonzero(voxel_in))  # every voxel, or the flagged ones (no copies)
    inside = slice(None) if m == n else np.flatnonzero(voxel_in)
    labels = np.empty(m, dtype=np.int32)
    count, across = node_labels(np.ascontiguousarray(link_voxels, dtype=np.int32), link_alive,
                                voxel_in, np.ascontiguousarray(voxel_key, dtype=np.int32),
                                labels)  # int32 as the model's: one kernel
    node = np.full(n, -1, dtype=np.int64)
    node[inside] = labels
    node_mass = np.bincount(labels, weights=mass[inside], minlength=count)
    node_com = np.stack([np.bincount(labels, weights=mass[inside] * centroid[inside, i],
                                     minlength=count) for i in range(3)], axis=1)
    node_com /= np.maximum(node_mass, 1e-300)[:, None]
    node_fixed = np.bincount(labels, weights=fixed[inside].astype(np.float64),
                             minlength=count) > 0
    na, nb = node[link_voxels[across, 0]], node[link_voxels[across, 1]]
    sign = np.where(na < nb, 1.0, -1.0)
    first, second = np.minimum(na, nb), np.maximum(na, nb)
    pairs, interface = np.unique(first * count + second, return_inverse=True)
    interface = interface.ravel()
    pair = np.stack([pairs // count, pairs % count], axis=1)
    trans, rot, centre, direction, area, length, facing = _interfaces(
        springs, across, interface, sign, len(pairs), pair, node_com)
    return Graph(node, node_mass, node_com, node_fixed, pair, centre, direction, area, length,
                 trans, rot, across, interface, sign, facing)


#: Graphs up to this many nodes are labelled with NumPy (SciPy's call costs more)
SMALL_GRAPH = 512


def components(m: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of m nodes joined by edges (a[i], b[i]): their count and
    each node's label (m,), numbered in the order of each component's smallest node,
    as scipy.sparse.csgraph.connected_components numbers them: large graphs by
    union-find (:func:`union_find_labels`), small ones (an impact's few voxels) by
    minimum-label propagation with pointer jumping."""
    if m > SMALL_GRAPH:
        labels = np.empty(m, dtype=np.int32)
        count = union_find_labels(m, np.ascontiguousarray(a, dtype=np.int64),
                                  np.ascontiguousarray(b, dtype=np.int64), labels)
        return int(count), labels
    label = np.arange(m)
    while True:
        low = np.minimum(label[a], label[b])
        lower = label.copy()
        np.minimum.at(lower, a, low)
        np.minimum.at(lower, b, low)
        lower = lower[lower]  # each label is a node of its component: jump to its label
        if np.array_equal(lower, label):
            break
        label = lower
    roots, labels = np.unique(label, return_inverse=True)
    return len(roots), labels.astype(np.int32)


@helper
def _union(parent, x, y) -> None:
    """Join the sets of x and y, the smaller root kept, halving paths on the way."""
    while parent[x] != x:  # path halving
        parent[x] = parent[parent[x]]
        x = parent[x]
    while parent[y] != y:
        parent[y] = parent[parent[y]]
        y = parent[y]
    if x < y:
        parent[y] = x
    elif y < x:
        parent[x] = y


@helper
def _number(parent, labels) -> int:
    """Write each node's component label to labels (m,), numbered in the order of each
    component's smallest node (SciPy's numbering; every root is its set's smallest
    node), and return their count."""
    count = 0
    for i in range(parent.shape[0]):
        r = parent[i]
        while parent[r] != r:
            r = parent[r]
        parent[i] = r
        if r == i:
            labels[i] = count
            count += 1
        else:
            labels[i] = labels[r]
    return count


@kernel
def union_find_labels(m, a, b, labels) -> int:
    """Connected components of m nodes joined by edges (a[i], b[i]) (int64): writes each
    node's label to labels (m,) int32, numbered in the order of each component's
    smallest node (SciPy's numbering), and returns their count. Union-find with the
    smaller root kept and path halving: linear memory (SciPy's connected_components
    built a symmetric sparse matrix, 117 MB at a million voxels)."""
    parent = np.arange(m)
    for e in range(a.shape[0]):
        _union(parent, a[e], b[e])
    return _number(parent, labels)


@kernel
def node_labels(link_voxels, link_alive, voxel_in, key, labels):
    """The nodes of :func:`coarse_graph`: the voxels flagged in voxel_in (N,) joined by
    their alive links (link_alive (L,), link_voxels (L, 2)) whose two ends have the
    same key (N, K), in components (:func:`components`' labels, into labels (M,) int32,
    the M flagged voxels in order). Returns their count and the alive links between two
    keys (J,), ascending: the interfaces' links. One pass over the links, nothing per
    link kept but those (the gathers of both ends' keys and the edge lists took 200 MB
    at a million voxels)."""
    place = np.empty(voxel_in.shape[0], dtype=np.int64)  # each flagged voxel's among them
    m = 0
    for v in range(voxel_in.shape[0]):
        place[v] = m
        if voxel_in[v]:
            m += 1
    parent = np.arange(labels.shape[0])
    between = 0
    for link in range(link_voxels.shape[0]):
        a, b = link_voxels[link, 0], link_voxels[link, 1]
        if not (link_alive[link] and voxel_in[a] and voxel_in[b]):
            continue
        if _same_key(key, a, b):
            _union(parent, place[a], place[b])
        else:
            between += 1
    across = np.empty(between, dtype=np.int64)
    j = 0
    for link in range(link_voxels.shape[0]):
        a, b = link_voxels[link, 0], link_voxels[link, 1]
        if link_alive[link] and voxel_in[a] and voxel_in[b] and not _same_key(key, a, b):
            across[j] = link
            j += 1
    return _number(parent, labels), across


@helper
def _same_key(key, a, b) -> bool:
    """Do voxels a and b have the same key (a row of key (N, K))?"""
    for c in range(key.shape[1]):
        if key[a, c] != key[b, c]:
            return False
    return True


def _interfaces(springs: LinkSprings, links: np.ndarray, interface: np.ndarray,
                sign: np.ndarray, count: int, pair: np.ndarray, node_com: np.ndarray):
    """Each interface's spring tensors, centroid, direction, area, length, and each of
    its links' facing (see :class:`Graph`).

    An interface between chunks is a staircase of voxel faces, not a plane section:
    its direction is its vector area (the sum of its faces' areas times their normals,
    first node to second), and each face counts with its area projected across that
    direction (area x facing), so the section's area and second moment are those of
    the member the interface cuts, whatever the steps (a face along the member, a
    riser of the staircase, carries none of its axial load). A plane interface is
    unchanged (facing 1)."""
    a_full = springs.area[links]
    e = springs.modulus[links]

    def total(values: np.ndarray) -> np.ndarray:
        if values.ndim == 1:
            return np.bincount(interface, weights=values, minlength=count).astype(np.float64)
        flat = values.reshape(len(values), int(np.prod(values.shape[1:])))
        out = np.stack([np.bincount(interface, weights=flat[:, i], minlength=count)
                        for i in range(flat.shape[1])], axis=1).astype(np.float64)
        return out.reshape((count,) + values.shape[1:])

    normal = sign[:, None] * springs.direction[links]
    direction = total(a_full[:, None] * normal)
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-300)
    d = direction[interface]
    facing = np.clip(np.einsum("ij,ij->i", normal, d), 0.0, 1.0)
    a = np.maximum(a_full * facing, 1e-12 * a_full)  # a riser keeps a token stiffness
    area = total(a)
    centre = total(a[:, None] * springs.midpoint[links]) / area[:, None]
    span = node_com[pair[:, 1]] - node_com[pair[:, 0]]
    length = np.maximum(np.abs(np.einsum("ij,ij->i", span, direction)), 1e-9)
    offset = springs.midpoint[links] - centre[interface]
    offset -= np.einsum("ij,ij->i", offset, d)[:, None] * d
    lever = np.cross(offset, d)
    eye = np.eye(3)
    shear_modulus = e / (2.0 * (1.0 + POISSON))
    bend = np.empty((count, 3, 3))
    for p in range(3):  # entry by entry: the links' (J, 3, 3) tensors took 65 MB at a
        for q in range(3):  # million voxels
            plane = eye[p, q] - d[:, p] * d[:, q]
            bend[:, p, q] = total(e * (a * lever[:, p] * lever[:, q]
                                       + (a * a_full / 12.0) * plane))
    twist = total(shear_modulus * (a * np.einsum("ij,ij->i", offset, offset)
                                   + TORSION_J * a * a_full))
    k_normal = total(e * a) / length
    k_shear = total(shear_modulus * a) / length
    dd = direction[:, :, None] * direction[:, None, :]
    trans = k_normal[:, None, None] * dd + k_shear[:, None, None] * (eye[None] - dd)
    rot = bend / length[:, None, None] + (twist / length)[:, None, None] * dd
    return (np.ascontiguousarray(trans), np.ascontiguousarray(rot), np.ascontiguousarray(centre),
            np.ascontiguousarray(direction), area, length, np.ascontiguousarray(facing))


@kernel
def _jacobian(centroid, node_com, pair, k, jac) -> None:
    """jac (3, 12): the relative displacement, second node minus first, at the
    centroid of interface k from (u_a, theta_a, u_b, theta_b):
    delta = u_b + theta_b x r_b - u_a - theta_a x r_a."""
    jac[:] = 0.0
    ia, ib = pair[k, 0], pair[k, 1]
    rax = centroid[k, 0] - node_com[ia, 0]
    ray = centroid[k, 1] - node_com[ia, 1]
    raz = centroid[k, 2] - node_com[ia, 2]
    rbx = centroid[k, 0] - node_com[ib, 0]
    rby = centroid[k, 1] - node_com[ib, 1]
    rbz = centroid[k, 2] - node_com[ib, 2]
    for i in range(3):
        jac[i, i] = -1.0
        jac[i, 6 + i] = 1.0
    # theta x r = -[r]x theta, so +[r_a]x for the first node, -[r_b]x for the second
    jac[0, 4], jac[0, 5] = -raz, ray
    jac[1, 3], jac[1, 5] = raz, -rax
    jac[2, 3], jac[2, 4] = -ray, rax
    jac[0, 10], jac[0, 11] = rbz, -rby
    jac[1, 9], jac[1, 11] = -rbz, rbx
    jac[2, 9], jac[2, 10] = rby, -rbx


@kernel
def assemble(graph, dof) -> tuple:
    """The stiffness matrix of the K interfaces of ``graph`` (:class:`Graph`) in COO
    triplets (rows, cols, values).

    dof (M,): each node's block (its six unknowns are 6 dof .. 6 dof + 5), -1 for a
    fixed node. Units N/m, N/rad and N m/rad about the nodes' centres of mass."""
    centroid, node_com, pair, trans, rot = (graph.centroid, graph.node_com, graph.pair,
                                            graph.trans, graph.rot)
    n = pair.shape[0]
    rows = np.empty(n * 144, dtype=np.int64)
    cols = np.empty(n * 144, dtype=np.int64)
    vals = np.empty(n * 144)
    jac = np.empty((3, 12))
    block = np.empty((12, 12))
    index = np.empty(12, dtype=np.int64)
    out = 0
    for k in range(n):
        _jacobian(centroid, node_com, pair, k, jac)
        for p in range(12):  # J^T C J, by hand (numba's @ would need BLAS)
            for q in range(12):
                total = 0.0
                for r in range(3):
                    for t in range(3):
                        total += jac[r, p] * trans[k, r, t] * jac[t, q]
                block[p, q] = total
        for p in range(3):  # rotations: phi = theta_b - theta_a
            for q in range(3):
                block[3 + p, 3 + q] += rot[k, p, q]
                block[9 + p, 9 + q] += rot[k, p, q]
                block[3 + p, 9 + q] -= rot[k, p, q]
                block[9 + p, 3 + q] -= rot[k, p, q]
        da, db = dof[pair[k, 0]], dof[pair[k, 1]]
        for p in range(6):
            index[p] = 6 * da + p if da >= 0 else -1
            index[6 + p] = 6 * db + p if db >= 0 else -1
        for p in range(12):
            if index[p] < 0:
                continue
            for q in range(12):
                if index[q] >= 0:
                    rows[out], cols[out], vals[out] = index[p], index[q], block[p, q]
                    out += 1
    return rows[:out], cols[:out], vals[:out]


@kernel
def link_stresses(springs, graph, dof, q, out) -> None:
    """Fill ``out`` (J, 4) with each interface link's largest tensile, compressive and
    shear stress (Pa) and its utilization, the largest of the three over its limit.

    springs: the :class:`LinkSprings` of the J links ``graph.links``, row by row;
    graph: the solve's :class:`Graph`; q (6 M',): the solved displacements (m) and
    rotations (rad) of the free nodes (dof, as for :func:`assemble`)."""
    jac = np.empty((3, 12))
    x = np.zeros(12)
    delta = np.zeros(3)
    phi = np.zeros(3)
    force = np.zeros(3)
    y = np.zeros(3)
    for j in range(graph.links.shape[0]):
        k = graph.link_interface[j]
        _jacobian(graph.centroid, graph.node_com, graph.pair, k, jac)
        da, db = dof[graph.pair[k, 0]], dof[graph.pair[k, 1]]
        for p in range(6):
            x[p] = q[6 * da + p] if da >= 0 else 0.0
            x[6 + p] = q[6 * db + p] if db >= 0 else 0.0
        for r in range(3):
            delta[r] = 0.0
            for p in range(12):
                delta[r] += jac[r, p] * x[p]
            phi[r] = x[9 + r] - x[3 + r]
        for r in range(3):
            force[r] = 0.0
            for t in range(3):
                force[r] += graph.trans[k, r, t] * delta[t]
        d = graph.direction[k]
        stretch = delta[0] * d[0] + delta[1] * d[1] + delta[2] * d[2]
        axial = force[0] * d[0] + force[1] * d[1] + force[2] * d[2]
        phi_n = phi[0] * d[0] + phi[1] * d[1] + phi[2] * d[2]
        sliding = 0.0
        bend = 0.0
        for r in range(3):
            sliding += (force[r] - axial * d[r]) ** 2
            bend += (phi[r] - phi_n * d[r]) ** 2
            y[r] = springs.midpoint[j, r] - graph.centroid[k, r]
        along = y[0] * d[0] + y[1] * d[1] + y[2] * d[2]
        for r in range(3):
            y[r] -= along * d[r]
        turn = ((phi[1] * y[2] - phi[2] * y[1]) * d[0] + (phi[2] * y[0] - phi[0] * y[2]) * d[1]
                + (phi[0] * y[1] - phi[1] * y[0]) * d[2])  # (phi x y) . d
        e = springs.modulus[j]
        side = math.sqrt(springs.area[j])
        span = graph.length[k]
        # the member's axial stress on a face turned by facing c: c^2 of it is normal
        c = graph.link_facing[j]
        normal = e * (stretch + turn) / span * c * c
        own = e * math.sqrt(bend) * side / (2.0 * span) * c
        radius = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) + 0.5 * side
        tau = (math.sqrt(sliding) / graph.area[k]
               + e / (2.0 * (1.0 + POISSON)) * abs(phi_n) * radius / span)
        tension = normal + own
        compression = -normal + own
        out[j, 0], out[j, 1], out[j, 2] = tension, compression, tau
        out[j, 3] = max(tension / springs.tensile[j],
                        compression / springs.compressive[j], tau / springs.shear[j])


class Solution(NamedTuple):
    """One solve: links (J,) the interface links, stress (J, 4) their largest tensile,
    compressive and shear stress (Pa) and utilization (see :func:`link_stresses`);
    nodes: the solve's node count."""

    links: np.ndarray
    stress: np.ndarray
    nodes: int


def solve(springs: LinkSprings, link_voxels: np.ndarray, voxel_in: np.ndarray,
          fixed: np.ndarray, link_alive: np.ndarray, voxel_key: np.ndarray,
          mass: np.ndarray, centroid: np.ndarray, gravity: np.ndarray,
          bearing: tuple[np.ndarray, np.ndarray] | None = None,
          load: np.ndarray | None = None) -> Solution:
    """Static equilibrium under gravity (3,) m/s^2 of the voxels flagged in voxel_in
    (N,), those flagged in fixed (N,) held still; only alive links (L,) carry load.
    voxel_key (N, 6): see :func:`coarse_graph`. Every component must hold a fixed voxel.

    ``bearing`` (voxels (S,), points (S, 3) m): the fixed voxels are what the body
    rests on, not what it is bonded to, touching its support at those S points, each
    of one of them; each holds the body only by pushing
    (:func:`blastvox.simulate.equilibrium.resting`): a deck on two piers spans
    between them as a simply supported beam instead of being clamped over them.

    ``load`` (N, 3) N: forces on the voxels besides their weights (what resting pieces
    push into a founded body: :class:`~blastvox.simulate.contact.loads.SustainedLoads`)."""
    from blastvox.simulate.equilibrium import equilibrium, node_loads, resting

    g = coarse_graph(springs, link_voxels, voxel_in, fixed, link_alive, voxel_key, mass,
                     centroid)
    stress = np.zeros((len(g.links), 4))
    if bearing is not None:
        held = np.zeros(len(g.node_fixed), dtype=bool)
        found = resting(g, bearing[0], bearing[1], gravity)
    else:
        held = g.node_fixed
        found = equilibrium(g, held, gravity, load=None if load is None
                            else node_loads(g, load, centroid))
    if found is None:
        return Solution(g.links, stress, len(held))
    dof, q = found
    link_stresses(springs.rows(g.links), g, dof, q, stress)
    return Solution(g.links, stress, len(held))


def overloaded(solution: Solution) -> np.ndarray:
    """Link ids to break after a solve: utilization above 1 and within
    :data:`EVENT_BAND` of the worst (one crack front at a time)."""
    use = solution.stress[:, 3]
    if not len(use) or not (use > 1.0).any():
        return np.zeros(0, dtype=np.int64)
    worst = float(use.max())
    return solution.links[(use > 1.0) & (use >= EVENT_BAND * worst)]


@dataclass
class Stress:
    """The stress solver's memory over a run: springs (the model's links', worked out on
    demand: :class:`~blastvox.simulate.springs.SpringTable`), cell (N, 3)
    each voxel's lattice index, chunk (N,) its chunk or None, solved (B,) bodies whose
    current solution is known (a body's voxels or links changed: it is solved again),
    and run totals (solves, seconds of wall time, links broken, the worst utilization
    of the last solve). survived and rubble, by body until its voxels or links change:
    the largest impact it survived (:mod:`blastvox.simulate.impact`), and its live
    voxel count when it is one chunk of a crushing material (no impact can break it);
    rested, by body: (live voxels, contact voxels, on the ground) of the support it was
    last judged on, and judged: by the set of supporting voxels (sorted, as bytes) it
    stood on since its voxels last changed, the rest-frame gravity vectors (3,) it
    stood under (:mod:`blastvox.simulate.support`)."""

    springs: SpringTable
    cell: np.ndarray
    chunk: np.ndarray | None
    solved: np.ndarray
    solves: int = 0
    seconds: float = 0.0
    broken: int = 0
    peak: dict = field(default_factory=dict)
    survived: dict = field(default_factory=dict)
    rubble: dict = field(default_factory=dict)
    rested: dict = field(default_factory=dict)
    judged: dict = field(default_factory=dict)


def start(arrays: dict, capacity: int, enabled: bool) -> Stress | None:
    """The run's stress solver, or None where the scene needs none (off, or no link
    with a finite strength)."""
    if not enabled:
        return None
    springs = SpringTable(arrays)
    if not has_limits(springs):
        return None
    chunk = arrays.get("voxel_chunk")
    # the model's int32 arrays, shared (node_key widens what it keys on)
    return Stress(springs=springs, cell=np.asarray(arrays["voxel_ijk"], dtype=np.int32),
                  chunk=None if chunk is None else np.asarray(chunk, dtype=np.int32),
                  solved=np.zeros(capacity, dtype=bool))


def node_key(cell: np.ndarray, chunk: np.ndarray | None, voxel_body: np.ndarray,
             fixed: np.ndarray, voxel_in: np.ndarray) -> np.ndarray:
    """Each voxel's node key (N, 6) int32 for :func:`coarse_graph`: body, foundation flag,
    chunk and the grid cell (N, 3) of :func:`cell_size`; (N, 5) without the chunk where
    the model has none, or the solve more than :data:`TARGET_NODES` of them.

    A node is the part of a chunk within a cell: every chunk boundary is a node
    boundary (a crack runs along it), and a chunk larger than a cell is cut by the
    cells, so a member's section is resolved as well as without chunks (a chunk as one
    rigid node put its boundary, not the member's section, where the stress is read:
    a cantilever's root read 0.6-0.7 x beam theory)."""
    count = int(np.count_nonzero(voxel_in))
    chunked = chunk is not None and np.unique(chunk[voxel_in]).size <= TARGET_NODES
    key = np.empty((len(voxel_body), 5 + chunked), dtype=np.int32)  # 24 MB at a million
    key[:, 0] = voxel_body
    key[:, 1] = fixed
    if chunked:
        key[:, 2] = chunk
    k = cell_size(count)
    for axis in range(3):
        key[:, 2 + chunked + axis] = cell[:, axis] // k
    return key


def voxel_links(model, members: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every link of the voxels ``members`` (K,) from the model's CSR, once per end among
    them: link ids (J,) and the member each was listed for (J,)."""
    offsets, ids = model.voxels.link_offsets, model.voxels.link_ids
    starts, counts = offsets[members], offsets[members + 1] - offsets[members]
    first = np.repeat(starts - np.cumsum(counts) + counts, counts)
    return ids[first + np.arange(int(counts.sum()))], np.repeat(members, counts)


def links_among(model, members: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The links with both ends among ``members`` (ascending voxel ids): their ids
    (K,), ascending, and their ends renumbered as places in ``members`` (K, 2). A
    small body's solve then costs what it holds, not what the model holds."""
    links = np.unique(voxel_links(model, members)[0])
    ends = model.links.voxels[links]
    place = np.minimum(np.searchsorted(members, ends), len(members) - 1)
    within = (members[place] == ends).all(axis=1)
    return links[within], place[within]


def solve_body(model, state, stress: Stress, members: np.ndarray, links: np.ndarray,
               ends: np.ndarray, fixed: np.ndarray, gravity: np.ndarray,
               bearing: tuple[np.ndarray, np.ndarray] | None = None) -> Solution:
    """:func:`solve` of one body alone: its live voxels ``members`` (K,), its links
    (``links``, ``ends`` renumbered into members: :func:`links_among`), ``fixed`` (K,)
    the voxels held (or, with ``bearing``, rested on), under ``gravity`` (3,) m/s^2 in
    its rest frame."""
    voxel_in = np.ones(members.size, dtype=bool)
    chunk = None if stress.chunk is None else stress.chunk[members]
    key = node_key(stress.cell[members], chunk, state.voxels.body[members], fixed, voxel_in)
    springs = stress.springs.rows(links)
    stress.solves += 1
    return solve(springs, ends, voxel_in, fixed, state.links.alive[links], key,
                 model.voxels.mass[members], model.voxels.centroid[members], gravity,
                 bearing=bearing)


def stress_phase(model, state, stress: Stress, gravity: np.ndarray,
                 sustained: SustainedLoads | None = None) -> bool:
    """Phase: solve the founded bodies whose voxels, links or contact loads changed since
    their last solve, and mark the overloaded links broken (state.marks.broken, bodies
    dirty). ``sustained``: what resting pieces push into them
    (:class:`~blastvox.simulate.contact.loads.SustainedLoads`), or None.

    Reads bodies (live, fixed, dust), voxels (body, alive, foundation) and the
    model's masses; writes links.alive, marks.broken, marks.dirty, stress.solved and
    counters.broken_links.
    Returns whether any link broke (the caller splits)."""
    bodies, voxels = state.bodies, state.voxels
    n = state.n_bodies
    todo = bodies.live[:n] & bodies.fixed[:n] & ~bodies.dust[:n] & ~stress.solved[:n]
    if not todo.any():
        return False
    started = time.perf_counter()
    gravity_on = float(exact.dot(gravity, gravity)) > 0.0
    if not gravity_on:
        stress.solved[:n] |= todo
        return False
    target = np.zeros(len(stress.solved), dtype=bool)
    target[:n] = todo
    voxel_in = voxels.alive & target[voxels.body]
    fixed = voxels.foundation & voxels.alive
    key = node_key(stress.cell, stress.chunk, voxels.body, fixed, voxel_in)
    load = None if sustained is None else sustained.force
    solution = solve(stress.springs, model.links.voxels, voxel_in, fixed, state.links.alive,
                     key, model.voxels.mass, model.voxels.centroid, gravity, load=load)
    if load is not None:
        sustained.solved(voxel_in)
    stress.solves += 1
    stress.solved[:n] |= todo
    broken = overloaded(solution)
    if len(solution.links):
        worst = int(np.argmax(solution.stress[:, 3]))
        stress.peak = {"utilization": float(solution.stress[worst, 3]),
                       "link": int(solution.links[worst]), "nodes": solution.nodes}
    stress.seconds += time.perf_counter() - started
    if not broken.size:
        return False
    stress.broken += int(broken.size)
    state.counters.broken_links += int(broken.size)
    state.links.alive[broken] = False
    state.marks.broken[broken] = True
    owners = voxels.body[model.links.voxels[broken, 0]]
    state.marks.dirty[:n] = False  # what earlier phases flagged was split already
    state.marks.dirty[owners] = True
    stress.solved[owners] = False  # solved again after the split
    return True


def invalidate(stress: Stress, voxel_body: np.ndarray, link_voxels: np.ndarray,
               broken: np.ndarray, destroyed: np.ndarray) -> None:
    """After a split: the bodies that now hold the ends of ``broken`` links or
    ``destroyed`` voxels must be solved again (new bodies are unsolved already)."""
    changed = np.concatenate([voxel_body[link_voxels[broken].ravel()], voxel_body[destroyed]])
    stress.solved[changed] = False
    for b in np.unique(changed).tolist():
        stress.survived.pop(b, None)
        stress.rubble.pop(b, None)
        stress.rested.pop(b, None)
        stress.judged.pop(b, None)


def break_links(state, stress: Stress, b: int, broken: np.ndarray) -> None:
    """Break body b's links ``broken``: alive, marks (broken, dirty) and both counts."""
    stress.broken += int(broken.size)
    state.counters.broken_links += int(broken.size)
    state.links.alive[broken] = False
    state.marks.broken[broken] = True
    state.marks.dirty[b] = True

