"""Free-air blast-wave model: reference data, scaling, Friedlander profile, exact impulse.

Reference data (1 kg TNT, spherical charge, free air, sea-level standard atmosphere)
------------------------------------------------------------------------------------
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

Hopkinson-Cranz scaling: W is the TNT-equivalent mass (kg) and Z = R / W^(1/3);
pressures are equal at equal Z, times and impulses scale by W^(1/3).

Outside the fitted range (defined and finite for every R >= 0, W > 0)
------------------------------------------------------------------------
* Z < 0.0531 (inside the charge): 0.0531 m/kg^(1/3) is where the fits start and is the
  radius of a 1 kg TNT sphere at 1600 kg/m^3 (0.0530 m). Ps, Td, I and b are held at
  their Z = 0.0531 values and the arrival time falls linearly to 0 at the centre,
  ta = ta(0.0531) Z / 0.0531 - a front crossing the charge at the speed this implies,
  6.9 km/s, which is TNT's detonation velocity.
* Z > 40 (acoustic far field): Ps and I decay as 1/R from their Z = 40 values (spherical
  spreading), Td and b stay at their Z = 40 values, and the front moves at the ambient
  speed of sound: ta = ta(40) + (Z - 40)/c0 (scaled). Ps is then non-increasing and ta
  increasing in R everywhere.

Decay coefficient b and the modified Friedlander profile
--------------------------------------------------------
Overpressure, tau = (t - ta)/Td:  p - p0 = 0 for tau < 0 and Ps (1 - tau) e^(-b tau)
for tau >= 0 (Baker 1973; Mazarak et al. 1999 eq. 2.1; Martins et al. 2001 eq. 3-1).
b is solved so that the positive-phase integral equals the reference impulse:

    integral_0^Td Ps (1 - t/Td) e^(-b t/Td) dt = Ps Td (b - 1 + e^-b) / b^2 = I

i.e. g(b) = I/(Ps Td) with g(b) = (b - 1 + e^-b)/b^2 = integral_0^1 (1-s) e^(-bs) ds,
which decreases from 1/2 (b -> 0) to 0 and is convex, so Newton's method from a point
left of the root converges monotonically (vectorised here; reproduces the k-alpha table
of NAVFAC DM-2.08, 1986, to its two decimals). g never exceeds 1/2, so a reference with
I >= Ps Td / 2 has no positive b: there b is clamped to B_MIN = 1e-3 and the positive
phase carries Ps Td g(B_MIN) = 0.49983 Ps Td, at most 0.6 % short of the reference
(KB gives I/(Ps Td) between 0.49983 and 0.5027 for Z = 33.4-40, and the Z = 40 value
beyond). NAVFAC's negative "alpha" (a concave positive phase) would match I exactly;
the clamp keeps b > 0 and the positive phase convex, as measured waves are.

Negative phase: continued, but bounded
--------------------------------------
For tau > 1 the same formula is continued (pressure is continuous at tau = 1) but, left
alone, its lobe is unbounded: its depth Ps e^-(1+b)/b and area Ps Td e^-b/b^2 grow
without limit as b -> 0. The lobe is therefore

1. ended at tau_end = 1 + min(X_EPS / b, NEG_MAX_DURATION): X_EPS = 7.638 is where the
   lobe has recovered to NEG_CUTOFF = 1 % of its own extremum (a universal constant in
   x = b (tau - 1), since (tau - 1) e^(-b tau) = e^-b x e^-x / b); NEG_MAX_DURATION = 3
   caps the negative phase at three positive durations (a modelling choice, not a fit
   to data; it only binds for b < 2.5, where the lobe would otherwise drag on);
2. scaled by sigma in (0, 1] (scaled, not clipped, so the profile keeps its shape and
   the step impulse stays closed form) so that
   * it never goes below a vacuum nor deeper than the positive peak:
     sigma Ps max(lobe) <= min(p0, Ps);
   * its impulse never exceeds the positive impulse: |I-| <= I+ (the acoustic limit -
     a spherical wave from a compact source carries zero net impulse far away).
After tau_end the overpressure is 0 again. In the far field (b small) this tends to an
N-wave-like saw tooth; near the charge the vacuum bound is the active one.

Exact impulse over a step
-------------------------
With G(tau) = integral_0^tau of the bounded profile / (Ps Td), the impulse of [t0, t1]
is Ps Td (G(tau1) - G(tau0)), in closed form:
    positive phase  G(tau) = tau^2 gfun(b tau) - tau (tau - 1) hfun(b tau),
    negative lobe   integral_1^tau (u - 1) e^(-b u) du = e^-b y^2 qfun(b y), y = tau - 1,
with gfun(x) = (x - 1 + e^-x)/x^2, hfun(x) = (1 - e^-x)/x, qfun(x) = (1 - (1 + x) e^-x)/x^2
evaluated with series near 0 (no cancellation). A shock that crosses a point inside a
step is therefore never missed, and sums over consecutive steps telescope exactly.

Vectorised NumPy functions are the public API; ``*_nb`` are scalar float64
``numba.njit(cache=True)`` twins for simulator kernels (same argument order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba as nb
import numpy as np

from blastvox.errors import BlastvoxError
from blastvox.jit import helper

__all__ = [
    "B_MIN", "C0_M_S", "NEG_CUTOFF", "NEG_MAX_DURATION", "P0_PA", "TNT_DENSITY_KG_M3",
    "TNT_EQUIVALENTS", "X_EPS", "Z_MAX", "Z_MIN", "BlastParameters", "blast_parameters",
    "blast_parameters_nb", "decay_coefficient", "decay_coefficient_nb", "impulse",
    "impulse_nb", "known_explosives", "negative_phase", "negative_phase_nb", "overpressure",
    "overpressure_nb", "positive_impulse", "reference_parameters", "reference_parameters_nb",
    "tnt_equivalent",
]

# --- ambient and model constants -------------------------------------------------------

P0_PA = 101_325.0            #: ambient pressure, sea-level standard atmosphere (Pa)
C0_M_S = 340.294             #: ambient speed of sound, ISA sea level 15 degC (m/s)
TNT_DENSITY_KG_M3 = 1600.0   #: cast TNT; its 1 kg sphere has radius 0.0530 m ~ Z_MIN
Z_MIN = 0.0531               #: lower end of the KB free-air fits (m/kg^(1/3))
Z_MAX = 40.0                 #: upper end of the KB free-air fits (m/kg^(1/3))
B_MIN = 1.0e-3               #: decay coefficient floor where I >= Ps Td / 2
NEG_CUTOFF = 0.01            #: the negative lobe ends when back within 1 % of its extremum
NEG_MAX_DURATION = 3.0       #: negative phase at most this many positive durations


def _x_eps(eps: float) -> float:
    """The x > 1 with x e^(1 - x) = eps (Newton on ln x + 1 - x = ln eps, from the right)."""
    x = 2.0 - 2.0 * math.log(eps)   # right of the root; f is concave, so no overshoot
    for _ in range(100):
        step = (math.log(x) + 1.0 - x - math.log(eps)) / (1.0 / x - 1.0)
        x -= step
        if abs(step) < 1e-15 * x:
            break
    return x


X_EPS = _x_eps(NEG_CUTOFF)   #: 7.638...: lobe recovery point in x = b (tau - 1)

# --- Kingery-Bulmash spherical free-air coefficients (ARL-TR-1310 App. A, imperial) -----

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

# --- TNT equivalence ----------------------------------------------------------------------

#: Mass of TNT per kg of explosive. Pressure-based factors from UFC 3-340-02 (2008),
#: Table 2-1 ("equivalent pressure factor") where listed; otherwise the ratio of heats of
#: detonation to TNT's 4520 kJ/kg as tabulated by Karlos & Solomos, *Calculation of Blast
#: Loads for Application to Structural Components*, JRC EUR 26456 EN (2013), Table 1.
TNT_EQUIVALENTS: dict[str, float] = {
    "tnt": 1.0,
    "c4": 1.37,             # UFC 3-340-02 Table 2-1 (Composition C-4)
    "petn": 1.27,           # UFC 3-340-02 Table 2-1
    "anfo": 0.82,           # UFC 3-340-02 Table 2-1 (94/6)
    "comp-b": 1.11,         # UFC 3-340-02 Table 2-1 (Composition B)
    "rdx": 1.185,           # Karlos & Solomos 2013 Table 1 (5360 kJ/kg)
    "hmx": 1.256,           # Karlos & Solomos 2013 Table 1 (5680 kJ/kg)
    "nitroglycerin": 1.481,  # Karlos & Solomos 2013 Table 1 (6700 kJ/kg)
    "semtex": 1.250,        # Karlos & Solomos 2013 Table 1 (5660 kJ/kg)
    "dynamite": 0.600,      # Karlos & Solomos 2013 Table 1: 60 % nitroglycerin dynamite
}

_ALIASES = {
    "c-4": "c4", "composition-c-4": "c4", "composition-c4": "c4",
    "compb": "comp-b", "composition-b": "comp-b",
    "cyclonite": "rdx", "octogen": "hmx", "nitroglycerine": "nitroglycerin",
    "ng": "nitroglycerin", "trinitrotoluene": "tnt",
}


def _normalise_name(name: str) -> str:
    return "-".join(str(name).strip().lower().replace("_", " ").replace("-", " ").split())


def known_explosives() -> list[str]:
    """Canonical explosive names accepted by :func:`tnt_equivalent` (aliases aside)."""
    return sorted(TNT_EQUIVALENTS)


def tnt_equivalent(explosive: str) -> float:
    """kg of TNT per kg of ``explosive`` (case, spaces, '-' and '_' are ignored)."""
    key = _normalise_name(explosive)
    key = _ALIASES.get(key, key)
    if key not in TNT_EQUIVALENTS:
        raise BlastvoxError(f"unknown explosive {explosive!r}; known: "
                            + ", ".join(known_explosives()))
    return TNT_EQUIVALENTS[key]


# --- reference data, vectorised -----------------------------------------------------------


def _horner(coeffs: np.ndarray, u: np.ndarray) -> np.ndarray:
    out = np.full_like(u, coeffs[-1])
    for c in coeffs[-2::-1]:
        out = out * u + c
    return out


def _kb_log(coeffs: np.ndarray, ucoef: tuple[float, float], zlog: np.ndarray) -> np.ndarray:
    return _horner(coeffs, ucoef[0] + ucoef[1] * zlog)


def _kingery_bulmash(z: np.ndarray) -> tuple[np.ndarray, ...]:
    """Raw KB free-air fits at z in [Z_MIN, Z_MAX]: (Ps Pa, ta, Td s/kg^(1/3), I Pa s/kg^(1/3))."""
    zlog = np.log10(z) + _LOG10_Z_TO_IMPERIAL
    ps = 10.0 ** _kb_log(_KB_PS, _KB_PS_U, zlog) * _PSI_PA
    ta = 10.0 ** _kb_log(_KB_TA, _KB_TA_U, zlog) * _TIME_TO_SI
    td_log = np.where(
        zlog <= _KB_TD_BREAKS[0], _KB_TD0_LOG,
        np.where(zlog <= _KB_TD_BREAKS[1], _kb_log(_KB_TD1, _KB_TD1_U, zlog),
                 np.where(zlog <= _KB_TD_BREAKS[2], _kb_log(_KB_TD2, _KB_TD2_U, zlog),
                          _kb_log(_KB_TD3, _KB_TD3_U, zlog))))
    td = 10.0 ** td_log * _TIME_TO_SI
    is_log = np.where(zlog <= _KB_IS_BREAK, _kb_log(_KB_IS1, _KB_IS1_U, zlog),
                      _kb_log(_KB_IS2, _KB_IS2_U, zlog))
    return ps, ta, td, 10.0 ** is_log * _IMPULSE_TO_SI


def reference_parameters(scaled_distance: Any) -> tuple[np.ndarray, ...]:
    """1 kg TNT free-air parameters at Z = R/W^(1/3) >= 0, with the near/far extensions.

    Returns (Ps Pa, ta s/kg^(1/3), Td s/kg^(1/3), I Pa s/kg^(1/3)); multiply the last three
    by W^(1/3) (kg^(1/3)) for a charge of W kg TNT.
    """
    z = np.asarray(scaled_distance, dtype=np.float64)
    ps, ta, td, imp = _kingery_bulmash(np.clip(z, Z_MIN, Z_MAX))
    ta = np.where(z < Z_MIN, ta * (np.maximum(z, 0.0) / Z_MIN), ta)
    far = z > Z_MAX
    spread = np.where(far, Z_MAX / np.where(far, z, Z_MAX), 1.0)
    ta = np.where(far, ta + (z - Z_MAX) / C0_M_S, ta)
    return ps * spread, ta, td, imp * spread


# --- Friedlander helpers (stable near 0), vectorised --------------------------------------

_SMALL = 0.1   # below this |x| the helpers use their Taylor series (degree 9, error < 1e-18)
_G_SERIES = np.array([(-1.0) ** n / math.factorial(n + 2) for n in range(10)])
_GP_SERIES = np.array([(-1.0) ** (m + 1) * (m + 1) / math.factorial(m + 3) for m in range(10)])
_Q_SERIES = np.array([(-1.0) ** n * (n + 1) / math.factorial(n + 2) for n in range(10)])


def _gfun(x: np.ndarray) -> np.ndarray:
    """(x - 1 + e^-x) / x^2 = integral_0^1 (1-s) e^(-xs) ds."""
    xs = np.where(np.abs(x) < _SMALL, 1.0, x)
    big = (xs + np.expm1(-xs)) / (xs * xs)
    return np.where(np.abs(x) < _SMALL, _horner(_G_SERIES, x), big)


def _gprime(x: np.ndarray) -> np.ndarray:
    """d gfun / dx = (hfun(x) - 2 gfun(x)) / x."""
    xs = np.where(np.abs(x) < _SMALL, 1.0, x)
    big = (_hfun(xs) - 2.0 * _gfun(xs)) / xs
    return np.where(np.abs(x) < _SMALL, _horner(_GP_SERIES, x), big)


def _hfun(x: np.ndarray) -> np.ndarray:
    """(1 - e^-x) / x."""
    xs = np.where(x == 0.0, 1.0, x)
    return np.where(x == 0.0, 1.0, -np.expm1(-xs) / xs)


def _qfun(x: np.ndarray) -> np.ndarray:
    """(1 - (1 + x) e^-x) / x^2 = integral_0^1 s e^(-xs) ds."""
    xs = np.where(np.abs(x) < _SMALL, 1.0, x)
    big = (-np.expm1(-xs) - xs * np.exp(-xs)) / (xs * xs)
    return np.where(np.abs(x) < _SMALL, _horner(_Q_SERIES, x), big)


_K_AT_B_MIN = float(_gfun(np.array(B_MIN)))
_K_FLOOR = 1e-9   # I/(Ps Td) below this is treated as 1e-9 (b ~ 1e9), only for odd inputs


def decay_coefficient(peak_overpressure: Any, positive_duration: Any, impulse: Any) -> np.ndarray:
    """Friedlander b with Ps Td (b - 1 + e^-b)/b^2 = I (vectorised Newton); >= B_MIN.

    Where I >= Ps Td g(B_MIN) (in particular I >= Ps Td / 2) b is B_MIN.
    """
    ps, td, imp = np.broadcast_arrays(np.asarray(peak_overpressure, dtype=np.float64),
                                      np.asarray(positive_duration, dtype=np.float64),
                                      np.asarray(impulse, dtype=np.float64))
    with np.errstate(divide="ignore", invalid="ignore"):
        k = imp / (ps * td)
    k = np.where(np.isfinite(k), k, _K_AT_B_MIN)
    k = np.clip(k, _K_FLOOR, _K_AT_B_MIN)
    # gfun is convex and decreasing: Newton from the left of the root converges monotonically.
    # gfun(b) >= (b - 1)/b^2 >= k at b = 1/k - 2 when k <= 1/4.
    b = np.where(k <= 0.25, np.maximum(1.0 / k - 2.0, B_MIN), B_MIN)
    for _ in range(100):
        step = (_gfun(b) - k) / _gprime(b)
        b = b - step
        if np.all(np.abs(step) <= 1e-15 * (b + 1.0)):
            break
    return np.maximum(b, B_MIN)


def positive_impulse(peak_overpressure: Any, positive_duration: Any, decay: Any) -> np.ndarray:
    """Closed-form positive-phase integral Ps Td (b - 1 + e^-b) / b^2 (Pa s)."""
    return (np.asarray(peak_overpressure, dtype=np.float64)
            * np.asarray(positive_duration, dtype=np.float64)
            * _gfun(np.asarray(decay, dtype=np.float64)))


def negative_phase(peak_overpressure: Any, decay: Any) -> tuple[np.ndarray, np.ndarray]:
    """(sigma, tau_end) of the bounded negative lobe: scale in (0, 1] and end in tau."""
    ps, b = np.broadcast_arrays(np.asarray(peak_overpressure, dtype=np.float64),
                                np.asarray(decay, dtype=np.float64))
    y_end = np.minimum(X_EPS / b, NEG_MAX_DURATION)
    inside = 1.0 / b <= y_end
    # extremum of (tau - 1) e^(-b tau) on (1, tau_end]
    depth = np.where(inside, np.exp(-1.0 - b) / b, y_end * np.exp(-b * (1.0 + y_end)))
    area = np.exp(-b) * y_end * y_end * _qfun(b * y_end)
    sigma = np.minimum(1.0, np.minimum(np.minimum(P0_PA, ps) / (ps * depth), _gfun(b) / area))
    return sigma, 1.0 + y_end


def _cumulative(tau: np.ndarray, b: np.ndarray, sigma: np.ndarray,
                tau_end: np.ndarray) -> np.ndarray:
    """G(tau) = integral_0^tau of the bounded profile (in units of Ps Td)."""
    tp = np.clip(tau, 0.0, 1.0)
    pos = tp * tp * _gfun(b * tp) - tp * (tp - 1.0) * _hfun(b * tp)
    y = np.clip(tau - 1.0, 0.0, tau_end - 1.0)
    neg = np.exp(-b) * y * y * _qfun(b * y)
    return pos - sigma * neg


def _profile_args(arrival_time: Any, positive_duration: Any, peak_overpressure: Any,
                  decay: Any, *times: Any) -> tuple[np.ndarray, ...]:
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in
                                   (*times, arrival_time, positive_duration,
                                    peak_overpressure, decay)))
    return tuple(arrays)


def overpressure(t: Any, arrival_time: Any, positive_duration: Any, peak_overpressure: Any,
                 decay: Any) -> np.ndarray:
    """p(t) - p0 (Pa) of the bounded modified Friedlander wave; 0 before arrival."""
    t, ta, td, ps, b = _profile_args(arrival_time, positive_duration, peak_overpressure,
                                     decay, t)
    sigma, tau_end = negative_phase(ps, b)
    tau = (t - ta) / td
    shape = (1.0 - tau) * np.exp(-b * np.clip(tau, 0.0, None))
    out = np.where(tau > 1.0, sigma * shape, shape) * ps
    return np.where((tau < 0.0) | (tau > tau_end), 0.0, out)


def impulse(t0: Any, t1: Any, arrival_time: Any, positive_duration: Any,
            peak_overpressure: Any, decay: Any) -> np.ndarray:
    """Exact integral of p - p0 over [t0, t1] (Pa s), closed form; negative if t1 < t0."""
    t0, t1, ta, td, ps, b = _profile_args(arrival_time, positive_duration,
                                          peak_overpressure, decay, t0, t1)
    sigma, tau_end = negative_phase(ps, b)
    g1 = _cumulative((t1 - ta) / td, b, sigma, tau_end)
    g0 = _cumulative((t0 - ta) / td, b, sigma, tau_end)
    return ps * td * (g1 - g0)


# --- charges -----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class BlastParameters:
    """Blast-wave parameters at each distance (SI units; arrays of one shape)."""

    distance_m: np.ndarray
    scaled_distance: np.ndarray       #: Z = R / W_TNT^(1/3) (m/kg^(1/3))
    peak_overpressure_pa: np.ndarray  #: Ps, peak incident (side-on) overpressure
    arrival_time_s: np.ndarray        #: ta, after detonation
    positive_duration_s: np.ndarray   #: Td
    decay_coefficient: np.ndarray     #: Friedlander b
    impulse_pa_s: np.ndarray          #: reference incident positive impulse I

    FIELDS = ("distance_m", "scaled_distance", "peak_overpressure_pa", "arrival_time_s",
              "positive_duration_s", "decay_coefficient", "impulse_pa_s")

    def overpressure(self, t: Any) -> np.ndarray:
        """p - p0 (Pa) at time(s) t after detonation (broadcast against the distances)."""
        return overpressure(t, self.arrival_time_s, self.positive_duration_s,
                            self.peak_overpressure_pa, self.decay_coefficient)

    def impulse(self, t0: Any, t1: Any) -> np.ndarray:
        """Exact integral of p - p0 over [t0, t1] (Pa s)."""
        return impulse(t0, t1, self.arrival_time_s, self.positive_duration_s,
                       self.peak_overpressure_pa, self.decay_coefficient)

    def records(self) -> list[dict[str, float]]:
        """One dict per distance (flattened), keys exactly :attr:`FIELDS`."""
        columns = [np.ravel(getattr(self, name)) for name in self.FIELDS]
        return [{name: float(col[i]) for name, col in zip(self.FIELDS, columns, strict=True)}
                for i in range(columns[0].size)]


def blast_parameters(distance_m: Any, charge_kg: Any, explosive: str = "TNT") -> BlastParameters:
    """Parameters of a spherical free-air burst of ``charge_kg`` of ``explosive``.

    distance_m (>= 0) and charge_kg (> 0) broadcast together; raises BlastvoxError on
    negative, non-finite or zero input and on an unknown explosive.
    """
    factor = tnt_equivalent(explosive)
    r = np.asarray(distance_m, dtype=np.float64)
    w = np.asarray(charge_kg, dtype=np.float64)
    if not np.all(np.isfinite(r)) or np.any(r < 0.0):
        raise BlastvoxError("distance must be a finite number of metres >= 0")
    if not np.all(np.isfinite(w)) or np.any(w <= 0.0):
        raise BlastvoxError("charge must be a finite mass in kg > 0")
    r, w = np.broadcast_arrays(r, w)
    cube = np.cbrt(w * factor)
    z = r / cube
    ps, ta, td, imp = reference_parameters(z)
    b = decay_coefficient(ps, td, imp)   # b depends on Z only: scaled values suffice
    return BlastParameters(distance_m=r.copy(), scaled_distance=z, peak_overpressure_pa=ps,
                           arrival_time_s=ta * cube, positive_duration_s=td * cube,
                           decay_coefficient=b, impulse_pa_s=imp * cube)


# --- numba scalar twins -------------------------------------------------------------------


@helper
def _horner_nb(coeffs, u):
    out = coeffs[coeffs.shape[0] - 1]
    for i in range(coeffs.shape[0] - 2, -1, -1):
        out = out * u + coeffs[i]
    return out


@helper
def reference_parameters_nb(z):
    """Scalar :func:`reference_parameters`: (Ps, ta, Td, I) per kg^(1/3) at Z >= 0."""
    zc = min(max(z, Z_MIN), Z_MAX)
    zlog = math.log10(zc) + _LOG10_Z_TO_IMPERIAL
    ps = 10.0 ** _horner_nb(_KB_PS, _KB_PS_U[0] + _KB_PS_U[1] * zlog) * _PSI_PA
    ta = 10.0 ** _horner_nb(_KB_TA, _KB_TA_U[0] + _KB_TA_U[1] * zlog) * _TIME_TO_SI
    if zlog <= _KB_TD_BREAKS[0]:
        td_log = _KB_TD0_LOG
    elif zlog <= _KB_TD_BREAKS[1]:
        td_log = _horner_nb(_KB_TD1, _KB_TD1_U[0] + _KB_TD1_U[1] * zlog)
    elif zlog <= _KB_TD_BREAKS[2]:
        td_log = _horner_nb(_KB_TD2, _KB_TD2_U[0] + _KB_TD2_U[1] * zlog)
    else:
        td_log = _horner_nb(_KB_TD3, _KB_TD3_U[0] + _KB_TD3_U[1] * zlog)
    td = 10.0 ** td_log * _TIME_TO_SI
    if zlog <= _KB_IS_BREAK:
        is_log = _horner_nb(_KB_IS1, _KB_IS1_U[0] + _KB_IS1_U[1] * zlog)
    else:
        is_log = _horner_nb(_KB_IS2, _KB_IS2_U[0] + _KB_IS2_U[1] * zlog)
    imp = 10.0 ** is_log * _IMPULSE_TO_SI
    if z < Z_MIN:
        ta = ta * (max(z, 0.0) / Z_MIN)
    elif z > Z_MAX:
        ta = ta + (z - Z_MAX) / C0_M_S
        ps = ps * (Z_MAX / z)
        imp = imp * (Z_MAX / z)
    return ps, ta, td, imp


@helper
def _gfun_nb(x):
    if abs(x) < _SMALL:
        return _horner_nb(_G_SERIES, x)
    return (x + math.expm1(-x)) / (x * x)


@helper
def _hfun_nb(x):
    if x == 0.0:
        return 1.0
    return -math.expm1(-x) / x


@helper
def _qfun_nb(x):
    if abs(x) < _SMALL:
        return _horner_nb(_Q_SERIES, x)
    return (-math.expm1(-x) - x * math.exp(-x)) / (x * x)


@helper
def _gprime_nb(x):
    if abs(x) < _SMALL:
        return _horner_nb(_GP_SERIES, x)
    return (_hfun_nb(x) - 2.0 * _gfun_nb(x)) / x


@nb.njit(cache=True)  # also called from Python (tests check it against the reference)
def decay_coefficient_nb(ps, td, imp):
    """Scalar :func:`decay_coefficient`."""
    k = imp / (ps * td)
    if not math.isfinite(k):
        k = _K_AT_B_MIN
    k = min(max(k, _K_FLOOR), _K_AT_B_MIN)
    b = max(1.0 / k - 2.0, B_MIN) if k <= 0.25 else B_MIN
    for _ in range(100):
        step = (_gfun_nb(b) - k) / _gprime_nb(b)
        b -= step
        if abs(step) <= 1e-15 * (b + 1.0):
            break
    return max(b, B_MIN)


@nb.njit(cache=True)  # also called from Python (tests check it against the reference)
def blast_parameters_nb(distance_m, charge_tnt_kg):
    """Scalar :func:`blast_parameters` for W kg *TNT-equivalent*: (Z, Ps, ta, Td, b, I)."""
    cube = np.cbrt(charge_tnt_kg)
    z = distance_m / cube
    ps, ta, td, imp = reference_parameters_nb(z)
    b = decay_coefficient_nb(ps, td, imp)
    return z, ps, ta * cube, td * cube, b, imp * cube


@nb.njit(cache=True)  # also called from Python (tests check it against the reference)
def negative_phase_nb(ps, b):
    """Scalar :func:`negative_phase`: (sigma, tau_end)."""
    y_end = min(X_EPS / b, NEG_MAX_DURATION)
    if 1.0 / b <= y_end:
        depth = math.exp(-1.0 - b) / b
    else:
        depth = y_end * math.exp(-b * (1.0 + y_end))
    area = math.exp(-b) * y_end * y_end * _qfun_nb(b * y_end)
    sigma = min(1.0, min(min(P0_PA, ps) / (ps * depth), _gfun_nb(b) / area))
    return sigma, 1.0 + y_end


@nb.njit(cache=True)  # also called from Python (tests check it against the reference)
def overpressure_nb(t, ta, td, ps, b):
    """Scalar :func:`overpressure`: p(t) - p0 (Pa)."""
    tau = (t - ta) / td
    if tau < 0.0:
        return 0.0
    shape = (1.0 - tau) * math.exp(-b * tau)
    if tau <= 1.0:
        return ps * shape
    sigma, tau_end = negative_phase_nb(ps, b)
    if tau > tau_end:
        return 0.0
    return sigma * ps * shape


@helper
def _cumulative_nb(tau, b, sigma, tau_end):
    tp = min(max(tau, 0.0), 1.0)
    pos = tp * tp * _gfun_nb(b * tp) - tp * (tp - 1.0) * _hfun_nb(b * tp)
    y = min(max(tau - 1.0, 0.0), tau_end - 1.0)
    if y == 0.0:
        return pos
    return pos - sigma * math.exp(-b) * y * y * _qfun_nb(b * y)


@nb.njit(cache=True)  # also called from Python (tests check it against the reference)
def impulse_nb(t0, t1, ta, td, ps, b):
    """Scalar :func:`impulse`: exact integral of p - p0 over [t0, t1] (Pa s)."""
    tau0 = (t0 - ta) / td
    tau1 = (t1 - ta) / td
    if tau0 <= 0.0 and tau1 <= 0.0:
        return 0.0
    sigma, tau_end = negative_phase_nb(ps, b)
    return ps * td * (_cumulative_nb(tau1, b, sigma, tau_end)
                      - _cumulative_nb(tau0, b, sigma, tau_end))
