"""The ambient air every blast quantity refers to: sea-level standard atmosphere (ISA).

numba freezes these globals into the kernels that use them, so this module counts
as numba code for :mod:`blastvox._kernel_cache`: editing it starts a fresh cache.
"""

from __future__ import annotations

P0_PA = 101_325.0   #: ambient pressure, sea-level standard atmosphere (Pa)
C0_M_S = 340.294    #: ambient speed of sound, ISA sea level 15 degC (m/s)
