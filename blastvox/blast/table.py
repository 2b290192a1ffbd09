"""The reference tabulated for compiled kernels: a point in a few nanoseconds.

:func:`reference_table` holds Ps, ta, Td and b for 1 kg TNT on a fine logarithmic
grid of scaled distance over the fitted range, made once per process;
:func:`params_at` interpolates it linearly in log Z (relative error ~1e-6) instead
of re-solving the decay coefficient at every point, and continues it outside the
range with the reference's own rules (constant near the charge with ta linear in
Z; 1/R decay and sound speed beyond Z_MAX). The other functions here are the
profile's quantities at a point r from a charge of scale W^(1/3).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from blastvox.blast._numeric import exp10
from blastvox.blast.atmosphere import C0_M_S
from blastvox.blast.friedlander import decay_coefficient, exceedance_nb, impulse_nb
from blastvox.blast.kingery_bulmash import Z_MAX, Z_MIN, reference_parameters
from blastvox.jit import helper, kernel

_GRID = 4096
_LOG_LO = math.log10(Z_MIN)
_LOG_HI = math.log10(Z_MAX)
_STEP = (_LOG_HI - _LOG_LO) / (_GRID - 1)


def reference_grid() -> np.ndarray:
    """The (GRID,) scaled distances of :func:`reference_table` (m/kg^(1/3)), Z_MIN to Z_MAX."""
    z = exp10(np.linspace(_LOG_LO, _LOG_HI, _GRID))
    z[0], z[-1] = Z_MIN, Z_MAX
    return z


@functools.lru_cache(maxsize=1)
def reference_table() -> np.ndarray:
    """(GRID, 4) columns Ps (Pa), ta (s), Td (s), b for 1 kg TNT on the log-Z grid (read-only)."""
    ps, ta, td, imp = reference_parameters(reference_grid())
    b = decay_coefficient(ps, td, imp)
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


@kernel
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
    """Integral over the positive phase of max(p - p0 - threshold, 0) dt (Pa s) at r (m);
    see :func:`blastvox.blast.friedlander.exceedance_nb`."""
    ps, _, td, b = params_at(table, r, scale)
    return exceedance_nb(ps, td, b, threshold)
