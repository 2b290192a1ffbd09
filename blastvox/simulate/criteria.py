"""Failure criteria of fracture (:mod:`blastvox.simulate.fracture`): the pressure-impulse
curve, the crushing of a loaded surface, and a link's yield after its orientation to
the wave.

Pressure-impulse (P-I) curves (Baker et al. 1983, *Explosion Hazards and Evaluation*,
ch. 7; the hyperbola of Jarrett 1968): an element fails when (p - p0)(i - i0) >=
K p0 i0, with the quasi-static asymptote p0 (Pa) and the impulsive asymptote i0 (Pa s)
of its material (``blastvox/data/materials.toml``), i0 scaled with the element's
thickness from the 0.25 m element the table gives it for.
"""

from __future__ import annotations

from blastvox.blast.face_load import face_load_nb, face_params_at
from blastvox.jit import helper

REFERENCE_THICKNESS = 0.25  #: m: the element thickness a material's impulse asymptote is for


@helper
def pi_exceeded(p, i, p0, i0, shape) -> bool:
    """Pressure-impulse criterion: (p - p0)(i - i0) >= shape p0 i0 with p > p0, i > i0
    (Pa, Pa s); i0 = 0 is the peak-pressure criterion p > p0."""
    if p <= p0:
        return False
    if i0 <= 0.0:
        return True
    return i > i0 and (p - p0) * (i - i0) >= shape * p0 * i0


@helper
def crushes(front, c, r_surface, cos_a, exposure, b, strength, m, thickness) -> bool:
    """Does charge c's wave crush the loaded surface of an element of material m whose
    face lies r_surface m from it (in its line of sight, at incidence cosine cos_a), of
    a member ``thickness`` m thick (:func:`element_view`)?

    The face load there passes the crushing P-I curve: the material's crush pressure
    (its compressive strength) and its voxel impulse asymptote for a layer as thick as
    the member, at most the reference element's (:data:`REFERENCE_THICKNESS`). A member
    thicker than that is not pulverized through at once: its surface layer crushes
    (a crater), and the layer behind it is judged as the surface once the wave has
    taken the layer in front (in order of arrival). A massive block under a close-in
    charge craters; its breach asymptote, scaled by the thickness the stress wave
    crosses during the load (metres of concrete), would never be reached."""
    p0 = strength.crush[m]
    if p0 <= 0.0:
        return False
    (ps, _, td, bb, imp, pr, ir, q, u, _, _,
     _) = face_params_at(front.table, front.burst[c], max(r_surface, 1e-6), front.scale[c])
    i_pos, p_peak = face_load_nb((ps, td, bb, imp, pr, ir, q, u), cos_a, True,
                                 exposure.clearing[b, c, 0], exposure.clearing[b, c, 1])
    i0 = strength.voxel_impulse[m] * min(thickness, REFERENCE_THICKNESS) / REFERENCE_THICKNESS
    return pi_exceeded(p_peak, i_pos, p0, i0, strength.pi_shape[m])


@helper
def oriented_yield(yield_pa, orientation, body_rot, b, link_direction, link, dx, dy, dz,
                   r) -> float:
    """Yield (Pa) of a link after the orientation factor: Y (1 - k |R_hat . l_hat|).

    The link's rest direction ``link_direction[link]`` turns with body b's
    rotation ``body_rot[b]``; (dx, dy, dz) is the wave's radius vector R (m) from
    the charge to where it is taken, |R| = r. Indices, not row views: this runs
    once per link a front crosses, and a view costs two reference counts.
    """
    if r <= 0.0:
        return yield_pa
    cosang = 0.0
    for a in range(3):
        la = (body_rot[b, a, 0] * link_direction[link, 0]
              + body_rot[b, a, 1] * link_direction[link, 1]
              + body_rot[b, a, 2] * link_direction[link, 2])
        ra = dx if a == 0 else (dy if a == 1 else dz)
        cosang += la * ra / r
    return yield_pa * (1.0 - orientation * abs(cosang))
