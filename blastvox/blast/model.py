"""Former single-module home of the blast model, kept so that old imports work.

New code imports from :mod:`blastvox.blast` (or its modules, listed there).
"""

from __future__ import annotations

from blastvox.blast.atmosphere import C0_M_S, P0_PA
from blastvox.blast.charge import BlastParameters, blast_parameters, blast_parameters_nb
from blastvox.blast.explosives import (
    TNT_DENSITY_KG_M3,
    TNT_EQUIVALENTS,
    known_explosives,
    tnt_equivalent,
)
from blastvox.blast.friedlander import (
    B_MIN,
    NEG_CUTOFF,
    NEG_MAX_DURATION,
    X_EPS,
    decay_coefficient,
    decay_coefficient_nb,
    impulse,
    impulse_nb,
    negative_phase,
    negative_phase_nb,
    overpressure,
    overpressure_nb,
    positive_impulse,
)
from blastvox.blast.kingery_bulmash import (
    Z_MAX,
    Z_MIN,
    reference_parameters,
    reference_parameters_nb,
)

__all__ = [
    "B_MIN", "C0_M_S", "NEG_CUTOFF", "NEG_MAX_DURATION", "P0_PA", "TNT_DENSITY_KG_M3",
    "TNT_EQUIVALENTS", "X_EPS", "Z_MAX", "Z_MIN", "BlastParameters", "blast_parameters",
    "blast_parameters_nb", "decay_coefficient", "decay_coefficient_nb", "impulse",
    "impulse_nb", "known_explosives", "negative_phase", "negative_phase_nb", "overpressure",
    "overpressure_nb", "positive_impulse", "reference_parameters", "reference_parameters_nb",
    "tnt_equivalent",
]
