"""The trade-off metrics (blastvox.analysis.tradeoff) on synthetic runs with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from blastvox.analysis.tradeoff import (
    RunSummary,
    com_rms_error,
    compare,
    horizontal_momentum,
    largest_pieces,
    log_mass_distance,
    momentum_error,
    pareto_front,
    summarize,
    up_vector,
    wasserstein_1d,
)

FRAMES = 5
FPS = 20.0


def synthetic_arrays() -> dict[str, np.ndarray]:
    """Three pieces (one fixed, one sliding along +x at 2 m/s, one falling) and one dust voxel.

    Piece 3 is the dust voxel (gone at frame 1) with 1 kg at (0, 3, 0) m/s.
    """
    t = np.arange(FRAMES) / FPS
    position = np.zeros((FRAMES, 4, 3))
    position[:, 0] = (0.0, 0.0, 1.0)
    position[:, 1, 0] = 2.0 * t  # 2 m/s along x
    position[:, 2, 2] = 5.0 - 0.5 * 9.81 * t**2  # falls along z (up): no horizontal momentum
    return {
        "frame_time": t,
        "piece_mass": np.array([100.0, 10.0, 4.0, 1.0]),
        "piece_position": position.astype(np.float32),
        "piece_end_frame": np.array([FRAMES, FRAMES, FRAMES, 1], dtype=np.int32),
        "voxel_destroyed_frame": np.array([-1, -1, 1, -1, -1], dtype=np.int32),
        "dust_voxel": np.array([2], dtype=np.int32),
        "dust_mass": np.array([1.0]),
        "dust_velocity": np.array([[0.0, 3.0, 0.0]]),
        "link_break_link": np.arange(3, dtype=np.int32),
    }


def test_momentum_of_pieces_and_dust_without_the_up_component() -> None:
    p = horizontal_momentum(synthetic_arrays(), up_vector("Z"))
    np.testing.assert_allclose(p, [10.0 * 2.0, 1.0 * 3.0, 0.0], rtol=1e-6)
    assert momentum_error(p * 1.1, p) == pytest.approx(0.1)
    assert momentum_error(np.zeros(3), np.zeros(3)) == 0.0


def test_largest_pieces_skip_dust_and_keep_order_on_ties() -> None:
    mass = np.array([1.0, 5.0, 5.0, 9.0, 2.0])
    end = np.array([10, 10, 10, 3, 10])
    assert largest_pieces(mass, end, 10, 3).tolist() == [1, 2, 4]


def test_identical_runs_have_zero_error() -> None:
    run = summarize(synthetic_arrays(), link_count=12, up=up_vector("Z"), k=2)
    assert run.broken_fraction == pytest.approx(0.25)
    assert run.com.shape == (FRAMES, 2, 3)
    errors = compare(run, run, scale=4.0)
    assert (errors.momentum, errors.com, errors.mass, errors.broken) == (0.0, 0.0, 0.0, 0.0)
    assert errors.combined == 0.0


def test_a_known_shift_gives_the_known_rms() -> None:
    reference = np.random.default_rng(0).normal(size=(FRAMES, 3, 3))
    shifted = reference + np.array([0.3, 0.0, 0.4])  # |shift| = 0.5 m at every frame
    assert com_rms_error(shifted, reference, scale=2.0) == pytest.approx(0.25)
    with pytest.raises(ValueError):
        com_rms_error(shifted[:-1], reference, scale=1.0)


def test_a_piece_that_did_not_come_loose_stays_at_its_rest_position() -> None:
    reference = np.zeros((FRAMES, 2, 3))
    reference[:, 1, 2] = np.linspace(0.0, 1.0, FRAMES)  # rank 2 flies 1 m up
    static = np.zeros((FRAMES, 1, 3))  # the run has only rank 1
    expected = np.sqrt(np.sum(np.linspace(0.0, 1.0, FRAMES) ** 2) / (2 * FRAMES))
    assert com_rms_error(static, reference, scale=1.0) == pytest.approx(expected)
    assert com_rms_error(reference, static, scale=1.0) == pytest.approx(expected)
    # two missing ranks, both flying the same way: the same RMS
    three = np.concatenate([reference, reference[:, 1:]], axis=1)
    expected = np.sqrt(2 * np.sum(np.linspace(0.0, 1.0, FRAMES) ** 2) / (3 * FRAMES))
    assert com_rms_error(static, three, scale=1.0) == pytest.approx(expected)


def test_mass_distribution_distance_in_decades() -> None:
    masses = np.array([1.0, 10.0, 100.0])
    assert log_mass_distance(masses, masses) == 0.0
    # every piece ten times heavier: the log-mass distribution moves by one decade
    assert log_mass_distance(masses * 10.0, masses) == pytest.approx(1.0)
    # mass-weighted: 1 kg and 1 kg against one 2 kg piece is log10(2) apart
    assert log_mass_distance(np.array([1.0, 1.0]), np.array([2.0])) == pytest.approx(
        np.log10(2.0))


def test_mass_distance_weights_by_mass() -> None:
    # log10 masses {0, 3} weighted 1 : 1000 against {1}: the CDFs differ by 1/1001 on
    # [0, 1) and by 1000/1001 on [1, 3), so W1 = (1 + 2 x 1000) / 1001 decades
    got = log_mass_distance(np.array([1.0, 1000.0]), np.array([10.0]))
    assert got == pytest.approx(2001.0 / 1001.0, rel=1e-12, abs=0.0)


def test_wasserstein_1d_hand_computed() -> None:
    # u: 0, 2, 5 weighted 1, 1, 2 (CDF 1/4, 1/2, 1); v: 1, 4, 4.8 equal (1/3 each).
    # merged support 0, 1, 2, 4, 4.8, 5 and |F - G| on each interval:
    #   1/4 x 1 + 1/12 x 1 + 1/6 x 2 + 1/6 x 0.8 + 1/2 x 0.2 = 54/60
    u, uw, v = np.array([5.0, 0.0, 2.0]), np.array([2.0, 1.0, 1.0]), np.array([4.8, 1.0, 4.0])
    assert wasserstein_1d(u, v, uw) == pytest.approx(0.9, rel=1e-12, abs=0.0)
    assert wasserstein_1d(v, u, None, uw) == pytest.approx(0.9, rel=1e-12, abs=0.0)
    # weights only matter in proportion
    assert wasserstein_1d(u, v, uw * 7.5, np.full(3, 0.1)) == pytest.approx(0.9, rel=1e-12)
    # two point masses: their distance; repeated values are one heavier atom
    assert wasserstein_1d([2.5], [-1.0]) == 3.5
    assert wasserstein_1d([0.0, 0.0, 1.0], [0.0, 1.0], None, [2.0, 1.0]) == 0.0
    assert wasserstein_1d([0.0, 1.0], [0.0, 1.0], [3.0, 1.0], [2.0, 2.0]) == pytest.approx(0.25)


@pytest.mark.parametrize("seed", range(10))
def test_wasserstein_1d_of_equal_size_samples_matches_sorted_pairs(seed: int) -> None:
    # unweighted, same size: W1 = mean |u_(i) - v_(i)| over the sorted samples
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    u, v = rng.normal(size=n), rng.standard_cauchy(size=n)
    if seed % 2:
        u, v = np.round(u, 1), np.round(v, 1)  # ties
    expected = np.mean(np.abs(np.sort(u) - np.sort(v)))
    assert wasserstein_1d(u, v) == pytest.approx(expected, rel=1e-12, abs=1e-15)
    # a shift by c moves it by |c| against itself
    assert wasserstein_1d(u + 3.0, u) == pytest.approx(3.0, rel=1e-12)


def test_wasserstein_1d_rejects_bad_samples() -> None:
    for args in (([], [1.0]), ([1.0], [])):
        with pytest.raises(ValueError, match="empty"):
            wasserstein_1d(*args)
    with pytest.raises(ValueError, match="negative"):
        wasserstein_1d([1.0, 2.0], [1.0], [1.0, -1.0])
    with pytest.raises(ValueError, match="total"):
        wasserstein_1d([1.0], [1.0], [0.0])
    with pytest.raises(ValueError, match="weights for"):
        wasserstein_1d([1.0, 2.0], [1.0], [1.0])


def test_compare_combines_com_mass_and_broken_links() -> None:
    com = np.zeros((FRAMES, 1, 3))
    reference = RunSummary(np.array([10.0, 0.0, 0.0]), com, np.array([1.0, 10.0]), 0.5)
    run = RunSummary(np.array([0.0, 12.0, 0.0]), com + [0.0, 0.0, 1.0],
                     np.array([10.0, 100.0]), 0.4)
    errors = compare(run, reference, scale=10.0)
    assert errors.momentum == pytest.approx(0.2)
    assert errors.com == pytest.approx(0.1)
    assert errors.mass == pytest.approx(1.0)
    assert errors.broken == pytest.approx(0.1)
    assert errors.combined == pytest.approx((0.1 + 1.0 + 0.1) / 3)


def test_pareto_front_of_a_known_set() -> None:
    times = np.array([1.0, 2.0, 3.0, 2.5, 4.0, 1.0])
    errors = np.array([0.5, 0.2, 0.1, 0.3, 0.1, 0.5])
    # (2.5, 0.3) is beaten by (2.0, 0.2); (4.0, 0.1) by (3.0, 0.1); the duplicates both stay
    assert pareto_front(times, errors).tolist() == [True, True, True, False, False, True]
