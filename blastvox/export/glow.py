"""The glow of fire and the fireball: how big each particle's glow is, and how the
glows of many particles are pooled into blobs that keep their identity from frame to
frame (the export's ``Particles/<system>_glow``, :mod:`blastvox.export.usd_effects`).

**How long a fireball glows.** Measured fireballs scale with the cube root of the
mass that burns: a maximum diameter D = 3.77 W^0.325 m and a duration
t = 0.258 W^0.349 s (W in kg), the correlation of fireball experiments quoted in
L. N. Davis, *Frozen Fire* (Friends of the Earth, 1979; Japanese translation, LNG
study group, 1981), as cited at http://blog.livedoor.jp/lngdata/archives/50417978.html.
The CCPS correlation for the fireballs of burst fuel tanks, D = 5.8 W^(1/3) m and
t = 0.45 W^(1/3) s (W < 30,000 kg; Center for Chemical Process Safety, as summarised
at https://www.scribd.com/document/529343808/), is of the same form and larger: a
tank's fuel burns in air, while a high explosive's fireball is its detonation
products' afterburn. For 50 kg of TNT: D = 13.5 m, t = 1.0 s (CCPS: 21 m, 1.7 s);
20 kg: 10.0 m, 0.74 s. The simulator's fireball (blastvox.simulate.effects) throws
its 200 particles of 0.8 W^(1/3) m out to about 1.5 W^(1/3) m from the charge, so
the cloud spans about 3.8 W^(1/3) m (14 m for 50 kg): the measured D. Its particles
live 1.2 s whatever the charge; the glow here lasts the measured t instead (1.0 s
for 50 kg, 0.74 s for 20 kg), never longer than the particles.

**How bright.** A particle's gas cools linearly over the glow's duration from the
volumes' ``hot_k`` (blastvox.export.volumes.VOLUME_LOOKS: 2,200 K for the fireball,
1,600 K for fire) to the Draper point, 798 K, below which hot matter gives no visible
light. Its glow is ``core`` times its diameter (GLOW_LOOKS in usd_glow) times
sqrt((T^4 - 798^4) / (hot_k^4 - 798^4)): its area, about its visible light, follows
a blackbody's T^4, and it is nothing when the gas stops glowing, so a glow never
vanishes at full size. Fire's particles, born all the time, also grow in over
``rise`` seconds instead of appearing at full size. The same law with a hotter floor
(GLOW_LOOKS' ``hot_core_k``: 1,500 K for the fireball, reached at half its duration)
sizes each blob's yellow core, which so shrinks away before its red rim.

**Pooling that keeps identities.** Many coincident translucent shells render as an
opaque wall (a renderer stops after a few transparent surfaces: Blender's Cycles
after 8), so particles are pooled. Each particle joins one group for life, at birth
(:func:`glow_groups`): a group is the particles born within ``window`` seconds of its
first one and within ``reach`` metres of where that one was born, so each charge's
fireball is one group and fire's groups are its flames of a quarter second on about
a metre of burning wall. At each frame a group is one blob (:func:`glow_blobs`), its
id the group's number: at its members' mean position and velocity, weighted by the
area of their glows, as wide as their mean glow plus 2.6 times their RMS distance
from the centre (a uniform ball's radius is 1.29 times its RMS radius) scaled by
the share of the group's full glow left. Every term moves continuously with its
members, so a blob drifts, grows and shrinks from frame to frame and fades out by
its scale; it never jumps, splits or pops.
"""

from __future__ import annotations

import numpy as np

from blastvox.geometry import fixed

#: the measured fireball: maximum diameter D = a W^b m and duration t = c W^d s (W, kg)
FIREBALL_DIAMETER = (3.77, 0.325)
FIREBALL_DURATION = (0.258, 0.349)
#: K: the Draper point, below which hot matter gives no visible light
DRAPER_K = 798.0
#: a group's blob: its glow's mean plus this many times its members' RMS distance
SPREAD = 2.6


def fireball_duration(tnt_kg: np.ndarray) -> np.ndarray:
    """Seconds a fireball of ``tnt_kg`` (kg TNT) glows: 0.258 W^0.349 (see the module)."""
    c, d = FIREBALL_DURATION
    return c * fixed.power(np.asarray(tnt_kg, dtype=np.float64), d)


def fireball_diameter(tnt_kg: np.ndarray) -> np.ndarray:
    """Metres across a fireball of ``tnt_kg`` (kg TNT) at its largest: 3.77 W^0.325."""
    a, b = FIREBALL_DIAMETER
    return a * fixed.power(np.asarray(tnt_kg, dtype=np.float64), b)


def glow_share(age: np.ndarray, duration: np.ndarray, hot_k: float,
               rise: float = 0.0, floor_k: float = DRAPER_K) -> np.ndarray:
    """(n,) in [0, 1]: the share of its full glow a particle ``age`` (n,) s old has
    (0 before birth), its gas cooling linearly from ``hot_k`` (K) at birth to the
    Draper point (DRAPER_K) at ``duration`` (n,) s: sqrt((T^4 - F^4) / (hot_k^4 - F^4)),
    0 once T is below ``floor_k`` F (K; the Draper point, or a hotter core's
    temperature), times min(1, age / rise) when ``rise`` (s) is not 0."""
    age = np.asarray(age, dtype=np.float64)
    phase = np.clip(age / np.maximum(duration, 1e-9), 0.0, 1.0)
    kelvin = hot_k - (hot_k - DRAPER_K) * phase
    k2, f2, h2 = kelvin * kelvin, floor_k * floor_k, hot_k * hot_k  # T^4 as squares
    share = np.sqrt(np.maximum(k2 * k2 - f2 * f2, 0.0) / (h2 * h2 - f2 * f2))
    if rise > 0:
        share = share * np.clip(age / rise, 0.0, 1.0)
    return np.where(age >= 0, share, 0.0)


def glow_groups(birth: np.ndarray, x0: np.ndarray, window: float, reach: float
                ) -> np.ndarray:
    """(n,) int64: the group of each particle, for life. Particles are taken in birth
    order (``birth`` (n,) s, ties in index order); one joins the open group whose first
    particle was born at most ``window`` s before it and at most ``reach`` m from its
    birth place ``x0`` (n, 3) m (the earliest such group), else starts a group.
    Groups are numbered in the order they start."""
    order = np.lexsort((np.arange(len(birth)), birth))
    group = np.empty(len(birth), dtype=np.int64)
    starts: list[tuple[float, np.ndarray, int]] = []  # open groups: (birth, place, id)
    count = 0
    for i in order.tolist():
        t, x = float(birth[i]), x0[i]
        starts = [s for s in starts if t - s[0] <= window]
        for _, place, gid in starts:
            if float(np.sum((x - place) ** 2)) <= reach * reach:
                group[i] = gid
                break
        else:
            starts.append((t, x, count))
            group[i] = count
            count += 1
    return group


def glow_blobs(group: np.ndarray, x: np.ndarray, velocity: np.ndarray, glow: np.ndarray,
               core: np.ndarray, full: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One frame's glow: (ids (B,) int64, centres (B, 3) m, diameters (B,) m, core
    diameters (B,) m, velocities (B, 3) m/s) of the blobs of the live particles of
    groups ``group`` (n,) at ``x`` (n, 3) m moving at ``velocity`` (n, 3) m/s whose
    glows are ``glow`` (n,) m across, of which ``core`` (n,) m (at most ``glow``) is
    their hot core's; ``full`` (G,) m is each group's sum of its members' glows at full
    size (all of them, born or not). A group whose glows are all 0 has no blob; its core
    is the blob's diameter times the share of its members' glow that is core. See the
    module docstring."""
    glow = np.asarray(glow, dtype=np.float64)
    lit = glow > 0
    if not lit.any():
        return (np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0), np.zeros(0),
                np.zeros((0, 3)))
    ids, member = np.unique(group[lit], return_inverse=True)
    member = member.ravel()
    g, xs, vs = glow[lit], x[lit], velocity[lit]
    weight = g * g  # the area of a glow: about its light
    total = np.bincount(member, weight)

    def mean(values: np.ndarray) -> np.ndarray:
        return np.stack([np.bincount(member, weight * values[:, k])
                         for k in range(values.shape[1])], axis=1) / total[:, None]

    centre = mean(xs)
    spread = np.sqrt(np.bincount(member, weight * ((xs - centre[member]) ** 2).sum(axis=1))
                     / total)
    glows = np.bincount(member, g)
    diameter = np.bincount(member, weight * g) / total + SPREAD * spread * glows / full[ids]
    hot = diameter * np.bincount(member, np.asarray(core, dtype=np.float64)[lit]) / glows
    return ids, centre, diameter, hot, mean(vs)
