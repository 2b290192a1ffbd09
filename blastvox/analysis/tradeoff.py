"""Error metrics between two SimCaches of the same shot, for the speed/accuracy trade.

``benchmarks/tradeoff.py`` sweeps voxel size, time step and fracture model and
compares every run with the finest one. The metrics live here, as plain
functions of arrays, so they can be tested on synthetic inputs:

* **momentum**: relative error of |p|, the horizontal momentum (perpendicular
  to the up axis, so gravity does not count) of every piece and dust voxel at
  an early output frame. A piece's momentum is its mass times its displacement
  over the frame interval before that frame, divided by the interval (kg m/s);
  a voxel that turned to dust by then counts with its mass and velocity at
  destruction.
* **COM**: RMS distance between the world centres of mass of the k largest
  pieces (matched by mass rank) over all output frames, divided by a scene
  size (dimensionless). Where one run has fewer than k lasting pieces, its
  missing ranks stay at the other run's first-frame positions of those ranks
  (a piece that did not come loose stayed where it was).
* **mass distribution**: 1-Wasserstein distance between the mass-weighted
  distributions of log10(piece mass / kg), in decades (0.1 decade is a
  factor of 1.26 in mass). Dust voxels are pieces too.
* **broken links**: absolute difference of the fractions of links broken.

The combined error is the mean of the COM, mass-distribution and broken-link
errors. Momentum is reported but left out of it: the momentum a fragment takes
from a wave depends on the step it breaks free in, so it is not converged in
dt even at 1/4000 s (README, "Choosing voxel size and time step") and a finest
run is no reference for it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from blastvox.geometry.frames import up_vector

#: The metrics, in table order: (key, column heading).
METRICS = (("momentum", "momentum rel. err"), ("com", "COM RMS / size"),
           ("mass", "mass W1 (decades)"), ("broken", "broken-link Δ"))


@dataclass(frozen=True)
class RunSummary:
    """What the metrics need from one run.

    momentum: (3,) kg m/s, horizontal momentum at the momentum frame;
    com: (F, k, 3) m, world centres of mass of the k largest lasting pieces,
    largest first; piece_mass: (P,) kg, every piece (dust voxels included);
    broken_fraction: broken links / links.
    """

    momentum: np.ndarray
    com: np.ndarray
    piece_mass: np.ndarray
    broken_fraction: float


@dataclass(frozen=True)
class RunErrors:
    """Errors of a run against a reference run (all dimensionless, see module doc)."""

    momentum: float
    com: float
    mass: float
    broken: float

    @property
    def combined(self) -> float:
        """Mean of the COM, mass-distribution and broken-link errors (not momentum)."""
        return (self.com + self.mass + self.broken) / 3.0


def horizontal_momentum(arrays: Mapping[str, np.ndarray], up: np.ndarray,
                        frame: int = 1) -> np.ndarray:
    """(3,) kg m/s: momentum of all pieces and dust at ``frame``, up component removed.

    ``arrays`` holds the SimCache arrays ``frame_time``, ``piece_mass``,
    ``piece_position``, ``piece_end_frame``, ``voxel_destroyed_frame``,
    ``dust_voxel``, ``dust_mass`` and ``dust_velocity``. A piece still there
    at ``frame`` counts with m (x[frame] - x[frame - 1]) / (t[frame] - t[frame - 1]);
    a dust voxel destroyed at or before ``frame`` with its mass and velocity at
    destruction.
    """
    if not 1 <= frame < len(arrays["frame_time"]):
        raise ValueError(f"frame {frame} is not in 1..{len(arrays['frame_time']) - 1}")
    interval = float(arrays["frame_time"][frame] - arrays["frame_time"][frame - 1])
    present = np.asarray(arrays["piece_end_frame"]) > frame
    position = np.asarray(arrays["piece_position"], dtype=np.float64)
    step = position[frame, present] - position[frame - 1, present]
    p = (np.asarray(arrays["piece_mass"])[present, None] * step).sum(axis=0) / interval
    dust_voxel = np.asarray(arrays["dust_voxel"], dtype=np.int64)
    gone = np.asarray(arrays["voxel_destroyed_frame"])[dust_voxel] <= frame
    p = p + (np.asarray(arrays["dust_mass"])[gone, None]
             * np.asarray(arrays["dust_velocity"])[gone]).sum(axis=0)
    up = np.asarray(up, dtype=np.float64)
    return p - np.dot(p, up) * up


def largest_pieces(piece_mass: np.ndarray, piece_end_frame: np.ndarray, frame_count: int,
                   k: int) -> np.ndarray:
    """Indices of the k heaviest pieces that last the whole shot, heaviest first.

    Equal masses keep piece order (pieces are numbered by their lowest voxel).
    """
    lasting = np.flatnonzero(np.asarray(piece_end_frame) >= frame_count)
    order = np.argsort(-np.asarray(piece_mass)[lasting], kind="stable")
    return lasting[order[:k]]


def summarize(arrays: Mapping[str, np.ndarray], link_count: int, up: np.ndarray,
              k: int = 5, momentum_frame: int = 1) -> RunSummary:
    """The :class:`RunSummary` of a run from its SimCache arrays and its model's link count."""
    frames = len(arrays["frame_time"])
    top = largest_pieces(arrays["piece_mass"], arrays["piece_end_frame"], frames, k)
    broken = len(arrays["link_break_link"]) / link_count if link_count else 0.0
    return RunSummary(momentum=horizontal_momentum(arrays, up, momentum_frame),
                      com=np.asarray(arrays["piece_position"], dtype=np.float64)[:, top],
                      piece_mass=np.asarray(arrays["piece_mass"], dtype=np.float64).copy(),
                      broken_fraction=float(broken))


def summarize_cache(cache, k: int = 5, momentum_frame: int = 1) -> RunSummary:
    """The :class:`RunSummary` of a :class:`blastvox.cache.SimCache`."""
    up = up_vector(cache.meta.get("up_axis") or cache.model.meta.get("up_axis") or "Y")
    return summarize(cache.arrays, len(cache.model.arrays["link_voxels"]), up, k,
                     momentum_frame)


def momentum_error(p: np.ndarray, reference: np.ndarray) -> float:
    """Relative error of the magnitude |p| against |reference| (0 if both are 0)."""
    a, b = float(np.linalg.norm(p)), float(np.linalg.norm(reference))
    if b == 0.0:
        return 0.0 if a == 0.0 else float("inf")
    return abs(a - b) / b


def com_rms_error(com: np.ndarray, reference: np.ndarray, scale: float) -> float:
    """RMS distance / ``scale`` between (F, k, 3) trajectories, matched by rank.

    Both must have F frames. If one has fewer ranks, its missing ranks are the
    other's first-frame positions held still (the piece never came loose).
    """
    com, reference = np.asarray(com, dtype=np.float64), np.asarray(reference, dtype=np.float64)
    if com.shape[0] != reference.shape[0]:
        raise ValueError(f"frame counts differ: {com.shape[0]} and {reference.shape[0]}")
    k = max(com.shape[1], reference.shape[1])
    if k == 0:
        return 0.0
    d2 = np.sum((_pad(com, reference) - _pad(reference, com)) ** 2, axis=-1)
    return float(np.sqrt(d2.mean())) / scale


def _pad(com: np.ndarray, other: np.ndarray) -> np.ndarray:
    """``com`` with the ranks only ``other`` has, at other's first-frame positions."""
    if com.shape[1] >= other.shape[1]:
        return com
    rest = np.repeat(other[:1, com.shape[1]:], len(other), axis=0)
    return np.concatenate([com, rest], axis=1)


def wasserstein_1d(u: np.ndarray, v: np.ndarray, u_weights: np.ndarray | None = None,
                   v_weights: np.ndarray | None = None) -> float:
    """1-Wasserstein distance between two weighted samples on the line.

    u (M,) and v (K,) are the sample values, u_weights (M,) and v_weights (K,)
    their weights (None: equal; any positive finite total, normalised here).
    Closed form W1 = integral |F(x) - G(x)| dx of the two step CDFs, exact on
    each interval between successive values of the merged sorted support.
    Raises ValueError on an empty sample or a negative, mis-sized or
    zero-total weight array.
    """
    u_values, u_cdf = _sorted_cdf(u, u_weights)
    v_values, v_cdf = _sorted_cdf(v, v_weights)
    support = np.sort(np.concatenate([u_values, v_values]), kind="mergesort")
    # on [support[i], support[i+1]) each CDF is its weight of values <= support[i]
    f = u_cdf[np.searchsorted(u_values, support[:-1], side="right")]
    g = v_cdf[np.searchsorted(v_values, support[:-1], side="right")]
    return float(np.dot(np.abs(f - g), np.diff(support)))


def _sorted_cdf(values: np.ndarray, weights: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Sorted values (M,) and the CDF (M + 1,) after 0, 1, ..., M of them."""
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size == 0:
        raise ValueError("empty sample")
    order = np.argsort(x, kind="stable")
    if weights is None:
        return x[order], np.arange(x.size + 1) / x.size
    w = np.asarray(weights, dtype=np.float64).ravel()
    if w.shape != x.shape:
        raise ValueError(f"{w.size} weights for {x.size} values")
    if np.any(w < 0):
        raise ValueError("negative weight")
    cumulative = np.concatenate([[0.0], np.cumsum(w[order])])
    if not 0.0 < cumulative[-1] < np.inf:
        raise ValueError("weights must have a positive, finite total")
    return x[order], cumulative / cumulative[-1]


def log_mass_distance(masses: np.ndarray, reference: np.ndarray) -> float:
    """Mass-weighted 1-Wasserstein distance between log10 piece masses, decades."""
    a = np.asarray(masses, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    a, b = a[a > 0], b[b > 0]
    return wasserstein_1d(np.log10(a), np.log10(b), u_weights=a, v_weights=b)


def compare(run: RunSummary, reference: RunSummary, scale: float) -> RunErrors:
    """Every metric of ``run`` against ``reference``; ``scale`` in m normalises COM."""
    return RunErrors(momentum=momentum_error(run.momentum, reference.momentum),
                     com=com_rms_error(run.com, reference.com, scale),
                     mass=log_mass_distance(run.piece_mass, reference.piece_mass),
                     broken=abs(run.broken_fraction - reference.broken_fraction))


def pareto_front(times: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """Bool mask of the runs no other run beats in both wall time and error.

    A run is dominated when another has time <= and error <= with at least one
    strictly smaller; exact duplicates are both on the front.
    """
    t, e = np.asarray(times, dtype=np.float64), np.asarray(errors, dtype=np.float64)
    no_worse = (t[None, :] <= t[:, None]) & (e[None, :] <= e[:, None])
    better = (t[None, :] < t[:, None]) | (e[None, :] < e[:, None])
    return ~np.any(no_worse & better, axis=1)
