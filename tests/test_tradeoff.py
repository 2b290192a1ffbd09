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
