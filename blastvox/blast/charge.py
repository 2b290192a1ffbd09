"""The blast of a charge at given distances: TNT equivalence and Hopkinson-Cranz scaling
of the 1 kg TNT reference.

W is the TNT-equivalent mass (kg) and Z = R / W^(1/3); pressures (and b) are equal at
equal Z, times and impulses scale by W^(1/3). The result is defined and finite for
every R >= 0 and W > 0 (see :mod:`blastvox.blast.kingery_bulmash` for Z outside the
fits). ``burst`` is "air" (a spherical charge in free air, the default) or "surface" (a
hemispherical charge on the ground); normally reflected Pr and Ir come with both.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from blastvox.blast._numeric import flat_arrays
from blastvox.blast.explosives import tnt_equivalent
from blastvox.blast.friedlander import decay_coefficient_nb, impulse, overpressure
from blastvox.blast.kingery_bulmash import burst_code, burst_parameters_nb, reference_parameters_nb
from blastvox.errors import BlastvoxError
from blastvox.jit import kernel


@kernel  # also called from Python (tests)
def blast_parameters_nb(distance_m, charge_tnt_kg):
    """(Z, Ps, ta, Td, b, I) at distance_m of charge_tnt_kg kg *TNT-equivalent* (SI)."""
    cube = np.cbrt(charge_tnt_kg)
    z = distance_m / cube
    ps, ta, td, imp = reference_parameters_nb(z)
    b = decay_coefficient_nb(ps, td, imp)   # b depends on Z only: scaled values suffice
    return z, ps, ta * cube, td * cube, b, imp * cube


@kernel  # also called from Python (tests)
def charge_parameters_nb(distance_m, charge_tnt_kg, burst):
    """(Z, Ps, ta, Td, b, I, Pr, Ir) at distance_m of charge_tnt_kg kg TNT-equivalent for
    ``burst`` AIR (0) or SURFACE (1) (SI; Pr, Ir normally reflected). For AIR the first six
    are :func:`blast_parameters_nb`'s, bit for bit."""
    cube = np.cbrt(charge_tnt_kg)
    z = distance_m / cube
    ps, ta, td, imp, pr, ir = burst_parameters_nb(z, burst)
    b = decay_coefficient_nb(ps, td, imp)
    return z, ps, ta * cube, td * cube, b, imp * cube, pr, ir * cube


@kernel
def _blast_parameters_kernel(distance_m, charge_tnt_kg, burst, out):
    for i in range(distance_m.shape[0]):
        values = charge_parameters_nb(distance_m[i], charge_tnt_kg[i], burst)
        for k in range(8):
            out[k, i] = values[k]


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
    reflected_overpressure_pa: np.ndarray  #: Pr, peak normally reflected overpressure
    reflected_impulse_pa_s: np.ndarray     #: Ir, normally reflected positive impulse

    FIELDS = ("distance_m", "scaled_distance", "peak_overpressure_pa", "arrival_time_s",
              "positive_duration_s", "decay_coefficient", "impulse_pa_s",
              "reflected_overpressure_pa", "reflected_impulse_pa_s")

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


def blast_parameters(distance_m: Any, charge_kg: Any, explosive: str = "TNT",
                     burst: Any = "air") -> BlastParameters:
    """NumPy face of :func:`charge_parameters_nb` for ``charge_kg`` of ``explosive``.

    distance_m (>= 0) and charge_kg (> 0) broadcast together; ``burst`` "air" or
    "surface". Raises BlastvoxError on negative, non-finite or zero input and on an
    unknown explosive or burst.
    """
    factor = tnt_equivalent(explosive)
    code = burst_code(burst)
    r = np.asarray(distance_m, dtype=np.float64)
    w = np.asarray(charge_kg, dtype=np.float64)
    if not np.all(np.isfinite(r)) or np.any(r < 0.0):
        raise BlastvoxError("distance must be a finite number of metres >= 0")
    if not np.all(np.isfinite(w)) or np.any(w <= 0.0):
        raise BlastvoxError("charge must be a finite mass in kg > 0")
    shape, (r, w) = flat_arrays(r, w * factor)
    out = np.empty((8, r.size))
    _blast_parameters_kernel(r, w, code, out)
    z, ps, ta, td, b, imp, pr, ir = (row.reshape(shape) for row in out)
    return BlastParameters(distance_m=r.reshape(shape), scaled_distance=z,
                           peak_overpressure_pa=ps, arrival_time_s=ta, positive_duration_s=td,
                           decay_coefficient=b, impulse_pa_s=imp, reflected_overpressure_pa=pr,
                           reflected_impulse_pa_s=ir)
