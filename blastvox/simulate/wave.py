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
    negative_phase,
    params_at,
    peak_overpressure,
    point_impulse,
    reference_grid,
    reference_table,
    tnt_equivalent,
)

__all__ = ["Charges", "build_charges", "exceedance_integral", "params_at", "peak_overpressure",
           "point_impulse", "reference_table"]


@dataclass(frozen=True)
class Charges:
    """The scene's charges. position (C, 3) m, tnt_kg (C,), time (C,) s, scale = W^(1/3)."""

    position: np.ndarray
    tnt_kg: np.ndarray
    time: np.ndarray
    scale: np.ndarray
    table: np.ndarray
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
                        radius[c] = self.scale[c] * _invert(tau, self._z, self._arrive,
                                                            leading=True)
                cache[t] = radius
            out = np.array([before if math.isnan(r) else r for r in radius])
            cache[t, before] = out
        return out

    def peak(self, c: int, r: float) -> float:
        """Peak incident overpressure (Pa) of charge c at distance r (m)."""
        return float(peak_overpressure(self.table, float(r), float(self.scale[c])))

    def tail_radius(self, t: float) -> np.ndarray:
        """Radius (C,) within which the whole wave (negative phase included) has passed by t.

        -1 where nothing has passed yet.
        """
        out = np.full(len(self.time), -1.0)
        for c in range(len(self.time)):
            tau = (t - self.time[c]) / self.scale[c]
            if tau <= self._leave[0]:
                continue
            out[c] = self.scale[c] * _invert(tau, self._z, self._leave, leading=False)
        return out


def _invert(tau: float, z: np.ndarray, times: np.ndarray, leading: bool) -> float:
    """Scaled distance at which the (increasing) scaled time ``times`` equals tau."""
    if tau >= times[-1]:
        return float(z[-1] + (tau - times[-1]) * C0_M_S)
    if tau < times[0]:
        return float(z[0] * tau / times[0]) if leading else float(z[0])
    return float(np.interp(tau, times, z))


def build_charges(specs) -> Charges:
    """Tabulate the blast of each :class:`~blastvox.simulate.settings.ChargeSpec`."""
    table = reference_table()
    z = reference_grid()
    _, tau_end = negative_phase(table[:, 0], table[:, 3])
    arrive = np.maximum.accumulate(table[:, 1])
    leave = np.maximum.accumulate(table[:, 1] + table[:, 2] * tau_end)
    position = np.array([s.position for s in specs], dtype=np.float64).reshape(-1, 3)
    tnt = np.array([s.mass_kg * tnt_equivalent(s.explosive) for s in specs],
                   dtype=np.float64)
    return Charges(position=position, tnt_kg=tnt,
                   time=np.array([s.time_s for s in specs], dtype=np.float64),
                   scale=np.cbrt(tnt), table=table, _z=z, _arrive=arrive, _leave=leave)
