"""The blast waves of a scene's charges, in the form the step kernels use.

The physics is :mod:`blastvox.blast` (Kingery-Bulmash reference data,
Hopkinson-Cranz scaling, the bounded modified Friedlander profile and its exact
step integral), tabulated once per process for the kernels by
:mod:`blastvox.blast.table`, whose point functions are re-exported here.

Here: the charges of a run, the shock-front radius at a time (inverse of the
arrival time) and the radius behind which a wave has completely passed, which
bound the shell of points a step must look at.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from blastvox.blast import (
    C0_M_S,
    exceedance_integral,
    params_at,
    peak_overpressure,
    point_impulse,
    reference_grid,
    reference_table,
    tnt_equivalent,
)
from blastvox.blast._numeric import cbrt
from blastvox.blast.face_load import face_tables
from blastvox.blast.kingery_bulmash import AIR, SURFACE
from blastvox.geometry import exact

#: a charge whose centre is at most this scaled height (m/kg^(1/3)) above the ground
#: is a surface burst by default (its TNT sphere's radius is 0.053; a modelling choice)
SURFACE_HEIGHT = 0.2

__all__ = ["Charges", "build_charges", "exceedance_integral", "params_at", "peak_overpressure",
           "point_impulse", "reference_table"]


@dataclass(frozen=True)
class Charges:
    """The scene's charges. position (C, 3) m, tnt_kg (C,), time (C,) s, scale = W^(1/3);
    burst (C,) int64 (AIR or SURFACE), the row of ``table`` (face_tables()) to use."""

    position: np.ndarray
    tnt_kg: np.ndarray
    time: np.ndarray
    scale: np.ndarray
    table: np.ndarray
    burst: np.ndarray
    _z: np.ndarray
    _arrive: np.ndarray
    _leave: np.ndarray
    _front_cache: dict = field(default_factory=dict, compare=False, repr=False)

    def front_radius(self, t: float, before: float = 0.0) -> np.ndarray:
        """Shock-front radius (C,) in m at time t; ``before`` for charges not yet detonated.

        A step asks for its t1, the next for the same time as its t0: the radii
        of the last few (t, before) are kept (do not modify the array returned).
        """
        cache = self._front_cache
        out = cache.get((t, before))
        if out is None:
            radius = cache.get(t)
            if radius is None:
                if len(cache) > 8:
                    cache.clear()
                radius = [math.nan] * len(self.time)
                for c in range(len(self.time)):
                    tau = (t - self.time[c]) / self.scale[c]
                    if tau > 0.0:
                        radius[c] = self.scale[c] * _invert(
                            tau, self._z, self._arrive[self.burst[c]], leading=True)
                cache[t] = radius
            out = np.array([before if math.isnan(r) else r for r in radius])
            cache[t, before] = out
        return out

    def peak(self, c: int, r: float) -> float:
        """Peak incident overpressure (Pa) of charge c at distance r (m)."""
        return float(peak_overpressure(self.table[self.burst[c]], float(r),
                                       float(self.scale[c])))

    def tail_radius(self, t: float) -> np.ndarray:
        """Radius (C,) within which the whole wave (negative phase included) has passed by t.

        -1 where nothing has passed yet.
        """
        out = np.full(len(self.time), -1.0)
        for c in range(len(self.time)):
            tau = (t - self.time[c]) / self.scale[c]
            leave = self._leave[self.burst[c]]
            if tau <= leave[0]:
                continue
            out[c] = self.scale[c] * _invert(tau, self._z, leave, leading=False)
        return out


def _invert(tau: float, z: np.ndarray, times: np.ndarray, leading: bool) -> float:
    """Scaled distance at which the (increasing) scaled time ``times`` equals tau."""
    if tau >= times[-1]:
        return float(z[-1] + (tau - times[-1]) * C0_M_S)
    if tau < times[0]:
        return float(z[0] * tau / times[0]) if leading else float(z[0])
    return float(np.interp(tau, times, z))


def build_charges(specs, up: np.ndarray | None = None,
                  ground: float | None = None) -> Charges:
    """Tabulate the blast of each :class:`~blastvox.simulate.settings.ChargeSpec`.

    A spec's burst "air" or "surface" is kept; "auto" is a surface burst when a
    ground plane (height ``ground`` m along the unit ``up``) is within
    SURFACE_HEIGHT W^(1/3) of the charge's centre, else air."""
    table = face_tables()
    z = reference_grid()
    arrive = np.maximum.accumulate(table[:, :, 1], axis=1)
    leave = np.maximum.accumulate(table[:, :, 1] + table[:, :, 2] + table[:, :, 11], axis=1)
    position = np.array([s.position for s in specs], dtype=np.float64).reshape(-1, 3)
    tnt = np.array([s.mass_kg * tnt_equivalent(s.explosive) for s in specs],
                   dtype=np.float64)
    scale = cbrt(tnt)
    burst = np.array([_burst(s, p, w, up, ground) for s, p, w in zip(specs, position, scale,
                                                                      strict=True)],
                     dtype=np.int64)
    return Charges(position=position, tnt_kg=tnt,
                   time=np.array([s.time_s for s in specs], dtype=np.float64),
                   scale=scale, table=table, burst=burst, _z=z, _arrive=arrive, _leave=leave)


def _burst(spec, position: np.ndarray, scale: float, up, ground) -> int:
    kind = spec.burst
    if kind == "air":
        return AIR
    if kind == "surface":
        return SURFACE
    if up is None or ground is None:
        return AIR
    height = float(exact.dot(position, up)) - ground
    return SURFACE if height <= SURFACE_HEIGHT * scale else AIR
