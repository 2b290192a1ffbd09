"""A blast wave meeting a surface: oblique reflection, and the shock's own speed and wind.

Oblique reflection (ConWep / LS-DYNA ``*LOAD_BLAST``)
----------------------------------------------------
Randers-Pehrson & Bannister, *Airblast Loading Model for DYNA2D and DYNA3D*, ARL-TR-1310,
US Army Research Laboratory, 1997 (section 2): a face whose outward normal makes the angle
alpha with the direction to the charge receives

    value = normal cos^2(alpha) + incident (1 + cos^2(alpha) - 2 cos(alpha))   (cos >= 0)

for both the peak overpressure (Pr, Ps) and the positive impulse (Ir, I): the normally
reflected value head-on (cos 1), the incident (side-on) value at grazing incidence
(cos 0). A face turned away from the charge (cos < 0) gets no direct load here (0); it
sees the wave only after diffraction, which this model does not include. The
combination is monotone in cos(alpha) only above cos* = incident / (normal + incident);
between grazing and cos* it dips below the incident value, to
normal incident / (normal + incident) at cos* (a property of the published formula).

Shock-front velocity and dynamic pressure (Rankine-Hugoniot, ideal air, gamma = 1.4)
-----------------------------------------------------------------------------------
For a shock of peak incident overpressure ps into still air at p0, c0 (UFC 3-340-02,
2008, section 2-13 and Figure 2-3; Baker, *Explosions in Air*, 1973, eqs. 2.34-2.36):

    U  = c0 sqrt(1 + 6 ps / (7 p0))          shock-front velocity, m/s
    q0 = 5 ps^2 / (2 (ps + 7 p0))            peak dynamic pressure (1/2 rho u^2), Pa

Both are exact for an ideal gas and run high for very strong shocks (ps >~ 2 MPa, Z <~
0.5 m/kg^(1/3)), where real air's gamma falls below 1.4.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from blastvox.blast._numeric import run_kernel
from blastvox.blast.atmosphere import C0_M_S, P0_PA
from blastvox.jit import helper, kernel


@helper
def oblique_nb(cos_alpha, normal_value, incident_value):
    """ConWep's oblique value: normal cos^2 + incident (1 + cos^2 - 2 cos) for
    cos_alpha >= 0 (cos_alpha clamped to 1 above), 0 for cos_alpha < 0; any unit
    (Pa, or Pa s for impulse)."""
    if not cos_alpha >= 0.0:
        return 0.0
    c = min(cos_alpha, 1.0)
    c2 = c * c
    return normal_value * c2 + incident_value * (1.0 + c2 - 2.0 * c)


@helper
def front_velocity_nb(ps):
    """Shock-front velocity c0 sqrt(1 + 6 ps / (7 p0)) (m/s) for overpressure ps >= 0 (Pa)."""
    return C0_M_S * math.sqrt(1.0 + 6.0 * max(ps, 0.0) / (7.0 * P0_PA))


@helper
def dynamic_pressure_nb(ps):
    """Peak dynamic pressure 5 ps^2 / (2 (ps + 7 p0)) (Pa) behind a shock of ps >= 0 (Pa)."""
    p = max(ps, 0.0)
    return 5.0 * p * p / (2.0 * (p + 7.0 * P0_PA))


@kernel
def _oblique_kernel(cos_alpha, normal_value, incident_value, out):
    for i in range(cos_alpha.shape[0]):
        out[0, i] = oblique_nb(cos_alpha[i], normal_value[i], incident_value[i])


@kernel
def _shock_kernel(ps, out):
    for i in range(ps.shape[0]):
        out[0, i] = front_velocity_nb(ps[i])
        out[1, i] = dynamic_pressure_nb(ps[i])


def oblique(cos_alpha: Any, normal_value: Any, incident_value: Any) -> np.ndarray:
    """NumPy face of :func:`oblique_nb` (arguments broadcast together)."""
    return run_kernel(_oblique_kernel, 1, cos_alpha, normal_value, incident_value)[0]


def front_velocity(peak_overpressure: Any) -> np.ndarray:
    """NumPy face of :func:`front_velocity_nb` (m/s)."""
    return run_kernel(_shock_kernel, 2, peak_overpressure)[0]


def dynamic_pressure(peak_overpressure: Any) -> np.ndarray:
    """NumPy face of :func:`dynamic_pressure_nb` (Pa)."""
    return run_kernel(_shock_kernel, 2, peak_overpressure)[1]
