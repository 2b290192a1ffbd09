"""TNT equivalence: kg of TNT per kg of a named explosive (pressure-based factors).

Pure Python (no NumPy or numba): scene validation and the CLI can look names
up without loading the compiled model.
"""

from __future__ import annotations

from blastvox.errors import BlastvoxError

TNT_DENSITY_KG_M3 = 1600.0   #: cast TNT; its 1 kg sphere has radius 0.0530 m ~ Z_MIN

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
