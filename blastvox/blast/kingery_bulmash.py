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

from blastvox.blast._numeric import flat_arrays, horner_nb, run_kernel
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

# --- reflected and surface-burst sets (ARL-TR-1310 App. A, the ConWep FORTRAN; imperial) ---

AIR = 0       #: spherical charge in free air
SURFACE = 1   #: hemispherical charge on the ground (surface burst)
#: what each burst's data describe, for titles
BURST_TITLES = {"air": "spherical charge, free air, sea level",
                "surface": "hemispherical charge on the ground (surface burst), sea level"}
Z_MIN_SURFACE = 0.0674   #: lower end of the KB hemispherical fits (m/kg^(1/3)), 0.17 ft/lb^(1/3)

# free air, normally reflected overpressure Pr (psi) and impulse Ir (psi ms/lb^(1/3))
_KB_PR = np.array([2.39106134946, -2.21400538997, 0.035119031446, 0.657599992109,
                   0.0141818951887, -0.243076636231, -0.0158699803158, 0.0492741184234,
                   0.00227639644004, -0.00397126276058])
_KB_PR_U = (-0.756579301809, 1.35034249993)
_KB_IR = np.array([1.60579280091, -0.903118886091, 0.101771877942, -0.0242139751146])
_KB_IR_U = (-0.757659920369, 1.37882996018)

# hemispherical surface burst
_KBS_PS = np.array([1.9422502013, -1.6958988741, -0.154159376846, 0.514060730593,
                    0.0988534365274, -0.293912623038, -0.0268112345019, 0.109097496421,
                    0.00162846756311, -0.0214631030242, 0.0001456723382, 0.00167847752266])
_KBS_PS_U = (-0.756579301809, 1.35034249993)
_KBS_TA = np.array([-0.173607601251, 1.35706496258, 0.052492798645, -0.196563954086,
                    -0.0601770052288, 0.0696360270891, 0.0215297490092, -0.0161658930785,
                    -0.00232531970294, 0.00147752067524])
_KBS_TA_U = (-0.755684472698, 1.37784223635)
_KBS_TD1 = np.array([-0.728671776005, 0.130143717675, 0.134872511954, 0.0391574276906,
                     -0.00475933664702, -0.00428144598008])
_KBS_TD1_U = (-0.1790217052, 5.25099193925)
_KBS_TD2 = np.array([0.20096507334, -0.0297944268976, 0.030632954288, 0.0183405574086,
                     -0.0173964666211, -0.00106321963633, 0.00562060030977, 0.0001618217499,
                     -0.0006860188944])
_KBS_TD2_U = (-5.85909812338, 9.2996288611)
_KBS_TD3 = np.array([0.572462469964, 0.0933035304009, -0.0005849420883, -0.00226884995013,
                     -0.00295908591505, 0.00148029868929])
_KBS_TD3_U = (-4.92699491141, 3.46349745571)
_KBS_TD0_LOG = -0.725                 # ConWep: log10 Td (ms/lb^(1/3)) for log10 Z < -0.34
_KBS_TD_BREAKS = (-0.34, 0.4048337, 0.845098)   # log10 Z (ft/lb^(1/3))
_KBS_IS1 = np.array([1.57159240621, -0.502992763686, 0.171335645235, 0.0450176963051,
                     -0.0118964626402])
_KBS_IS1_U = (0.832468843425, 3.0760329666)
# C2 = -0.0260816706301 as in the metric KB set and lightsquared/kingery_bulmash; the ConWep
# C++ ports print -0.0280816706301, which leaves a 1.4 % step at the join (0.4 % with -0.026)
_KBS_IS2 = np.array([0.719852655584, -0.384519026965, -0.0260816706301, 0.00595798753822,
                     0.014544526107, -0.00663289334734, -0.00284189327204, 0.0013644816227])
_KBS_IS2_U = (-2.91358616806, 2.40697745406)
_KBS_IS_BREAK = 0.382017              # log10 Z (ft/lb^(1/3)), Z = 2.41
_KBS_PR = np.array([2.56431321138, -2.21030870597, -0.218536586295, 0.895319589372,
                    0.24989009775, -0.569249436807, -0.11791682383, 0.224131161411,
                    0.0245620259375, -0.0455116002694, -0.00190930738887, 0.00361471193389])
_KBS_PR_U = (-0.789312405513, 1.36637719229)
_KBS_IR = np.array([1.75291677799, -0.949516092853, 0.112136118689, -0.0250659183287])
_KBS_IR_U = (-0.781951689212, 1.33422049854)

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


@helper
def _fit_nb(coeffs, u, zlog):
    """10^(sum_i coeffs[i] U^i) with U = u[0] + u[1] log10 Z (imperial)."""
    return 10.0 ** horner_nb(coeffs, u[0] + u[1] * zlog)


@helper
def _surface_nb(zlog):
    """(Ps psi, ta ms, Td ms, I, Pr psi, Ir psi ms) per lb^(1/3), hemispherical, at log10 Z
    (ft/lb^(1/3)) inside the fits."""
    ps = _fit_nb(_KBS_PS, _KBS_PS_U, zlog)
    ta = _fit_nb(_KBS_TA, _KBS_TA_U, zlog)
    if zlog <= _KBS_TD_BREAKS[0]:
        td = 10.0 ** _KBS_TD0_LOG
    elif zlog <= _KBS_TD_BREAKS[1]:
        td = _fit_nb(_KBS_TD1, _KBS_TD1_U, zlog)
    elif zlog <= _KBS_TD_BREAKS[2]:
        td = _fit_nb(_KBS_TD2, _KBS_TD2_U, zlog)
    else:
        td = _fit_nb(_KBS_TD3, _KBS_TD3_U, zlog)
    if zlog <= _KBS_IS_BREAK:
        imp = _fit_nb(_KBS_IS1, _KBS_IS1_U, zlog)
    else:
        imp = _fit_nb(_KBS_IS2, _KBS_IS2_U, zlog)
    return (ps, ta, td, imp, _fit_nb(_KBS_PR, _KBS_PR_U, zlog),
            _fit_nb(_KBS_IR, _KBS_IR_U, zlog))


@helper
def burst_parameters_nb(z, burst):
    """(Ps Pa, ta s/kg^(1/3), Td s/kg^(1/3), I Pa s/kg^(1/3), Pr Pa, Ir Pa s/kg^(1/3)) of
    1 kg TNT at Z >= 0 (m/kg^(1/3)) for ``burst`` AIR or SURFACE.

    Pr and Ir are the peak overpressure and positive impulse *normally reflected* from a
    rigid surface facing the charge. AIR: the first four are
    :func:`reference_parameters_nb`'s, bit for bit. SURFACE: the hemispherical fits, for W
    the mass of the charge on the ground (the ground's reflection is in the fits).
    Outside the fits: held below Z_MIN (SURFACE: Z_MIN_SURFACE) with ta linear to 0,
    Ps, I, Pr and Ir decay as 1/R beyond Z_MAX, Td held and ta at the speed of sound.
    """
    if burst != SURFACE:
        ps, ta, td, imp = reference_parameters_nb(z)
        zlog = math.log10(min(max(z, Z_MIN), Z_MAX)) + _LOG10_Z_TO_IMPERIAL
        pr = _fit_nb(_KB_PR, _KB_PR_U, zlog) * _PSI_PA
        ir = _fit_nb(_KB_IR, _KB_IR_U, zlog) * _IMPULSE_TO_SI
        if z > Z_MAX:
            pr = pr * (Z_MAX / z)
            ir = ir * (Z_MAX / z)
        return ps, ta, td, imp, pr, ir
    zc = min(max(z, Z_MIN_SURFACE), Z_MAX)
    ps, ta, td, imp, pr, ir = _surface_nb(math.log10(zc) + _LOG10_Z_TO_IMPERIAL)
    ps = ps * _PSI_PA
    pr = pr * _PSI_PA
    ta = ta * _TIME_TO_SI
    td = td * _TIME_TO_SI
    imp = imp * _IMPULSE_TO_SI
    ir = ir * _IMPULSE_TO_SI
    if z < Z_MIN_SURFACE:
        ta = ta * (max(z, 0.0) / Z_MIN_SURFACE)
    elif z > Z_MAX:
        decay = Z_MAX / z
        ta = ta + (z - Z_MAX) / C0_M_S
        ps = ps * decay
        imp = imp * decay
        pr = pr * decay
        ir = ir * decay
    return ps, ta, td, imp, pr, ir


@kernel
def _burst_kernel(z, burst, out):
    for i in range(z.shape[0]):
        ps, ta, td, imp, pr, ir = burst_parameters_nb(z[i], burst)
        out[0, i] = ps
        out[1, i] = ta
        out[2, i] = td
        out[3, i] = imp
        out[4, i] = pr
        out[5, i] = ir


def burst_code(burst: Any) -> int:
    """AIR or SURFACE from ``burst``: one of them, or "air" / "surface" (any case)."""
    if isinstance(burst, str):
        code = {"air": AIR, "surface": SURFACE}.get(burst.strip().lower())
    else:
        code = int(burst) if burst in (AIR, SURFACE) else None
    if code is None:
        from blastvox.errors import BlastvoxError

        raise BlastvoxError(f"unknown burst {burst!r}: air or surface")
    return code


def burst_parameters(scaled_distance: Any, burst: Any = AIR) -> tuple[np.ndarray, ...]:
    """NumPy face of :func:`burst_parameters_nb`: (Ps, ta, Td, I, Pr, Ir) arrays at Z >= 0;
    ``burst`` AIR, SURFACE, "air" or "surface"."""
    shape, (z,) = flat_arrays(scaled_distance)
    out = np.empty((6, z.size))
    _burst_kernel(z, burst_code(burst), out)
    return tuple(row.reshape(shape) for row in out)
