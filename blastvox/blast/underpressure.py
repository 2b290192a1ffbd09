"""A published negative phase: peak underpressure, negative impulse and a cubic profile.

(Named ``underpressure`` because ``blastvox.blast.negative_phase`` is already the
Friedlander lobe's function, which a submodule of that name would shadow.)

Model
-----
Granström (1956), *Loading characteristics of air blasts from detonating charges*, and
Drake et al. (1989), as given by Rigby, Tyas, Fay, Clarke & Warren, "The negative phase
of the blast load", *Int. J. Protective Structures* 5(1), 2014 (section 2), for a TNT
charge at scaled distance Z (m/kg^(1/3)):

    Pmin = 0.35 / Z bar  for Z > 3.5,   0.1 bar (10 kPa) for Z <= 3.5
    i-   = i+ (1 - 1/(2Z))                       (i+ the positive impulse)

and the cubic profile of the underpressure, s = (t - ta - Td) / Td- in [0, 1]:

    p(t) - p0 = -Pmin (27/4) s (1 - s)^2

whose minimum is -Pmin (at s = 1/3) and whose area is (9/16) Pmin Td-, so that
Td- = 16 i- / (9 Pmin). The profile and Td- agree with Rigby's ``Blast.m`` (University of
Sheffield) as ported in a public MATLAB class (``Class_Blast``: 6.75 s (1 - s)^2 and
tm = (16/9) im / pmin). The constants 0.35, 3.5 and 1/(2Z) could not be checked against a
retrievable copy of Granström or Rigby et al. here and are the ones the brief gives.

Reflected negative phase: UFC 3-340-02 Figure 2-16 gives Pr- and ir- only as curves; no
retrievable table of them was found, so a reflected negative impulse is taken with the
same ratio i-/i+ as the incident one (Ir- = Ir (1 - 1/(2Z))).

Bounds (so that the wave always pushes away on balance)
-------------------------------------------------------
1 - 1/(2Z) is negative for Z < 1/2 and tends to 1 as Z grows; the fraction used is
clamped to [0, 1 - 1e-6], so 0 <= i- < i+ at every Z > 0 (the cap binds only beyond
Z = 5e5 m/kg^(1/3)). Where i- = 0, Td- = 0 and there is no negative phase.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from blastvox.blast._numeric import run_kernel
from blastvox.jit import helper, kernel

BAR_PA = 1.0e5               #: 1 bar in Pa
Z_KNEE = 3.5                 #: Granström: Pmin constant at or below this Z (m/kg^(1/3))
P_MIN_NEAR_PA = 0.1 * BAR_PA  #: Granström: Pmin for Z <= Z_KNEE
FRACTION_MAX = 1.0 - 1.0e-6  #: cap of i-/i+ (keeps a net positive push at huge Z)
SHAPE_AREA = 9.0 / 16.0      #: integral_0^1 (27/4) s (1 - s)^2 ds


@helper
def negative_parameters_nb(z, i_pos):
    """(Pmin Pa, i- Pa s, Td- s) of the negative phase at Z >= 0 (m/kg^(1/3)) of a wave
    whose positive impulse is i_pos >= 0 (Pa s); Pmin > 0 is the depth below p0."""
    if z > Z_KNEE:
        p_min = 0.35 * BAR_PA / z
    else:
        p_min = P_MIN_NEAR_PA
    fraction = 0.0
    if z > 0.5:
        fraction = min(1.0 - 0.5 / z, FRACTION_MAX)
    i_neg = max(i_pos, 0.0) * fraction
    return p_min, i_neg, i_neg / (SHAPE_AREA * p_min)


@helper
def _cumulative_nb(s):
    """Fraction of the lobe's impulse before normalised time s in [0, 1]: 6s^2 - 8s^3 + 3s^4."""
    s = min(max(s, 0.0), 1.0)
    return s * s * (6.0 + s * (-8.0 + 3.0 * s))


@helper
def negative_fraction_nb(s0, s1):
    """Fraction (0..1) of the cubic lobe's impulse between normalised times s0 <= s1
    (each clamped to [0, 1]), closed form: sums over consecutive windows telescope."""
    return _cumulative_nb(s1) - _cumulative_nb(s0)


@kernel
def _parameters_kernel(z, i_pos, out):
    for i in range(z.shape[0]):
        p_min, i_neg, td_neg = negative_parameters_nb(z[i], i_pos[i])
        out[0, i] = p_min
        out[1, i] = i_neg
        out[2, i] = td_neg


@kernel
def _fraction_kernel(s0, s1, out):
    for i in range(s0.shape[0]):
        out[0, i] = negative_fraction_nb(s0[i], s1[i])


def negative_parameters(scaled_distance: Any, positive_impulse: Any) -> tuple[np.ndarray, ...]:
    """NumPy face of :func:`negative_parameters_nb`: (Pmin, i-, Td-) arrays."""
    return run_kernel(_parameters_kernel, 3, scaled_distance, positive_impulse)


def negative_fraction(s0: Any, s1: Any) -> np.ndarray:
    """NumPy face of :func:`negative_fraction_nb`."""
    return run_kernel(_fraction_kernel, 1, s0, s1)[0]
