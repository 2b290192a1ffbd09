"""Kingery-Bulmash reference data: 1 kg TNT, spherical charge, free air, sea level.

Source
------
Kingery & Bulmash, *Airblast Parameters from TNT Spherical Air Burst and Hemispherical
Surface Burst*, ARBRL-TR-02555, US Army Ballistic Research Laboratory, 1984: the
log-log polynomial fits ``Y = sum_i C_i U^i``, ``U = K0 + K1 log10(Z)``, value = 10^Y,
for the *spherical free-air* burst. The coefficients are the ones ConWep uses, as
listed by Randers-Pehrson & Bannister, *Airblast Loading Model for DYNA2D and DYNA3D*,
ARL-TR-1310, US Army Research Laboratory, 1997 (Appendix A; the same fits behind
UFC 3-340-02 (2008) Figure 2-7 and LS-DYNA's ``*LOAD_BLAST``). They are kept in their
native units (Z in ft/lb^(1/3); psi; ms/lb^(1/3); psi-ms/lb^(1/3)) and converted to SI
here with exact factors (1 ft = 0.3048 m, 1 lb = 0.45359237 kg, 1 psi =
6894.757293168361 Pa), so no rounded metric coefficient set is involved. Swisdak's 1994
simplified coefficients (NSWC IHTR) are *hemispherical surface burst* fits and are not
used: a charge in free air is the case the papers (and the simulator) model.

Valid range of the fits, Z = R / W^(1/3): 0.0531 <= Z <= 40 m/kg^(1/3) (0.134 to
100 ft/lb^(1/3)) for peak incident overpressure Ps, arrival time ta and incident
positive impulse I (two pieces, joined at Z = 0.793); positive-phase duration Td is
fitted from Z = 0.147 in three pieces (joined at 0.889 and 2.28) and, as in ConWep,
held at 10^-0.824 ms/lb^(1/3) below Z = 0.181. The pieces of Td and I join with jumps
of up to 1 %, inherent to the published fits. Cross-checks (see tests/test_blast.py):
the shock speed implied by d(ta)/dR agrees with the Rankine-Hugoniot speed
c0 sqrt(1 + 6 Ps / 7 p0) of the fitted Ps to within 7 % over the whole range, Ps and I
agree with Kinney & Graham's (1985) closed forms to within 11 % for Z in 1-20 (Ps) and
2-20 (I), and the metric form of the same fits is reproduced to 3e-4.
Spot values, 1 kg TNT: Z = 1 m/kg^(1/3): Ps = 934.9 kPa, ta = 0.532 ms,
Td = 1.795 ms, I = 174.5 Pa s; Z = 10: Ps = 11.09 kPa, ta = 22.7 ms, Td = 4.20 ms,
I = 21.1 Pa s.

Outside the fitted range (defined and finite for every Z >= 0)
-------------------------------------------------------------
* Z < 0.0531 (inside the charge): 0.0531 m/kg^(1/3) is where the fits start and is the
  radius of a 1 kg TNT sphere at 1600 kg/m^3 (0.0530 m). Ps, Td and I are held at
  their Z = 0.0531 values and the arrival time falls linearly to 0 at the centre,
  ta = ta(0.0531) Z / 0.0531 - a front crossing the charge at the speed this implies,
  6.9 km/s, which is TNT's detonation velocity.
* Z > 40 (acoustic far field): Ps and I decay as 1/R from their Z = 40 values (spherical
  spreading), Td stays at its Z = 40 value, and the front moves at the ambient speed of
  sound: ta = ta(40) + (Z - 40)/c0 (scaled). Ps is then non-increasing and ta
  increasing in R everywhere.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from blastvox.blast._numeric import horner_nb, run_kernel
from blastvox.blast.atmosphere import C0_M_S
from blastvox.jit import helper, kernel

Z_MIN = 0.0531   #: lower end of the KB free-air fits (m/kg^(1/3))
Z_MAX = 40.0     #: upper end of the KB free-air fits (m/kg^(1/3))

# --- spherical free-air coefficients (ARL-TR-1310 App. A, imperial) ----------------------

_KB_PS = np.array([1.77284970457, -1.69012801396, 0.00804973591951, 0.336743114941,
                   -0.00516226351334, -0.0809228619888, -0.00478507266747,
                   0.00793030472242, 0.0007684469735])
_KB_PS_U = (-0.756579301809, 1.35034249993)
_KB_TA = np.array([-0.0423733936826, 1.36456871214, -0.0570035692784, -0.182832224796,
                   0.0118851436014, 0.0432648687627, -0.0007997367834, -0.00436073555033])
_KB_TA_U = (-0.80501734056, 1.37407043777)
_KB_TD1 = np.array([-0.801052722864, 0.164953518069, 0.127788499497, 0.00291430135946,
                    0.00187957449227, 0.0173413962543, 0.00269739758043,
                    -0.00361976502798, -0.00100926577934])
_KB_TD1_U = (0.209440059933, 5.11588554305)
_KB_TD2 = np.array([0.115874238335, -0.0297944268969, 0.0306329542941, 0.018340557407,
                    -0.0173964666286, -0.00106321963576, 0.0056206003128, 0.0001618217499,
                    -0.0006860188944])
_KB_TD2_U = (-5.06778493835, 9.2996288611)
_KB_TD3 = np.array([0.50659210403, 0.0967031995552, -0.00801302059667, 0.00482705779732,
                    0.00187587272287, -0.00246738509321, -0.000841116668, 0.0006193291052])
_KB_TD3_U = (-4.39590184126, 3.1524725264)
_KB_TD0_LOG = -0.824                  # ConWep: log10 Td (ms/lb^(1/3)) for log10 Z < -0.34
_KB_TD_BREAKS = (-0.34, 0.350248, 0.7596678)   # log10 Z (ft/lb^(1/3))
_KB_IS1 = np.array([1.43534136453, -0.443749377691, 0.168825414684, 0.0348138030308,
                    -0.010435192824])
_KB_IS1_U = (1.04504877747, 3.24299066475)
_KB_IS2 = np.array([0.599008468099, -0.40463292088, -0.0142721946082, 0.00912366316617,
                    -0.0006750681404, -0.00800863718901, 0.00314819515931,
                    0.00152044783382, -0.0007470265899])
_KB_IS2_U = (-2.67912519532, 2.30629231803)
_KB_IS_BREAK = 0.30103                # log10 Z (ft/lb^(1/3)) = log10 2

_FT_M = 0.3048
_LB_KG = 0.45359237
_PSI_PA = 6894.757293168361
_LOG10_Z_TO_IMPERIAL = math.log10(_LB_KG ** (1.0 / 3.0) / _FT_M)   # + log10 Z in m/kg^(1/3)
_TIME_TO_SI = 1e-3 / _LB_KG ** (1.0 / 3.0)    # ms/lb^(1/3) -> s/kg^(1/3)
_IMPULSE_TO_SI = _PSI_PA * _TIME_TO_SI        # psi ms/lb^(1/3) -> Pa s/kg^(1/3)


@helper
def reference_parameters_nb(z):
    """(Ps Pa, ta s/kg^(1/3), Td s/kg^(1/3), I Pa s/kg^(1/3)) of 1 kg TNT at Z >= 0.

    Multiply the last three by W^(1/3) (kg^(1/3)) for a charge of W kg TNT.
    """
    zc = min(max(z, Z_MIN), Z_MAX)
    zlog = math.log10(zc) + _LOG10_Z_TO_IMPERIAL
    ps = 10.0 ** horner_nb(_KB_PS, _KB_PS_U[0] + _KB_PS_U[1] * zlog) * _PSI_PA
    ta = 10.0 ** horner_nb(_KB_TA, _KB_TA_U[0] + _KB_TA_U[1] * zlog) * _TIME_TO_SI
    if zlog <= _KB_TD_BREAKS[0]:
        td_log = _KB_TD0_LOG
    elif zlog <= _KB_TD_BREAKS[1]:
        td_log = horner_nb(_KB_TD1, _KB_TD1_U[0] + _KB_TD1_U[1] * zlog)
    elif zlog <= _KB_TD_BREAKS[2]:
        td_log = horner_nb(_KB_TD2, _KB_TD2_U[0] + _KB_TD2_U[1] * zlog)
    else:
        td_log = horner_nb(_KB_TD3, _KB_TD3_U[0] + _KB_TD3_U[1] * zlog)
    td = 10.0 ** td_log * _TIME_TO_SI
    if zlog <= _KB_IS_BREAK:
        is_log = horner_nb(_KB_IS1, _KB_IS1_U[0] + _KB_IS1_U[1] * zlog)
    else:
        is_log = horner_nb(_KB_IS2, _KB_IS2_U[0] + _KB_IS2_U[1] * zlog)
    imp = 10.0 ** is_log * _IMPULSE_TO_SI
    if z < Z_MIN:
        ta = ta * (max(z, 0.0) / Z_MIN)
    elif z > Z_MAX:
        ta = ta + (z - Z_MAX) / C0_M_S
        ps = ps * (Z_MAX / z)
        imp = imp * (Z_MAX / z)
    return ps, ta, td, imp


@kernel
def _reference_kernel(z, out):
    for i in range(z.shape[0]):
        ps, ta, td, imp = reference_parameters_nb(z[i])
        out[0, i] = ps
        out[1, i] = ta
        out[2, i] = td
        out[3, i] = imp


def reference_parameters(scaled_distance: Any) -> tuple[np.ndarray, ...]:
    """NumPy face of :func:`reference_parameters_nb`: (Ps, ta, Td, I) arrays at Z >= 0."""
    return run_kernel(_reference_kernel, 4, scaled_distance)
