"""The run's momentum ledger: where the pieces' linear momentum came from.

Every step, the free pieces' total linear momentum (N s, world frame; pieces that are
not founded, dust included) is measured between the phases that change it, and each
change is booked to its cause:

- ``initial``: what the pieces had before a step, set by a caller (0 from the CLI);
- ``blast``: the wave's impulse on free pieces (and a confined charge's gas);
- ``released``: the impulse founded voxels took from a wave, handed to the pieces
  that break free of them in it (:func:`~blastvox.simulate.kernels.release_held`),
  and the wave's impulse on the face of a voxel it turned to dust, handed to its dust
  (in every fracture model, :func:`~blastvox.simulate.fracture.fracture_wave`);
- ``gravity_drag``: gravity and air drag;
- ``ground`` and ``foundations``: what contacts with the ground and with founded
  bodies gave the pieces (negative: what the pieces put into them);
- ``damping``: what resting contact takes off: resting-contact damping and the
  ground's balance test, which stops a body at rest on it (what the contact phase
  changed beyond the ground's and the founded bodies' rows: contacts between pieces
  cancel);
- ``sleep``: momentum zeroed when a piece falls asleep.

So ``pieces`` (the momentum at the end) equals the sum of the terms, by
construction; what a test or a user reads off it is where momentum went: a shot
whose debris rises with no upward ``blast`` had it from its contacts. Also
``blast_on_founded``: the wave's impulse on founded bodies (held by their voxels,
``released`` with the pieces that break free, the rest into the ground).

Sums run in numba kernels in a fixed order, so the ledger is byte-identical from
run to run (it is stored in the SimCache meta).
"""

from __future__ import annotations

import numpy as np

from blastvox.jit import kernel
from blastvox.simulate.contact.loads import row_impulse
from blastvox.simulate.integrate import moving

TERMS = ("initial", "blast", "released", "gravity_drag", "ground", "foundations", "damping",
         "sleep")


@kernel
def free_momentum(bodies, out) -> None:
    """out (3,): the total linear momentum (N s) of the live bodies that are not fixed."""
    out[:] = 0.0
    for b in range(bodies.count[0]):
        if bodies.live[b] and not bodies.fixed[b]:
            for a in range(3):
                out[a] += bodies.lin[b, a]


@kernel
def applied_blast(loads, bodies, out) -> None:
    """out (3,): the blast impulse (N s) :func:`integrate_velocities` gives this step
    (loads.impulse of the bodies it moves)."""
    out[:] = 0.0
    for b in range(bodies.count[0]):
        if moving(b, bodies.live, bodies.fixed, bodies.dust, bodies.asleep):
            for a in range(3):
                out[a] += loads.impulse[b, a]


@kernel
def founded_total(loads, out) -> None:
    """out (3,): the impulse (N s) founded voxels hold (loads.held_p summed, voxel by
    voxel in order: a voxel without a row holds nothing)."""
    out[:] = 0.0
    for v in range(loads.held_slot.shape[0]):
        s = loads.held_slot[v]
        if s >= 0:
            for a in range(3):
                out[a] += loads.held_p[s, a]


@kernel
def contact_momentum(rows, end, bodies, out) -> None:
    """out (2, 3): what the first ``end`` solved rows gave free bodies (N s) from the
    ground (row 0) and from fixed bodies (row 1); rows between free bodies cancel."""
    out[:] = 0.0
    j = np.empty(3)
    for r in range(end):
        for side in range(2):
            k, o = rows.body[r, side], rows.body[r, 1 - side]
            if k < 0 or bodies.fixed[k] or (o >= 0 and not bodies.fixed[o]):
                continue
            row_impulse(rows, r, side, j)
            for a in range(3):
                out[0 if o < 0 else 1, a] += j[a]


class Ledger:
    """A run's momentum ledger (see the module docstring): totals (term -> (3,) N s),
    the pieces' momentum at the last measure, and work arrays."""

    def __init__(self) -> None:
        self.totals = {term: np.zeros(3) for term in TERMS}
        self.founded = np.zeros(3)
        self.last = np.zeros(3)
        self._now = np.zeros(3)
        self._part = np.zeros(3)
        self._rows = np.zeros((2, 3))

    def measure(self, state) -> np.ndarray:
        """The pieces' momentum now (a view, valid until the next call)."""
        free_momentum(state.bodies, self._now)
        return self._now

    def book(self, state, term: str, *known: tuple[str, np.ndarray]) -> None:
        """Book the change since the last measure: ``known`` (term, (3,)) parts first,
        the rest to ``term``."""
        now = self.measure(state)
        change = now - self.last
        for name, part in known:
            self.totals[name] += part
            change -= part
        self.totals[term] += change
        self.last[:] = now

    def blast_applied(self, state) -> np.ndarray:
        """The blast impulse the velocity integration is about to give (a copy)."""
        applied_blast(state.loads, state.bodies, self._part)
        return self._part.copy()

    def founded_held(self, state) -> np.ndarray:
        """The impulse founded voxels hold now (a copy)."""
        founded_total(state.loads, self._part)
        return self._part.copy()

    def contacts(self, state, end: int) -> tuple[np.ndarray, np.ndarray]:
        """What the step's solved rows (the first ``end``) gave pieces from the ground
        and from founded bodies."""
        contact_momentum(state.contacts.memory.rows, end, state.bodies, self._rows)
        return self._rows[0].copy(), self._rows[1].copy()

    def meta(self) -> dict:
        """The ledger for the SimCache meta: each term and the pieces' momentum at the
        end, [x, y, z] N s."""
        out = {term: [float(x) for x in value] for term, value in self.totals.items()}
        out["blast_on_founded"] = [float(x) for x in self.founded]
        out["pieces"] = [float(x) for x in self.last]
        return out
