"""The modified Friedlander pressure-time profile: decay coefficient, bounded negative
phase, exact impulse over any time window, and the impulse above a threshold.

Decay coefficient b and the profile
-----------------------------------
Overpressure, tau = (t - ta)/Td:  p - p0 = 0 for tau < 0 and Ps (1 - tau) e^(-b tau)
for tau >= 0 (Baker 1973; Mazarak et al. 1999 eq. 2.1; Martins et al. 2001 eq. 3-1).
b is solved so that the positive-phase integral equals the reference impulse:

    integral_0^Td Ps (1 - t/Td) e^(-b t/Td) dt = Ps Td (b - 1 + e^-b) / b^2 = I

i.e. g(b) = I/(Ps Td) with g(b) = (b - 1 + e^-b)/b^2 = integral_0^1 (1-s) e^(-bs) ds,
which decreases from 1/2 (b -> 0) to 0 and is convex, so Newton's method from a point
left of the root converges monotonically (reproduces the k-alpha table of NAVFAC
DM-2.08, 1986, to its two decimals). g never exceeds 1/2, so a reference with
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

Exact impulse over a window
---------------------------
With G(tau) = integral_0^tau of the bounded profile / (Ps Td), the impulse of [t0, t1]
is Ps Td (G(tau1) - G(tau0)), in closed form:
    positive phase  G(tau) = tau^2 gfun(b tau) - tau (tau - 1) hfun(b tau),
    negative lobe   integral_1^tau (u - 1) e^(-b u) du = e^-b y^2 qfun(b y), y = tau - 1,
with gfun(x) = (x - 1 + e^-x)/x^2, hfun(x) = (1 - e^-x)/x, qfun(x) = (1 - (1 + x) e^-x)/x^2
evaluated with series near 0 (no cancellation). A shock that crosses a point inside a
step is therefore never missed, and sums over consecutive steps telescope exactly.

Faces
-----
The ``*_nb`` functions are the implementation (scalar float64, compiled with
``cache=True``; the argument order is the NumPy face's). The NumPy faces broadcast
their arguments and run the same functions over them in a compiled loop. One
difference is deliberate: :func:`decay_coefficient` runs Newton on all elements
together until every one has converged (so an element may take a step or two more
than :func:`decay_coefficient_nb` alone, a change of at most ~1e-13 relative); the
simulator's reference table is built with it and its caches depend on these bits.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from blastvox.blast._numeric import horner_nb, run_kernel
from blastvox.blast.atmosphere import P0_PA
from blastvox.jit import helper, kernel

B_MIN = 1.0e-3          #: decay coefficient floor where I >= Ps Td / 2
NEG_CUTOFF = 0.01       #: the negative lobe ends when back within 1 % of its extremum
NEG_MAX_DURATION = 3.0  #: negative phase at most this many positive durations


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

# --- g, h, q and g' (stable near 0) --------------------------------------------------------

_SMALL = 0.1   # below this |x| the helpers use their Taylor series (degree 9, error < 1e-18)
_G_SERIES = np.array([(-1.0) ** n / math.factorial(n + 2) for n in range(10)])
_GP_SERIES = np.array([(-1.0) ** (m + 1) * (m + 1) / math.factorial(m + 3) for m in range(10)])
_Q_SERIES = np.array([(-1.0) ** n * (n + 1) / math.factorial(n + 2) for n in range(10)])


@helper
def _gfun_nb(x):
    """(x - 1 + e^-x) / x^2 = integral_0^1 (1-s) e^(-xs) ds."""
    if abs(x) < _SMALL:
        return horner_nb(_G_SERIES, x)
    return (x + math.expm1(-x)) / (x * x)


@helper
def _hfun_nb(x):
    """(1 - e^-x) / x."""
    if x == 0.0:
        return 1.0
    return -math.expm1(-x) / x


@helper
def _qfun_nb(x):
    """(1 - (1 + x) e^-x) / x^2 = integral_0^1 s e^(-xs) ds."""
    if abs(x) < _SMALL:
        return horner_nb(_Q_SERIES, x)
    return (-math.expm1(-x) - x * math.exp(-x)) / (x * x)


@helper
def _gprime_nb(x):
    """d gfun / dx = (hfun(x) - 2 gfun(x)) / x."""
    if abs(x) < _SMALL:
        return horner_nb(_GP_SERIES, x)
    return (_hfun_nb(x) - 2.0 * _gfun_nb(x)) / x


# --- decay coefficient ------------------------------------------------------------------

_K_FLOOR = 1e-9   # I/(Ps Td) below this is treated as 1e-9 (b ~ 1e9), only for odd inputs
_NEWTON_ITERATIONS = 100


@helper
def _decay_start_nb(ps, td, imp):
    """(k, b0): the target g(b) = k = I/(Ps Td), clamped to [_K_FLOOR, g(B_MIN)] (g(B_MIN)
    where not finite), and a start left of the root, from which Newton is monotone."""
    k_max = _gfun_nb(B_MIN)
    den = ps * td
    k = imp / den if den != 0.0 else math.inf
    if not math.isfinite(k):
        k = k_max
    k = min(max(k, _K_FLOOR), k_max)
    # gfun(b) >= (b - 1)/b^2 >= k at b = 1/k - 2 when k <= 1/4
    return k, max(1.0 / k - 2.0, B_MIN) if k <= 0.25 else B_MIN


@helper
def _decay_step_nb(b, k):
    """Newton's step for gfun(b) = k."""
    return (_gfun_nb(b) - k) / _gprime_nb(b)


@kernel  # also called from Python (tests)
def decay_coefficient_nb(ps, td, imp):
    """Friedlander b >= B_MIN with Ps Td (b - 1 + e^-b)/b^2 = I; B_MIN where
    I >= Ps Td g(B_MIN) (in particular I >= Ps Td / 2)."""
    k, b = _decay_start_nb(ps, td, imp)
    for _ in range(_NEWTON_ITERATIONS):
        step = _decay_step_nb(b, k)
        b -= step
        if abs(step) <= 1e-15 * (b + 1.0):
            break
    return max(b, B_MIN)


@kernel
def _decay_kernel(ps, td, imp, out):
    """:func:`decay_coefficient_nb` on all elements together: every b takes Newton steps
    until all have converged."""
    n = ps.shape[0]
    b = out[0]
    k = np.empty(n)
    for i in range(n):
        k[i], b[i] = _decay_start_nb(ps[i], td[i], imp[i])
    for _ in range(_NEWTON_ITERATIONS):
        done = True
        for i in range(n):
            step = _decay_step_nb(b[i], k[i])
            b[i] -= step
            if not abs(step) <= 1e-15 * (b[i] + 1.0):
                done = False
        if done:
            break
    for i in range(n):
        b[i] = max(b[i], B_MIN)


def decay_coefficient(peak_overpressure: Any, positive_duration: Any, impulse: Any) -> np.ndarray:
    """NumPy face of :func:`decay_coefficient_nb` (Newton on all elements together)."""
    return run_kernel(_decay_kernel, 1, peak_overpressure, positive_duration, impulse)[0]


@helper
def positive_impulse_nb(ps, td, b):
    """Closed-form positive-phase integral Ps Td (b - 1 + e^-b) / b^2 (Pa s)."""
    return ps * td * _gfun_nb(b)


@kernel
def _positive_impulse_kernel(ps, td, b, out):
    for i in range(ps.shape[0]):
        out[0, i] = positive_impulse_nb(ps[i], td[i], b[i])


def positive_impulse(peak_overpressure: Any, positive_duration: Any, decay: Any) -> np.ndarray:
    """NumPy face of :func:`positive_impulse_nb` (Pa s)."""
    return run_kernel(_positive_impulse_kernel, 1, peak_overpressure, positive_duration,
                      decay)[0]


# --- negative phase, profile, exact impulse -----------------------------------------------


@kernel  # also called from Python (tests)
def negative_phase_nb(ps, b):
    """(sigma, tau_end) of the bounded negative lobe: scale in (0, 1] and end in tau."""
    y_end = min(X_EPS / b, NEG_MAX_DURATION)
    if 1.0 / b <= y_end:   # extremum of (tau - 1) e^(-b tau) on (1, tau_end]
        depth = math.exp(-1.0 - b) / b
    else:
        depth = y_end * math.exp(-b * (1.0 + y_end))
    area = math.exp(-b) * y_end * y_end * _qfun_nb(b * y_end)
    sigma = min(1.0, min(min(P0_PA, ps) / (ps * depth), _gfun_nb(b) / area))
    return sigma, 1.0 + y_end


@kernel
def _negative_phase_kernel(ps, b, out):
    for i in range(ps.shape[0]):
        sigma, tau_end = negative_phase_nb(ps[i], b[i])
        out[0, i] = sigma
        out[1, i] = tau_end


def negative_phase(peak_overpressure: Any, decay: Any) -> tuple[np.ndarray, np.ndarray]:
    """NumPy face of :func:`negative_phase_nb`: (sigma, tau_end) arrays."""
    sigma, tau_end = run_kernel(_negative_phase_kernel, 2, peak_overpressure, decay)
    return sigma, tau_end


@kernel  # also called from Python (tests)
def overpressure_nb(t, ta, td, ps, b):
    """p(t) - p0 (Pa) of the bounded modified Friedlander wave; 0 before arrival."""
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


@kernel
def _overpressure_kernel(t, ta, td, ps, b, out):
    for i in range(t.shape[0]):
        out[0, i] = overpressure_nb(t[i], ta[i], td[i], ps[i], b[i])


def overpressure(t: Any, arrival_time: Any, positive_duration: Any, peak_overpressure: Any,
                 decay: Any) -> np.ndarray:
    """NumPy face of :func:`overpressure_nb` (Pa)."""
    return run_kernel(_overpressure_kernel, 1, t, arrival_time, positive_duration,
                      peak_overpressure, decay)[0]


@helper
def _cumulative_nb(tau, b, sigma, tau_end):
    """G(tau) = integral_0^tau of the bounded profile (in units of Ps Td)."""
    tp = min(max(tau, 0.0), 1.0)
    pos = tp * tp * _gfun_nb(b * tp) - tp * (tp - 1.0) * _hfun_nb(b * tp)
    y = min(max(tau - 1.0, 0.0), tau_end - 1.0)
    if y == 0.0:
        return pos
    return pos - sigma * math.exp(-b) * y * y * _qfun_nb(b * y)


@helper
def _positive_cumulative_nb(tau, b):
    """integral_0^tau of the positive phase alone (in units of Ps Td), tau clamped to [0, 1]."""
    tp = min(max(tau, 0.0), 1.0)
    return tp * tp * _gfun_nb(b * tp) - tp * (tp - 1.0) * _hfun_nb(b * tp)


@helper
def positive_fraction_nb(tau0, tau1, b):
    """Fraction (0..1) of the positive phase's impulse between tau0 <= tau1 (in units
    of Td from arrival); consecutive windows telescope exactly. A window wholly before
    arrival or after the phase is exactly 0 (both ends clamp alike), without the
    exponentials."""
    if tau0 >= 1.0 or tau1 <= 0.0:
        return 0.0
    return (_positive_cumulative_nb(tau1, b) - _positive_cumulative_nb(tau0, b)) / _gfun_nb(b)


@kernel  # also called from Python (tests)
def impulse_nb(t0, t1, ta, td, ps, b):
    """Exact integral of p - p0 over [t0, t1] (Pa s), closed form; negative if t1 < t0."""
    tau0 = (t0 - ta) / td
    tau1 = (t1 - ta) / td
    if tau0 <= 0.0 and tau1 <= 0.0:
        return 0.0
    sigma, tau_end = negative_phase_nb(ps, b)
    return ps * td * (_cumulative_nb(tau1, b, sigma, tau_end)
                      - _cumulative_nb(tau0, b, sigma, tau_end))


@kernel
def _impulse_kernel(t0, t1, ta, td, ps, b, out):
    for i in range(t0.shape[0]):
        out[0, i] = impulse_nb(t0[i], t1[i], ta[i], td[i], ps[i], b[i])


def impulse(t0: Any, t1: Any, arrival_time: Any, positive_duration: Any,
            peak_overpressure: Any, decay: Any) -> np.ndarray:
    """NumPy face of :func:`impulse_nb` (Pa s)."""
    return run_kernel(_impulse_kernel, 1, t0, t1, arrival_time, positive_duration,
                      peak_overpressure, decay)[0]


@helper
def exceedance_nb(ps, td, b, threshold):
    """Integral over the positive phase of max(p - p0 - threshold, 0) dt, Pa s.

    The positive phase is decreasing, so the overpressure exceeds ``threshold``
    on [0, tau*] with Ps (1 - tau*) e^(-b tau*) = threshold (Newton from the
    left, monotone). Closed form: Td [Ps F(tau*) - threshold tau*] with
    F(tau) = integral_0^tau (1 - s) e^(-b s) ds.
    """
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
