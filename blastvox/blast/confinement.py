"""Confined explosions: the quasi-static gas pressure of a charge in a closed room.

A charge detonated inside a closed (or nearly closed) volume heats and fills it
with detonation products: after the shock reverberations, the room holds a
quasi-static overpressure that lasts until the gas vents. Its peak is UFC
3-340-02 (2008) Fig 2-152 ("peak gas pressure" against W/V_f, the charge's
TNT-equivalent mass over the room's free volume), which applies to chambers
with vent area up to 0.022 V^(2/3). The values below are a hand digitisation
of that chart (good to about 10 %, see ``docs/research/blast-loading-sources.md``
§4.1), interpolated on log-log axes and continued with the end slopes.
Cross-check: 2 kg TNT burnt in 14.1 m^3 (0.14 kg/m^3) gives 0.745 MPa by an
energy balance (Cooper, "Explosives Engineering", pp. 153-158); the chart
gives 0.55 MPa there (afterburning makes the chart exceed the energy balance at
light loadings, at most about twice).

Venting. No published closed form of the vented gas-pressure history (UFC
Figs 2-153 and 2-154) was found. Here the pressure holds while the room is
closed, and once a wall of it has broken it decays as exp(-t / tau) with
tau = VENT_TIME_FACTOR V^(1/3) / c0: the time for the gas to cross the room
a couple of times through openings of the order of a wall (a modelling
choice, stated as such in docs/physics.md).
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.blast.atmosphere import C0_M_S

#: W/V_f (kg/m^3) and peak quasi-static gas pressure (Pa), UFC 3-340-02 Fig 2-152
_LOADING = np.array([0.016, 0.032, 0.080, 0.160, 0.320, 0.801, 1.60, 3.20, 8.01, 16.0, 64.1])
_PRESSURE = np.array([0.117, 0.186, 0.345, 0.586, 1.10, 1.86, 2.96, 4.96, 10.0, 17.2, 55.2]) * 1e6
VENT_TIME_FACTOR = 2.0


def gas_pressure(tnt_kg: float, free_volume_m3: float) -> float:
    """Peak quasi-static gas overpressure (Pa) of tnt_kg kg TNT in free_volume_m3 m^3."""
    if not free_volume_m3 > 0.0 or not tnt_kg > 0.0:
        return 0.0
    x = math.log(tnt_kg / free_volume_m3)
    lx, ly = np.log(_LOADING), np.log(_PRESSURE)
    if x <= lx[0]:
        slope = (ly[1] - ly[0]) / (lx[1] - lx[0])
        return float(math.exp(ly[0] + slope * (x - lx[0])))
    if x >= lx[-1]:
        slope = (ly[-1] - ly[-2]) / (lx[-1] - lx[-2])
        return float(math.exp(ly[-1] + slope * (x - lx[-1])))
    return float(math.exp(np.interp(x, lx, ly)))


def vent_time(free_volume_m3: float) -> float:
    """Decay time (s) of the gas pressure once the room has opened (see above)."""
    return VENT_TIME_FACTOR * max(free_volume_m3, 0.0) ** (1.0 / 3.0) / C0_M_S
