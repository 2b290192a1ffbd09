"""The linear solve of the stress solver's graph: held nodes and bearing springs.

:func:`equilibrium` solves K q = f for a :class:`blastvox.simulate.stress.Graph`
under gravity with some nodes held still (a founded structure's foundations).
:func:`resting` solves a body that rests on something instead of being bonded to
it: each contact point holds it by a spring on its translation that only pushes
(a support that would pull the body down lets go; one let go that would sink into
its support holds again), so a deck on two piers pivots on their inner edges and
spans between them, as beam theory's simply supported beam, instead of being
clamped over its bearings.

A body its supports do not hold still (its weight outside them: it pivots on one
edge, or on one point) has no static equilibrium: K is singular along the rigid
motions they leave free. Such a body is solved with inertia relief (MSC Nastran's
INREL; Barnett & Reed, "Inertia relief", 1969 NASA CR): its nodes carry the
d'Alembert loads of the rigid acceleration the unbalanced weight gives it, so its
links read the stresses of the instant it starts to turn (a bar on a pivot at one
end: w L^2 / 27 at a third of its length, :data:`RELIEF`), not the round-off of a
singular factor (up to 1e5 times the strength before, in the building's rubble).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from blastvox.geometry import exact
from blastvox.simulate.stress import Graph, assemble

#: Most rounds of letting supports go (or hold again) in a bearing solve.
BEARING_ROUNDS = 12
#: A bearing's stiffness across gravity, over its stiffness along it: a support
#: pushes, and holds the body in place only just enough for the solve (a rigid grip
#: at both ends of a deck would arch it: bottom fibres held apart, its span's
#: bending relieved). Beam theory's simply supported beam rolls on one end.
SLIDING = 1e-3
#: SuperLU's options for the stiffness matrix, symmetric positive definite once held:
#: a symmetric fill-reducing order (minimum degree on A^T + A) and pivots on the
#: diagonal. COLAMD's column order with partial pivoting filled L + U 2-3x more and
#: factored 2-5x slower on the city block's slabs (5,922 dofs: 0.087 s against 0.025-0.040 s).
SYMMETRIC_LU = {"permc_spec": "MMD_AT_PLUS_A", "diag_pivot_thresh": 0.0,
                "options": {"SymmetricMode": True}}
#: Inertia relief of a bearing solve: each node's translations are held by a spring of
#: stiffness its mass times RELIEF x the stiffest entry of K over the heaviest node's
#: mass. Along the rigid motions the supports leave free these springs are all there
#: is, and mass-proportional springs there are exactly the d'Alembert loads of that
#: rigid acceleration (the springs' stretch times the rate is the acceleration), which
#: rigid motions leave the links unstrained by; along the held motions they change
#: the solution by about RELIEF relative (their stiffness is a 1e-3 x K at least).
RELIEF = 1e-10


class BearingSprings(NamedTuple):
    """The support springs of a bearing solve, one per support voxel (S): node (S,)
    its node; jac (S, 3, 6) its centre's displacement from its node's (u, theta);
    tensor (S, 3, 3) its stiffness, N/m; down (3,) unit gravity."""

    node: np.ndarray
    jac: np.ndarray
    tensor: np.ndarray
    down: np.ndarray


def bearing_springs(g: Graph, voxels: np.ndarray, points: np.ndarray,
                     gravity: np.ndarray) -> BearingSprings:
    """A spring at each contact ``points`` (S, 3) m of the support ``voxels`` (S,), on
    the voxel's node: along gravity as stiff as the stiffest interface of the node
    shared among the node's contacts, :data:`SLIDING` of that across gravity."""
    down = gravity / max(float(exact.norm(gravity)), 1e-300)
    node = g.node[voxels]
    normal = np.einsum("kij,ki,kj->k", g.trans, g.direction, g.direction)
    stiffness = np.zeros(len(g.node_fixed))
    np.maximum.at(stiffness, g.pair[:, 0], normal)
    np.maximum.at(stiffness, g.pair[:, 1], normal)
    stiffness = np.where(stiffness > 0.0, stiffness, normal.max(initial=1.0))
    share = stiffness[node] / np.bincount(node, minlength=len(stiffness))[node]
    r = points - g.node_com[node]
    jac = np.zeros((len(voxels), 3, 6))
    jac[:, :, :3] = np.eye(3)
    # theta x r = -[r]x theta
    jac[:, 0, 4], jac[:, 0, 5] = r[:, 2], -r[:, 1]
    jac[:, 1, 3], jac[:, 1, 5] = -r[:, 2], r[:, 0]
    jac[:, 2, 3], jac[:, 2, 4] = r[:, 1], -r[:, 0]
    tensor = np.outer(down, down) * (1.0 - SLIDING) + SLIDING * np.eye(3)
    return BearingSprings(node, jac, share[:, None, None] * tensor[None], down)


def equilibrium(g: Graph, held: np.ndarray, gravity: np.ndarray,
                 bed: BearingSprings | None = None, engaged: np.ndarray | None = None,
                 load: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """(dof, q) of the graph's equilibrium under gravity with the nodes ``held`` (M,)
    still (see :func:`assemble`) and the ``engaged`` (S,) springs of ``bed``; None
    when nothing holds the graph or the system is singular (a part held by nothing).
    ``load``: external forces (M, 3) N on the nodes and their moments (M, 3) N m about
    the nodes' centres of mass (:func:`node_loads`), besides their weights."""
    from scipy.sparse import csc_matrix
    from scipy.sparse.linalg import splu

    free = ~held
    dof = np.full(len(free), -1, dtype=np.int64)
    dof[free] = np.arange(int(free.sum()))
    size = 6 * int(free.sum())
    on = np.zeros(0, dtype=np.int64) if bed is None else np.flatnonzero(engaged)
    if size == 0 or len(g.links) == 0 or not (held.any() or on.size):
        return None
    rows, cols, vals = assemble(g, dof)
    if on.size:  # J^T T J on each spring's node block
        block = np.einsum("sai,sab,sbj->sij", bed.jac[on], bed.tensor[on], bed.jac[on])
        base = 6 * dof[bed.node[on]][:, None] + np.arange(6)
        rows = np.concatenate([rows, np.repeat(base, 6, axis=1).ravel()])
        cols = np.concatenate([cols, np.tile(base, 6).ravel()])
        vals = np.concatenate([vals, block.ravel()])
    if bed is not None:
        rows, cols, vals = _relief(g, dof, free, rows, cols, vals)
    matrix = csc_matrix((vals, (rows, cols)), shape=(size, size))
    rhs = np.zeros(size)
    blocks = np.flatnonzero(free)
    for axis in range(3):
        rhs[6 * dof[blocks] + axis] = g.node_mass[blocks] * gravity[axis]
        if load is not None:
            rhs[6 * dof[blocks] + axis] += load[0][blocks, axis]
            rhs[6 * dof[blocks] + 3 + axis] += load[1][blocks, axis]
    try:
        return dof, splu(matrix, **SYMMETRIC_LU).solve(rhs)
    except RuntimeError:  # "Factor is exactly singular": a part let go of everything
        return None



def _relief(g: Graph, dof: np.ndarray, free: np.ndarray, rows: np.ndarray,
            cols: np.ndarray, vals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The COO triplets (rows, cols, vals) of K with the inertia relief springs of the
    ``free`` (M,) nodes (dof (M,): their blocks) on their translations (:data:`RELIEF`)."""
    nodes = np.flatnonzero(free)
    if not nodes.size or not vals.size:
        return rows, cols, vals
    rate = RELIEF * float(np.abs(vals).max()) / float(g.node_mass[nodes].max())
    index = (6 * dof[nodes][:, None] + np.arange(3)).ravel()
    return (np.concatenate([rows, index]), np.concatenate([cols, index]),
            np.concatenate([vals, rate * np.repeat(g.node_mass[nodes], 3)]))


def node_loads(g: Graph, force: np.ndarray, centroid: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """The graph's nodes' external loads from forces (N, 3) N on the voxels at centroid
    (N, 3) m (voxels outside the graph ignored): each node's force (M, 3) N and moment
    (M, 3) N m about its centre of mass, summed voxel by voxel in id order."""
    m = len(g.node_mass)
    on = np.flatnonzero((g.node >= 0) & (force != 0.0).any(axis=1))
    node, f = g.node[on], force[on]
    arm = centroid[on] - g.node_com[node]
    moment = np.stack([arm[:, 1] * f[:, 2] - arm[:, 2] * f[:, 1],
                       arm[:, 2] * f[:, 0] - arm[:, 0] * f[:, 2],
                       arm[:, 0] * f[:, 1] - arm[:, 1] * f[:, 0]], axis=1)
    return tuple(np.stack([np.bincount(node, weights=x[:, a], minlength=m)
                           for a in range(3)], axis=1) for x in (f, moment))


def resting(g: Graph, voxels: np.ndarray, points: np.ndarray, gravity: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray] | None:
    """(dof, q) of the graph resting on the contacts at ``points`` (S, 3) m of its
    ``voxels`` (S,) under gravity (3,) m/s^2, no node held: the bearing springs
    engaged, then let go or engaged again until none changes (at most
    :data:`BEARING_ROUNDS`); None when nothing holds it."""
    held = np.zeros(len(g.node_fixed), dtype=bool)
    bed = bearing_springs(g, voxels, points, gravity)
    engaged = np.ones(len(bed.node), dtype=bool)
    found = equilibrium(g, held, gravity, bed, engaged)
    for _ in range(BEARING_ROUNDS if found is not None else 0):
        dof, q = found
        sink = np.einsum("sij,sj->si", bed.jac, q[6 * dof[bed.node][:, None]
                                                  + np.arange(6)])
        sink = exact.dot(sink, bed.down)
        scale = max(float(np.abs(sink).max(initial=0.0)), 1e-300)
        changed = (engaged & ~(sink < -1e-9 * scale)) | (~engaged & (sink > 1e-9 * scale))
        if np.array_equal(changed, engaged) or not changed.any():
            break
        again = equilibrium(g, held, gravity, bed, changed)
        if again is None:
            break
        engaged, found = changed, again
    return found
