"""Bounce table from impacts: flight-time speeds, per-bounce ε, missed and spurious impacts."""

import numpy as np
import pandas as pd
import pytest

import dashpot
from dashpot.bounces import bounce_table


def _impacts(times, sigma=1e-5):
    return pd.DataFrame({"time": times, "time_uncertainty": np.full(len(times), sigma)})


def _geometric_train(n=30, first=0.5, ratio=0.9):
    return np.concatenate([[0.0], np.cumsum(first * ratio ** np.arange(n - 1))])


def test_speeds_and_restitution_of_a_clean_train():
    """A model train: v = g(T − τ)/2 recovers the model's rebound speeds, T_{n+1}/T_n its ε."""
    omega0, beta, g = 2 * np.pi * 400, 20.0, 9.81
    seq = dashpot.bounce_sequence("Ia", beta=beta, omega0=omega0, g=g, v0=2.0, n_max=25)
    table = bounce_table(_impacts(seq.impact_times), g=g,
                         contact_duration=seq.contact_durations[0])
    assert (table["flag"] == "ok").all()
    # Model Ia has a speed-independent contact duration: the estimate is exact.
    np.testing.assert_allclose(table["rebound_speed"], seq.impact_speeds[1:], rtol=1e-9)
    # T_{n+1}/T_n = (τ + 2εv/g)/(τ + 2v/g) differs from ε by at most ~τ/T_{n+1}.
    bound = seq.contact_durations[0] / seq.intervals[1:]
    assert np.all(np.abs(table["restitution"][:-1] / seq.restitution[1:-1] - 1) <= bound)


def test_uncertainty_propagation_matches_monte_carlo():
    rng = np.random.default_rng(3)
    times = _geometric_train(12)
    sigma = 2e-4
    table = bounce_table(_impacts(times, sigma), g=9.81)
    draws = times + rng.normal(0, sigma, (20000, times.size))
    ratios = np.diff(draws[:, 1:], axis=1) / np.diff(draws[:, :-1], axis=1)
    np.testing.assert_allclose(table["restitution_uncertainty"][:-1], ratios.std(axis=0),
                               rtol=0.05)
    np.testing.assert_allclose(table["interval_uncertainty"], np.diff(draws).std(axis=0),
                               rtol=0.05)


def test_missed_impact_is_flagged_and_kept():
    times = _geometric_train(30)
    dropped = np.delete(times, 12)
    table = bounce_table(_impacts(dropped), g=9.81)
    assert len(table) == len(dropped) - 1  # nothing removed
    flagged = table.index[table["flag"] != "ok"].tolist()
    assert flagged == [11]
    assert table.loc[11, "flag"] == "missed"


def test_spurious_impact_is_flagged_and_kept():
    times = _geometric_train(30)
    extra = np.sort(np.append(times, times[15] + 0.3 * (times[16] - times[15])))
    table = bounce_table(_impacts(extra), g=9.81)
    assert len(table) == len(extra) - 1
    assert table.loc[[15, 16], "flag"].tolist() == ["spurious", "spurious"]
    assert (table.drop(index=[15, 16])["flag"] == "ok").all()


def test_slowly_varying_restitution_is_not_flagged():
    """ε rising from 0.82 to 0.94 over 35 bounces (like the rubber ball) is a trend, not noise."""
    ratios = np.linspace(0.82, 0.94, 34)
    times = np.concatenate([[0.0], np.cumsum(0.6 * np.cumprod(np.append(1.0, ratios[:-1])))])
    table = bounce_table(_impacts(times), g=9.81)
    assert (table["flag"] == "ok").all()


@pytest.mark.parametrize("times,match", [([0.0, 1.0], "at least three"),
                                         ([0.0, 1.0, 0.5], "increase")])
def test_bad_impacts(times, match):
    with pytest.raises(ValueError, match=match):
        bounce_table(_impacts(times), g=9.81)


def test_running_median_is_pandas_centred_rolling_median():
    from dashpot.bounces import TREND_WINDOW, _rolling_median

    rng = np.random.default_rng(5)
    for size in (1, 2, 3, 6, 7, 8, 40):
        for _ in range(20):
            values = 0.9 + 0.05 * rng.standard_normal(size)
            values[rng.random(size) < 0.3] = np.nan
            want = pd.Series(values).rolling(TREND_WINDOW, center=True,
                                             min_periods=1).median().to_numpy()
            np.testing.assert_allclose(_rolling_median(values), want, rtol=1e-15,
                                       equal_nan=True)
