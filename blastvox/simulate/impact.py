"""Impact fracture: a body stopped hard by a contact is loaded by its own inertia.

A body whose momentum a step's contacts changed by a deceleration beyond
:data:`IMPACT_ACCELERATION` (a slab landing on an edge, a piece striking a wall)
is solved as a founded body is (:mod:`blastvox.simulate.stress`): its voxels carry
the d'Alembert inertia of the velocity change over the elastic contact time
2 L / c against the voxels that took the contact, and its links past their limits
break. Impacts break only links between chunks (a chunk never shatters).
"""

from __future__ import annotations

import math
import time

import numpy as np

from blastvox.geometry import exact
from blastvox.simulate.stress import Stress, break_links, links_among, solve_body

#: Contact decelerations below this (m/s^2, 20 g) are resting contact, not impacts.
IMPACT_ACCELERATION = 20.0 * 9.81
#: No impact below this velocity change (m/s): IMPACT_ACCELERATION over the shortest
#: contact time (a one-voxel body of the fastest material, 2e-4 s).
MIN_IMPACT_DV = IMPACT_ACCELERATION * 2e-4
#: An impact within this angle's cosine (10 degrees) of one a body survived, with the
#: same voxels, scales that solve (an elastic solve is linear in its load)...
SAME_SIDE = math.cos(math.radians(10.0))
#: ... and is solved again only if the scaled peak utilization reaches this.
RESOLVE_UTILIZATION = 0.8


def impact_phase(model, state, stress: Stress, lin_before: np.ndarray,
                 sustained: float) -> bool:
    """Phase: impact fracture. A free body whose momentum the contacts of this step
    changed by dp (N s, lin_before (B, 3) the momenta before the collide and ground
    phases) beyond what they take off every step to hold it up (``sustained``, m/s:
    the step's gravity g dt with its Coulomb friction, sqrt(1 + mu^2) g dt, and the
    contacts' resting speed) was stopped from dv = |dp| / m - sustained over a
    contact time tau = 2 L / c (L its
    length along dp, c the bar wave speed: the duration of an elastic rod's impact,
    Goldsmith 1960, "Impact", ch. 2): it decelerates at a = dv / tau. Its voxels
    carry the inertial load -m a to the voxels in contact (within one voxel of its
    face towards the contact), solved as for gravity; every link past its limit
    breaks, except links inside a chunk of a material that crushes (model.strength.inner):
    such a chunk is the smallest piece of rubble.
    The solve is linear in its load, so a body that survived a larger
    impact from the same side (:data:`SAME_SIDE`) with the same voxels is not
    solved again unless the scaled peak utilization reaches
    :data:`RESOLVE_UTILIZATION` (stress.survived). Weight is a sustained load, not an
    impact: a body resting or sliding on something is never judged, whatever dt
    (g dt / tau would grow with dt).

    Reads bodies and voxels; writes links.alive, marks.broken, marks.dirty and
    counters.broken_links. Returns whether any link broke (the caller splits)."""
    bodies, voxels = state.bodies, state.voxels
    n = len(lin_before)  # bodies split off since (by collisions) are not judged this step
    dp = bodies.lin[:n] - lin_before
    dv = np.sqrt(np.einsum("ij,ij->i", dp, dp)) / np.where(bodies.mass[:n] > 0.0,
                                                            bodies.mass[:n], np.inf) - sustained
    # a loose prefilter of _impact's own (a few ulps wider: vector and scalar norms)
    candidates = np.flatnonzero(bodies.live[:n] & ~bodies.fixed[:n] & ~bodies.dust[:n]
                                & (dv >= MIN_IMPACT_DV * (1.0 - 1e-9)))
    if not candidates.size:
        return False
    started = time.perf_counter()
    # the candidates' live voxels, grouped by body once (a one-voxel body has no link)
    owner = np.where(voxels.alive, voxels.body, -1)
    in_candidate = np.zeros(len(bodies.live) + 1, dtype=bool)  # [-1]: no body
    in_candidate[candidates] = True
    held = np.flatnonzero(in_candidate[owner])  # voxel order, as flatnonzero per body
    held = held[np.argsort(owner[held], kind="stable")]
    bounds = np.searchsorted(owner[held], np.append(candidates, n))
    any_broken = False
    for i, b in enumerate(candidates):
        members = held[bounds[i]:bounds[i + 1]]
        if members.size >= 2:
            any_broken |= _impact(model, state, stress, int(b), members, dp[b], sustained)
    stress.seconds += time.perf_counter() - started
    return any_broken


def _impact(model, state, stress: Stress, b: int, members: np.ndarray, dp: np.ndarray,
            sustained: float) -> bool:
    """Impact fracture of body b (its live voxels ``members``) under the contact impulse
    dp (3,) N s, world frame, of which ``sustained`` m/s of velocity change held it up."""
    bodies = state.bodies
    dv = float(exact.norm(dp)) / bodies.mass[b] - sustained
    if dv <= 0.0 or dv < MIN_IMPACT_DV or stress.rubble.get(b) == members.size:
        return False
    rest_dir = exact.vecmat(dp / exact.norm(dp), bodies.rot[b])  # R^T dp / |dp|
    along = exact.dot(model.voxels.centroid[members], rest_dir)
    size = 2.0 * float(np.median(model.voxels.contact_radius[members]))
    length = float(along.max() - along.min()) + size
    speed = float(np.average(model.wave_speed[model.material[members]],
                             weights=model.voxels.mass[members]))
    tau = 2.0 * length / speed
    acceleration = dv / tau
    if acceleration < IMPACT_ACCELERATION:
        return False
    known = stress.survived.get(b)
    if (known is not None and known[0] == members.size
            and float(exact.dot(known[1], rest_dir)) >= SAME_SIDE
            and known[3] * acceleration / known[2] < RESOLVE_UTILIZATION):
        return False
    links, ends = links_among(model, members)  # the body alone, renumbered
    if model.strength.inner[links].all():
        stress.rubble[b] = members.size  # one chunk of a material that crushes: nothing
        return False                     # an impact can break
    fixed = along <= along.min() + 0.5 * size
    solution = solve_body(model, state, stress, members, links, ends, fixed,
                          -acceleration * rest_dir)
    use = solution.stress[:, 3]
    between = ~model.strength.inner[links[solution.links]]  # a chunk never shatters
    broken = links[solution.links[(use > 1.0) & between]]
    if not broken.size:
        if known is None or acceleration > known[2]:
            peak = float(use[between].max(initial=0.0))
            stress.survived[b] = (members.size, rest_dir, acceleration, peak)
        return False
    stress.survived.pop(b, None)
    break_links(state, stress, b, broken)
    return True
