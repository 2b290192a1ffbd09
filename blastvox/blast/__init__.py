"""The blast-wave model shared by every stage (``blast``, ``simulate``, ``preview``).

A spherical free-air (or hemispherical surface) burst: Kingery-Bulmash reference data for
1 kg TNT, incident and normally reflected, scaled to a charge by TNT equivalence and
Hopkinson-Cranz; the modified Friedlander profile with a bounded negative phase and its
exact impulse over any window; oblique reflection and a published negative phase.

=====================  =================================================================
module                 contents
=====================  =================================================================
``atmosphere``         P0_PA, C0_M_S: the ambient air of the reference data
``explosives``         tnt_equivalent, known_explosives, TNT_EQUIVALENTS (pure Python)
``kingery_bulmash``    Z_MIN, Z_MAX, reference_parameters(_nb): the 1 kg TNT fits;
                       AIR, SURFACE, burst_parameters(_nb): with normal reflection, and
                       the hemispherical surface burst
``reflection``         oblique, front_velocity, dynamic_pressure (and ``*_nb``): a wave
                       meeting a surface, Rankine-Hugoniot
``underpressure``      negative_parameters, negative_fraction (and ``*_nb``): Granström's
                       published negative phase, cubic profile
``friedlander``        decay_coefficient, positive_impulse, negative_phase, overpressure,
                       impulse (and ``*_nb``), exceedance_nb: the pressure-time profile
``charge``             blast_parameters(_nb), charge_parameters_nb, BlastParameters: a
                       charge at distances
``table``              reference_table, params_at, peak_overpressure, point_impulse,
                       exceedance_integral: the tabulated form simulator kernels use
=====================  =================================================================

Every formula is one scalar numba function (``*_nb``, ``cache=True``); the
NumPy faces (array in, array out) run the same functions in compiled loops.

The names below are importable from this package; each loads only its module,
so ``import blastvox.blast`` costs nothing and ``tnt_equivalent`` loads no numba.
"""

from __future__ import annotations

import importlib

_HOME = {
    "atmosphere": ("C0_M_S", "P0_PA"),
    "explosives": ("TNT_DENSITY_KG_M3", "TNT_EQUIVALENTS", "known_explosives",
                   "tnt_equivalent"),
    "kingery_bulmash": ("AIR", "BURST_TITLES", "SURFACE", "Z_MAX", "Z_MIN", "Z_MIN_SURFACE",
                        "burst_code", "burst_parameters", "burst_parameters_nb",
                        "reference_parameters", "reference_parameters_nb"),
    "reflection": ("dynamic_pressure", "dynamic_pressure_nb", "front_velocity",
                   "front_velocity_nb", "oblique", "oblique_nb"),
    "underpressure": ("negative_fraction", "negative_fraction_nb", "negative_parameters",
                       "negative_parameters_nb"),
    "friedlander": ("B_MIN", "NEG_CUTOFF", "NEG_MAX_DURATION", "X_EPS", "decay_coefficient",
                    "decay_coefficient_nb", "exceedance_nb", "impulse", "impulse_nb",
                    "negative_phase", "negative_phase_nb", "overpressure", "overpressure_nb",
                    "positive_impulse", "positive_impulse_nb"),
    "charge": ("BlastParameters", "blast_parameters", "blast_parameters_nb",
               "charge_parameters_nb"),
    "table": ("exceedance_integral", "params_at", "peak_overpressure", "point_impulse",
              "reference_grid", "reference_table"),
}
_MODULE_OF = {name: module for module, names in _HOME.items() for name in names}

__all__ = sorted(_MODULE_OF)


def __getattr__(name: str) -> object:
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})

