"""The blast load on a face: reflection by angle of incidence, clearing, drag,
diffraction into shadows, and the negative phase.

A face of outward unit normal n at distance r from a charge, reached by the
wave along the unit radius u, has angle of incidence alpha with
cos(alpha) = -n . u. Its load, per unit area:

* **Facing the charge, in line of sight** (cos alpha > 0, the segment from the
  charge unobstructed, see :mod:`blastvox.simulate.shielding`): the normally
  reflected wave (Kingery-Bulmash reflected fits, UFC 3-340-02 Figs 2-7 and
  2-15) combined with the side-on load by angle of incidence, ConWep's
  ``normal cos^2 a + side (1 + cos^2 a - 2 cos a)`` (Randers-Pehrson &
  Bannister 1997, the form of UFC 3-340-02 Fig 2-193's trend and LS-DYNA's
  ``*LOAD_BLAST``), for both the peak and the impulse.
* **Clearing** (UFC 3-340-02 §2-15.3.2, Fig 2-196): on a surface of finite
  size the reflected pressure relieves to the stagnation pressure
  Ps + Cd q (front drag coefficient Cd = 1) within the clearing time
  tc = 4 S / ((1 + S/G) U), with S and G the smaller and larger of the
  surface's half-height and half-width (m) and U the shock front velocity;
  the reflected impulse is then the smaller of the normally reflected impulse
  and the stagnation impulse plus the triangle 0.5 (Pr - Ps - q) tc. A wall
  metres across keeps Ir; a 10 cm box is loaded as a drag target.
* **Side-on** (cos alpha = 0) and **shadowed or turned away** (cos alpha <= 0
  or the line of sight blocked): the diffracted wave, Ps + Cd q with the
  side, roof and rear-wall drag coefficient of UFC 3-340-02 §2-15.3.3
  (-0.4 below 25 psi, -0.3 to 50 psi, -0.2 above) - continuous with the
  facing load at cos alpha = 0. A wave that has wrapped round an obstacle is
  weakened further by the obstacle itself; that is not modelled.
* **Dynamic pressure** q = 5 Ps^2 / (2 (Ps + 7 p0)) (Rankine-Hugoniot,
  gamma = 1.4) decays as q (1 - tau)^2 e^(-2 b tau) (Glasstone & Dolan 1977,
  ch. III; Baker 1973): its impulse is q Td h(2b), h(c) = integral_0^1
  (1 - s)^2 e^(-c s) ds.
* **Negative phase**: every loaded face takes the incident negative phase
  (:mod:`blastvox.blast.underpressure`), the same on the front and the back
  of a body, so it never cancels the net push of the positive phase.

Time profile. A face's positive impulse is delivered with the shape of the
incident Friedlander positive phase at that point and its negative impulse
with the cubic negative phase, so the impulse of any step is closed form and
consecutive steps telescope to exactly the face's total (the momentum of a
piece does not depend on dt). The reflected pulse is in truth shorter than
the incident one (it clears); a rigid piece integrates the impulse, which is
what this keeps exact.

Tables. :func:`face_tables` holds, for each burst (``AIR`` free-air sphere,
``SURFACE`` hemispherical surface burst), the columns ``COLUMNS`` for 1 kg TNT
on the log-Z grid of :mod:`blastvox.blast.table`; :func:`face_params_at`
interpolates them at r from a charge of scale W^(1/3).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from blastvox.blast._numeric import horner_nb
from blastvox.blast.atmosphere import C0_M_S
from blastvox.blast.friedlander import decay_coefficient, positive_fraction_nb
from blastvox.blast.kingery_bulmash import AIR, SURFACE, Z_MAX, Z_MIN, burst_parameters
from blastvox.blast.reflection import dynamic_pressure, front_velocity, oblique_nb
from blastvox.blast.table import reference_grid, reference_table
from blastvox.blast.underpressure import negative_fraction_nb, negative_parameters
from blastvox.jit import helper

#: the columns of a face table, per 1 kg TNT: incident peak Pa, arrival s/kg^(1/3),
#: positive duration s/kg^(1/3), Friedlander b, incident impulse Pa s/kg^(1/3),
#: reflected peak Pa, reflected impulse Pa s/kg^(1/3), dynamic pressure Pa,
#: front velocity m/s, negative-phase peak Pa, impulse Pa s/kg^(1/3), duration s/kg^(1/3)
COLUMNS = ("ps", "ta", "td", "b", "is", "pr", "ir", "q", "u", "p_neg", "i_neg", "td_neg")
_GRID_LOG_LO = math.log10(Z_MIN)
_GRID_STEP = (math.log10(Z_MAX) - _GRID_LOG_LO) / (4096 - 1)
CD_FRONT = 1.0  #: UFC 3-340-02 §2-15.3.2: front-wall drag coefficient

_H_SERIES = np.array([2.0 * (-1.0) ** n / math.factorial(n + 3) for n in range(12)])


@functools.lru_cache(maxsize=1)
def face_tables() -> np.ndarray:
    """(2, GRID, 12) the face table of each burst (AIR, SURFACE), read-only; the air
    burst's first four columns are :func:`blastvox.blast.table.reference_table`'s."""
    z = reference_grid()
    tables = np.empty((2, len(z), len(COLUMNS)))
    for burst in (AIR, SURFACE):
        ps, ta, td, imp, pr, ir = burst_parameters(z, burst)
        b = decay_coefficient(ps, td, imp)
        if burst == AIR:  # bit for bit the incident table the rest of the model uses
            reference = reference_table()
            ps, ta, td, b = (reference[:, k] for k in range(4))
        p_neg, i_neg, td_neg = negative_parameters(z, imp)
        tables[burst] = np.stack([ps, ta, td, b, imp, pr, ir, dynamic_pressure(ps),
                                  front_velocity(ps), p_neg, i_neg, td_neg], axis=1)
    tables.flags.writeable = False
    return tables


@helper
def face_params_at(tables, burst, r, scale):
    """The 12 :data:`COLUMNS` at r (m) from a charge of scale W^(1/3) (kg^(1/3)), scaled.

    Outside the fitted range: held below Z_MIN (arrival linear in Z); beyond
    Z_MAX pressures and impulses fall as 1/R, q as 1/R^2, arrival at sound speed.
    """
    table = tables[burst]
    z = r / scale
    far = 1.0
    if z <= Z_MIN:
        i, w = 0, 0.0
        ta = table[0, 1] * z / Z_MIN
    elif z >= Z_MAX:
        i, w, far = table.shape[0] - 2, 1.0, Z_MAX / z
        ta = table[table.shape[0] - 1, 1] + (z - Z_MAX) / C0_M_S
    else:
        x = (math.log10(z) - _GRID_LOG_LO) / _GRID_STEP
        i = min(int(x), table.shape[0] - 2)
        w = x - i
        ta = _lerp(table, i, w, 1)
    return (_lerp(table, i, w, 0) * far, ta * scale, _lerp(table, i, w, 2) * scale,
            _lerp(table, i, w, 3), _lerp(table, i, w, 4) * far * scale,
            _lerp(table, i, w, 5) * far, _lerp(table, i, w, 6) * far * scale,
            _lerp(table, i, w, 7) * far * far, _lerp(table, i, w, 8),
            _lerp(table, i, w, 9) * far, _lerp(table, i, w, 10) * far * scale,
            _lerp(table, i, w, 11) * scale)


@helper
def _lerp(table, i, w, k):
    return table[i, k] * (1.0 - w) + table[i + 1, k] * w


@helper
def _hfun2_nb(c):
    """integral_0^1 (1 - s)^2 e^(-c s) ds = (c^2 - 2c + 2 - 2 e^-c) / c^3."""
    if abs(c) < 0.5:
        return horner_nb(_H_SERIES, c)
    return (c * c - 2.0 * c + 2.0 * (1.0 - math.exp(-c))) / (c * c * c)


@helper
def side_drag_coefficient(ps) -> float:
    """UFC 3-340-02 §2-15.3.3: drag coefficient of side walls, roofs and rear walls
    against peak incident overpressure ps (Pa)."""
    psi = ps / 6894.757293168361
    if psi < 25.0:
        return -0.4
    if psi < 50.0:
        return -0.3
    return -0.2


@helper
def face_load_nb(wave, cos_a, direct, s_clear, g_clear):
    """(positive impulse Pa s, peak overpressure Pa) on a face; see the module docstring.

    wave: the tuple (ps, td, b, is, pr, ir, q, u) of :func:`face_params_at`'s
    values at the face;
    cos_a: cosine of the angle of incidence (> 0 facing the charge); direct:
    the line of sight is clear; s_clear, g_clear: the loaded surface's smaller
    and larger half-extent across the wave (m), for clearing.
    """
    ps, td, b, imp, pr, ir, q, u = wave
    cd = side_drag_coefficient(ps)
    i_q = q * td * _hfun2_nb(2.0 * b)
    side_i = max(imp + cd * i_q, 0.0)
    side_p = max(ps + cd * q, 0.0)
    if not direct or cos_a <= 0.0:
        return side_i, side_p
    stagnation_p = ps + CD_FRONT * q
    tc = 4.0 * s_clear / ((1.0 + s_clear / max(g_clear, s_clear, 1e-300)) * u)
    cleared = imp + CD_FRONT * i_q + 0.5 * max(pr - stagnation_p, 0.0) * tc
    normal_i = min(ir, cleared)
    return oblique_nb(min(cos_a, 1.0), normal_i, side_i), oblique_nb(min(cos_a, 1.0), pr, side_p)


@helper
def face_step_fractions_nb(t0, t1, ta, td, b, td_neg):
    """(positive, negative) fractions of a face's phase impulses falling in [t0, t1] (s
    after detonation): of the positive phase (the incident Friedlander shape from ta over
    td) and of the negative phase (the cubic lobe from ta + td over td_neg). A face
    taking i_pos and i_neg gets i_pos * positive - i_neg * negative. (The products with
    1.0 and 0.0 keep the signed zeros of the earlier per-phase evaluation: the caches
    stay byte-identical.)"""
    if t1 <= ta:
        return 0.0, 0.0
    positive = positive_fraction_nb((t0 - ta) / td, (t1 - ta) / td, b)
    if td_neg <= 0.0:
        return 1.0 * positive, 0.0
    negative = 0.0 * positive
    if t1 > ta + td:
        negative -= negative_fraction_nb((t0 - ta - td) / td_neg, (t1 - ta - td) / td_neg)
    return 1.0 * positive, -negative
