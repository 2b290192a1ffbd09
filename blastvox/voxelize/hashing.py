"""Counter-based random numbers: a value per (seed, stream, key), independent of order.

Jitter uses these so that a lattice vertex moves the same way whichever voxels
happen to be occupied around it (adding a voxel does not reshuffle the others).
"""

from __future__ import annotations

import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _splitmix64(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        z = x + _GOLDEN
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def uniform_by_key(seed: int, stream: int, keys: np.ndarray) -> np.ndarray:
    """Uniform floats in [0, 1), one per integer key (any shape), reproducible."""
    with np.errstate(over="ignore"):
        base = _splitmix64(np.uint64(seed) * np.uint64(0x100000001B3) + np.uint64(stream))
        z = _splitmix64(np.asarray(keys, dtype=np.uint64) ^ base)
    return (z >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)
