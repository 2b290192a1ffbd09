"""What a run's settings let the simulator honour, and one warning per limit it passes.

The simulator stays finite whatever the settings (the blast is integrated exactly
over any step, the rotation conserves |q|, L and the kinetic energy, drag decays
exponentially, ground contacts are speculative). Two things still depend on the
step being short enough for what moves in it:

* **Motion per step** (only with fragment collisions on): collisions are found
  between voxel spheres of diameter about one voxel at the end of each step,
  with no sweep in between. A fragment whose surface moves more than
  :data:`MOTION_LIMIT_VOXELS` voxels in a step sinks that deep into what it hits
  before the contact is found, and one moving two voxels passes through a thin
  wall unseen. Measured per moving body as (|v| + |omega| r) dt / s, with v its
  speed (m/s), omega its angular velocity (rad/s), r its bounding radius (m), dt
  the step (s) and s the model's typical voxel size (m, twice the median
  contact radius, i.e. the median volume^(1/3)). Ground contacts are
  speculative and do not depend on it.
* **Spin per step**: the rotation is sub-stepped so that it conserves energy
  (:mod:`blastvox.simulate.integrate`), up to
  :data:`~blastvox.simulate.integrate.MAX_SPIN_PER_STEP` rad of spin per step
  (|L| tr(I^-1) / 3 dt, which is |omega| dt for a body of isotropic inertia);
  beyond that it falls back to one explicit update whose energy is only bounded.

* **Penetration**: contacts hold bodies apart (speculative contacts, and a position
  pass that pushes interpenetrating ones apart; :mod:`blastvox.simulate.kernels`),
  but an impact faster than a contact looks ahead, or a load the solver cannot
  carry within its sweeps, leaves bodies inside each other or the ground. The
  contact solver records the deepest penetration of any step (m); deeper than
  :data:`PENETRATION_LIMIT_VOXELS` voxels, the run warns (unless the motion limit,
  whose advice is the same, has warned already).

A run measures them at every output frame on the moving bodies (live, free,
not dust, not asleep) and warns once per limit, at the end, with the worst
value, the limit and the step that would honour it, as a
:class:`~blastvox.errors.SimulationLimitWarning` (the CLI prints it as one
``blastvox: warning: ...`` line). A dt longer than the blast's positive phase is
*not* a limit: each step receives the exact integral of the pressure.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from blastvox.errors import SimulationLimitWarning
from blastvox.simulate.integrate import MAX_SPIN_PER_STEP
from blastvox.simulate.kernels import body_rotations
from blastvox.simulate.model import SimModel
from blastvox.simulate.settings import SimSettings
from blastvox.simulate.state import State

#: Voxels a fragment's surface may move per step when fragments collide.
MOTION_LIMIT_VOXELS = 0.5
#: Spin (rad) per step up to which the rotation conserves energy.
SPIN_LIMIT_RAD = MAX_SPIN_PER_STEP
#: Voxels bodies may sink into each other or the ground before a run warns.
PENETRATION_LIMIT_VOXELS = 0.5
#: The contact solver's default sub-steps (:class:`~blastvox.simulate.settings.SimSettings`).
DEFAULT_SUBSTEPS = SimSettings.contact_substeps


def voxel_size(contact_radius: np.ndarray) -> float:
    """The model's typical voxel size (m): twice the median contact radius (m).

    The median, not the minimum: conform cells clipped by the surface can be
    slivers that do not set the scale of a collision.
    """
    if contact_radius.size == 0:
        return 0.0
    return 2.0 * float(np.median(contact_radius))


def motion_per_step(speed: np.ndarray, spin: np.ndarray, radius: np.ndarray, dt: float,
                    size: float) -> np.ndarray:
    """Voxels a body's surface moves per step: (speed + spin radius) dt / size.

    speed (m/s), spin (|omega|, rad/s), radius (bounding radius, m) broadcast
    together; dt (s); size (voxel size, m, > 0).
    """
    return (np.asarray(speed) + np.asarray(spin) * np.asarray(radius)) * dt / size


def spin_per_step(angular_momentum: np.ndarray, inv_inertia: np.ndarray, dt: float) -> np.ndarray:
    """Spin per step (rad) as the integrator measures it: |L| tr(I^-1) / 3 dt.

    angular_momentum (B, 3) in N m s; inv_inertia (B, 3, 3) rest-frame I^-1 in
    1/(kg m^2); dt in s.
    """
    norm = np.linalg.norm(angular_momentum, axis=-1)
    return norm * np.trace(inv_inertia, axis1=-2, axis2=-1) / 3.0 * dt


def suggested_dt(dt: float, measured: float, limit: float) -> float:
    """A step (s) that brings ``measured`` (proportional to dt) within ``limit``.

    dt limit / measured, rounded down to one significant digit (0.00213 -> 0.002).
    """
    target = dt * limit / measured
    scale = 10.0 ** math.floor(math.log10(target))
    return math.floor(target / scale * (1 + 1e-12)) * scale


def motion_message(dt: float, measured: float, mass: float, speed: float) -> str:
    """The warning for fragments that move ``measured`` voxels per step of ``dt`` s; the
    one that moved most weighs ``mass`` kg and flew at ``speed`` m/s (so an artist can
    judge whether a few light shards are worth a shorter step)."""
    return (f"dt {dt:.3g} s lets fragments move {measured:.2f} voxels per step (limit "
            f"{MOTION_LIMIT_VOXELS:g}; the fastest: {mass:.3g} kg at {speed:.3g} m/s), so "
            f"collisions can be missed; use --dt "
            f"{suggested_dt(dt, measured, MOTION_LIMIT_VOXELS):.2g} or smaller "
            f"(scene: [simulation] dt)")


def spin_message(dt: float, measured: float) -> str:
    """The warning for fragments that spin ``measured`` rad per step of ``dt`` s."""
    return (f"dt {dt:.3g} s lets fragments spin {measured:.1f} rad per step (limit "
            f"{SPIN_LIMIT_RAD:g}), so their rotation no longer conserves energy; use --dt "
            f"{suggested_dt(dt, measured, SPIN_LIMIT_RAD):.2g} or smaller "
            f"(scene: [simulation] dt)")


def penetration_message(dt: float, measured: float, substeps: int = DEFAULT_SUBSTEPS) -> str:
    """The warning for bodies that sank ``measured`` voxels into each other or the ground,
    with the contact solver at ``substeps`` sub-steps a step."""
    fewer = (f", or raise --contact-substeps from {substeps} (scene: [simulation] "
             f"contact_substeps; default {DEFAULT_SUBSTEPS})" if substeps < DEFAULT_SUBSTEPS
             else "")
    return (f"dt {dt:.3g} s lets fragments sink {measured:.2f} voxels into each other or the "
            f"ground (limit {PENETRATION_LIMIT_VOXELS:g}), so contacts did not hold them "
            f"apart; use --dt {suggested_dt(dt, measured, PENETRATION_LIMIT_VOXELS):.2g} or "
            f"smaller (scene: [simulation] dt){fewer}")


class LimitMonitor:
    """Measures a run against the limits at each output frame; warns once per limit at the end."""

    def __init__(self, sm: SimModel, settings: SimSettings, dt: float) -> None:
        self.dt = dt
        self.size = voxel_size(sm.voxels.contact_radius)
        self.collisions = settings.collisions
        self.substeps = settings.contact_substeps
        self.motion = 0.0  # worst voxels per step seen
        self.fastest = (0.0, 0.0)  # that fragment's mass (kg) and speed (m/s)
        self.spin = 0.0  # worst rad per step seen
        self.depth = 0.0  # deepest penetration seen, voxels
        self._rot = np.zeros((0, 3, 3))

    def check(self, state: State) -> None:
        """Record the worst motion and spin per step of the moving bodies now, and the
        deepest penetration the contacts have seen."""
        memory = state.contacts.memory
        if memory is not None and self.size > 0.0:
            self.depth = max(self.depth, float(memory.deepest[0]) / self.size)
        n = state.n_bodies
        live = state.bodies.live[:n] & ~state.bodies.dust[:n]
        moving = np.flatnonzero(live & ~state.bodies.fixed[:n] & ~state.bodies.asleep[:n])
        if not moving.size:
            return
        ang = state.bodies.ang[moving]
        inv = state.bodies.inv_inertia[moving]
        self.spin = max(self.spin, float(spin_per_step(ang, inv, self.dt).max()))
        if not self.collisions or np.count_nonzero(live) < 2 or self.size <= 0.0:
            return
        if len(self._rot) < n:
            self._rot = np.zeros((len(state.bodies.quat), 3, 3))
        # into the monitor's own matrices: the step's (bodies.rot) are its own business
        body_rotations(state.bodies.quat, state.bodies.live, n, self._rot)
        rot = self._rot[moving]
        # omega = R I^-1 R^T L, three small contractions (one 4-operand einsum is slow)
        body_frame = np.einsum("blk,bl->bk", rot, ang)
        omega = np.einsum("bij,bj->bi", rot, np.einsum("bjk,bk->bj", inv, body_frame))
        speed = np.linalg.norm(state.bodies.lin[moving], axis=1) / state.bodies.mass[moving]
        motion = motion_per_step(speed, np.linalg.norm(omega, axis=1),
                                 state.bodies.radius[moving], self.dt, self.size)
        worst = int(np.argmax(motion))
        if motion[worst] > self.motion:
            self.motion = float(motion[worst])
            self.fastest = (float(state.bodies.mass[moving[worst]]), float(speed[worst]))

    def messages(self) -> list[str]:
        """One message per limit the run passed (empty when it honoured them all)."""
        out = []
        if self.motion > MOTION_LIMIT_VOXELS:
            out.append(motion_message(self.dt, self.motion, *self.fastest))
        if self.spin > SPIN_LIMIT_RAD:
            out.append(spin_message(self.dt, self.spin))
        if self.depth > PENETRATION_LIMIT_VOXELS and self.motion <= MOTION_LIMIT_VOXELS:
            out.append(penetration_message(self.dt, self.depth, self.substeps))
        return out

    def finish(self) -> None:
        """Issue each message once as a :class:`SimulationLimitWarning`."""
        for message in self.messages():
            warnings.warn(message, SimulationLimitWarning, stacklevel=3)
