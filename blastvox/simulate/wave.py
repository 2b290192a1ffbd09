"""The blast waves of a scene's charges, in the form the step kernels use.

:mod:`blastvox.blast.model` defines the physics (Kingery-Bulmash reference
data, Hopkinson-Cranz scaling, the bounded modified Friedlander profile and its
exact step integral). Here it is tabulated once per run on a fine logarithmic
grid of scaled distance (Ps, ta, Td, b for 1 kg TNT; linear interpolation in
log Z, relative error ~1e-6), so a kernel evaluates a point in a few
nanoseconds instead of re-solving the decay coefficient. Outside the fitted
range the table continues with the blast module's own rules (constant near
the charge with ta linear in Z; 1/R decay and sound speed beyond Z_MAX).

Also here: the shock-front radius at a time (inverse of the arrival time) and
the radius behind which a wave has completely passed, which bound the shell
of points a step must look at.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numba as nb
import numpy as np

from blastvox.blast import model as blast
from blastvox.blast.model import C0_M_S, Z_MAX, Z_MIN, impulse_nb
from blastvox.jit import helper

_GRID = 4096
_LOG_LO = math.log10(Z_MIN)
_LOG_HI = math.log10(Z_MAX)
_STEP = (_LOG_HI - _LOG_LO) / (_GRID - 1)


@functools.lru_cache(maxsize=1)
def reference_table() -> np.ndarray:
    """(GRID, 4) columns Ps (Pa), ta (s), Td (s), b for 1 kg TNT on the log-Z grid (read-only)."""
    z = 10.0 ** np.linspace(_LOG_LO, _LOG_HI, _GRID)
    z[0], z[-1] = Z_MIN, Z_MAX
    ps, ta, td, imp = blast.reference_parameters(z)
    b = blast.decay_coefficient(ps, td, imp)
    table = np.ascontiguousarray(np.stack([ps, ta, td, b], axis=1), dtype=np.float64)
    table.flags.writeable = False
    return table


@helper
def params_at(table: np.ndarray, r: float, scale: float):
    """(Ps Pa, ta s, Td s, b) at distance r (m) from a charge of scale W^(1/3) (kg^(1/3))."""
    z = r / scale
    if z <= Z_MIN:
        frac = z / Z_MIN
        return table[0, 0], table[0, 1] * frac * scale, table[0, 2] * scale, table[0, 3]
    if z >= Z_MAX:
        last = table.shape[0] - 1
        ta = table[last, 1] + (z - Z_MAX) / C0_M_S
        return table[last, 0] * Z_MAX / z, ta * scale, table[last, 2] * scale, table[last, 3]
    x = (math.log10(z) - _LOG_LO) / _STEP
    i = min(int(x), table.shape[0] - 2)
    w = x - i
    ps = table[i, 0] * (1.0 - w) + table[i + 1, 0] * w
    ta = table[i, 1] * (1.0 - w) + table[i + 1, 1] * w
    td = table[i, 2] * (1.0 - w) + table[i + 1, 2] * w
    b = table[i, 3] * (1.0 - w) + table[i + 1, 3] * w
    return ps, ta * scale, td * scale, b


@nb.njit(cache=True)
def peak_overpressure(table: np.ndarray, r: float, scale: float) -> float:
    """Peak incident overpressure (Pa) at r (m)."""
    return params_at(table, r, scale)[0]


@helper
def point_impulse(table: np.ndarray, r: float, t_detonation: float, scale: float,
                  t0: float, t1: float) -> float:
    """Exact integral of p - p0 (Pa s) over [t0, t1] at a fixed point r (m) from the charge."""
    ps, ta, td, b = params_at(table, r, scale)
    return impulse_nb(t0 - t_detonation, t1 - t_detonation, ta, td, ps, b)


@helper
def exceedance_integral(table: np.ndarray, r: float, scale: float, threshold: float) -> float:
    """Integral over the positive phase of max(p - p0 - threshold, 0) dt, Pa s.

    The positive phase is decreasing, so the overpressure exceeds ``threshold``
    on [0, tau*] with Ps (1 - tau*) e^(-b tau*) = threshold (Newton from the
    left, monotone). Closed form: Td [Ps F(tau*) - threshold tau*] with
    F(tau) = integral_0^tau (1 - s) e^(-b s) ds.
    """
    ps, _, td, b = params_at(table, r, scale)
    if threshold >= ps:
        return 0.0
    if threshold <= 0.0:
        tau = 1.0
    else:
        k = threshold / ps
        tau = 0.0
        for _ in range(60):
            f = (1.0 - tau) * math.exp(-b * tau) - k
            df = -math.exp(-b * tau) * (1.0 + b * (1.0 - tau))
            step = f / df
            tau -= step
            if abs(step) < 1e-14:
                break
        tau = min(max(tau, 0.0), 1.0)
    e = math.exp(-b * tau)
    if b * tau < 1e-6:
        integral = tau - 0.5 * tau * tau * (1.0 + b) + b * tau ** 3 / 3.0
    else:
        integral = (1.0 - e) / b - (1.0 - e * (1.0 + b * tau)) / (b * b)
    return td * (ps * integral - threshold * tau)


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
    z = 10.0 ** np.linspace(_LOG_LO, _LOG_HI, _GRID)
    z[0], z[-1] = Z_MIN, Z_MAX
    sigma, tau_end = blast.negative_phase(table[:, 0], table[:, 3])
    del sigma
    arrive = np.maximum.accumulate(table[:, 1])
    leave = np.maximum.accumulate(table[:, 1] + table[:, 2] * tau_end)
    position = np.array([s.position for s in specs], dtype=np.float64).reshape(-1, 3)
    tnt = np.array([s.mass_kg * blast.tnt_equivalent(s.explosive) for s in specs],
                   dtype=np.float64)
    return Charges(position=position, tnt_kg=tnt,
                   time=np.array([s.time_s for s in specs], dtype=np.float64),
                   scale=np.cbrt(tnt), table=table, _z=z, _arrive=arrive, _leave=leave)
