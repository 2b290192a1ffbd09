"""Visual cues computed from the blast alone, after the run (Martins 2001 §6).

Shock sphere opacity: the sphere fades as the wave weakens, opacity =
clip(log10(Ps / 1 kPa) / 3, 0, 1): 1 at 1 MPa and above, 0 at 1 kPa.

Camera shake: when a wave reaches the scene's camera, the camera is
displaced by a damped oscillation whose amplitude grows with the peak
overpressure there: A = min(0.02 m sqrt(Ps / 1 kPa), 0.5 m), decay time
0.25 s, with incommensurate frequencies on the three axes (11, 13, 17 Hz) so
it does not look mechanical. Charges add up.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.blast._numeric import libm
from blastvox.blast.charge import blast_parameters
from blastvox.geometry import exact

_TAU_S = 0.25
_FREQ_HZ = np.array([11.0, 13.0, 17.0])
_PHASE = np.array([0.0, 1.3, 2.1])


def shock_opacity(radius: np.ndarray, tnt_kg: np.ndarray) -> np.ndarray:
    """Opacity (F, C) of each charge's shock sphere of radius (F, C) m; 0 where radius is 0."""
    out = np.zeros_like(radius)
    for c, w in enumerate(tnt_kg):
        r = radius[:, c]
        live = r > 0
        if live.any():
            ps = blast_parameters(r[live], w).peak_overpressure_pa
            out[live, c] = np.clip(libm(math.log10, np.maximum(ps, 1e-9) / 1e3) / 3.0, 0.0,
                                   1.0)
    return out


def camera_shake(camera_position: np.ndarray, times: np.ndarray, charge_position: np.ndarray,
                 tnt_kg: np.ndarray, charge_time: np.ndarray) -> np.ndarray:
    """Camera offsets (F, 3) in metres at frame ``times`` (s)."""
    offset = np.zeros((len(times), 3))
    for c in range(len(tnt_kg)):
        r = float(exact.norm(np.asarray(camera_position) - charge_position[c]))
        p = blast_parameters(r, tnt_kg[c])
        arrival = charge_time[c] + float(p.arrival_time_s)
        amplitude = min(0.02 * np.sqrt(float(p.peak_overpressure_pa) / 1e3), 0.5)
        s = times - arrival
        after = s >= 0
        envelope = np.where(after, amplitude * libm(math.exp, -np.where(after, s, 0.0) / _TAU_S),
                            0.0)
        phase = 2 * np.pi * _FREQ_HZ[None, :] * np.maximum(s, 0)[:, None] + _PHASE[None, :]
        offset += envelope[:, None] * libm(math.sin, phase) * after[:, None]
    return offset
