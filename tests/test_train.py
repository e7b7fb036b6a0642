"""Whole trains by Newton (dashpot.physics.train) against the impact-by-impact map.

The reference is :func:`dashpot.bounce_sequence`, which applies the bounce map one impact at a
time and is itself checked against an event-driven ODE simulation in test_bounce_train.py.
"""

from __future__ import annotations

import numpy as np
import pytest

import dashpot
from dashpot.physics.train import impact_train, impact_trains

G = 9.80665
CASES = [  # (ζ, ω0 in rad/s, v0 in m/s): light damping, moderate, heavy, nearly elastic
    (0.01, 3000.0, 2.0), (0.1, 500.0, 1.0), (0.3, 100.0, 1.0), (1e-3, 1e4, 3.0),
    (1.2, 200.0, 5.0), (0.05, 50.0, 0.3)]


def reference(model, zeta, omega0, v0, count):
    """Dimensionless speeds and intervals from the impact-by-impact map."""
    sequence = dashpot.bounce_sequence(model, beta=zeta * omega0, omega0=omega0, g=G, v0=v0,
                                       n_max=count)
    v_star = G / omega0
    return sequence.impact_speeds / v_star, sequence.intervals * omega0, sequence.stop_reason


def assert_same_train(train, speeds, intervals, rtol=2e-13):
    assert train.speeds.size == speeds.size
    np.testing.assert_allclose(train.speeds, speeds, rtol=rtol, atol=0)
    np.testing.assert_allclose(train.intervals, intervals, rtol=rtol, atol=0)


@pytest.mark.parametrize("model", dashpot.MODELS)
@pytest.mark.parametrize("zeta, omega0, v0", CASES)
def test_train_from_scratch_is_the_map(model, zeta, omega0, v0):
    speeds, intervals, stop = reference(model, zeta, omega0, v0, 30)
    train = impact_train(model, zeta, v0 * omega0 / G, 30)
    assert_same_train(train, speeds, intervals)
    assert train.captured == (stop == "captured")


@pytest.mark.parametrize("model", ("Ib", "IIb", "hybrid"))
@pytest.mark.parametrize("zeta, omega0, v0", CASES)
@pytest.mark.parametrize("shift", [1e-9, 1e-6, 1e-3, 0.05])
def test_newton_from_a_nearby_train_reaches_the_map(model, zeta, omega0, v0, shift):
    count = 30
    near = impact_train(model, zeta, v0 * omega0 / G, count)
    ratios = np.ones(count)
    ratios[:near.speeds.size] = near.speeds / near.speeds[0]
    ratios[near.speeds.size:] = ratios[near.speeds.size - 1] * 0.5 ** np.arange(
        1, count - near.speeds.size + 1)
    zeta_new, v0_new = zeta * (1 + shift), v0 * (1 - 0.7 * shift)
    speeds, intervals, _ = reference(model, zeta_new, omega0, v0_new, count)
    train = impact_train(model, zeta_new, v0_new * omega0 / G, count, start=ratios)
    # The last impacts before a capture sit near the critical speed, where ε ∝ √(ṽ − ṽc)
    # amplifies any rounding (in the reference too): 1e-12 there.
    assert_same_train(train, speeds, intervals, rtol=1e-12)
    assert train.error_bound <= 1e-13
    if shift <= 1e-6 and near.speeds.size == count:
        # What a fit's finite-difference steps ask: one vectorized evaluation.
        assert train.evaluations == 1


def test_many_trains_at_once_match_one_by_one():
    zeta = np.array([0.01, 0.3, 0.05, 1.2, 0.1, 0.8])
    omega0 = np.array([3000.0, 100.0, 50.0, 200.0, 500.0, 40.0])
    v0 = np.array([2.0, 1.0, 0.3, 5.0, 1.0, 0.2])
    for model in dashpot.MODELS:
        trains = impact_trains(model, zeta, v0 * omega0 / G, 25)
        refined = impact_trains(model, zeta * (1 + 1e-7), v0 * omega0 / G, 25,
                                start=trains.speeds / trains.speeds[:, :1])
        for k in range(zeta.size):
            speeds, intervals, _ = reference(model, zeta[k], omega0[k], v0[k], 25)
            n = trains.impacts[k]
            assert n == speeds.size
            np.testing.assert_allclose(trains.speeds[k, :n], speeds, rtol=2e-13)
            np.testing.assert_allclose(trains.intervals[k, :n - 1], intervals, rtol=2e-13)
            assert np.all(trains.speeds[k, n:] == 0.0)
            speeds, intervals, _ = reference(model, zeta[k] * (1 + 1e-7), omega0[k], v0[k], 25)
            m = refined.impacts[k]
            assert m == speeds.size
            np.testing.assert_allclose(refined.intervals[k, :m - 1], intervals, rtol=2e-13)


def test_ia_train_ends_where_restitution_underflows():
    # Ia's ε = exp(−πζ/√(1−ζ²)) underflows to 0 just below ζ = 1.
    zeta = 1.0 - 1e-7
    train = impact_train("Ia", zeta, 10.0, 5)
    assert train.speeds.size == 1 and train.captured
    assert np.all(np.isfinite(train.contact_times))


def test_bad_count_is_refused():
    with pytest.raises(ValueError, match="count"):
        impact_train("Ib", 0.1, 10.0, 0)
