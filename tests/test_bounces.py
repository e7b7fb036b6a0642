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


def test_a_ratio_involving_a_flagged_interval_is_flagged():
    """ε = T_{n+1}/T_n next to a missed impact or a typed-in 10x time is never "ok"."""
    times = _geometric_train(30)
    missed = bounce_table(_impacts(np.delete(times, 12)), g=9.81)
    typo = times.copy()
    typo[-1] *= 10  # the last time typed with its decimal point one place off
    mistyped = bounce_table(_impacts(typo), g=9.81)
    for table in (missed, mistyped):
        flags = table["flag"].to_numpy()
        assert np.any(flags != "ok")
        both_ok = (flags[:-1] == "ok") & (flags[1:] == "ok")
        ratio_flags = table["restitution_flag"].to_numpy()
        np.testing.assert_array_equal(ratio_flags[:-1] == "ok", both_ok)
        assert ratio_flags[-1] == "last"
        # What is left "ok" is the ball's ε.
        ok = table["restitution"][table["restitution_flag"] == "ok"]
        np.testing.assert_allclose(ok, 0.9, rtol=1e-9)
    assert missed.loc[[10, 11], "restitution_flag"].tolist() == ["missed", "missed"]
    assert mistyped["restitution"].iloc[-2] > 100


def test_runs_are_never_bridged():
    """Two runs side by side: intervals and ratios within each run, numbered from 0."""
    first, second = _geometric_train(12), _geometric_train(9, first=0.4, ratio=0.8) + 0.013
    frame = pd.DataFrame({"time": np.concatenate([first, second]),
                          "time_uncertainty": 1e-5,
                          "run": np.repeat([0, 1], [first.size, second.size])})
    frame = frame.sort_values("time", kind="stable").reset_index(drop=True)
    table = bounce_table(frame, g=9.81)
    for run, times, ratio in ((0, first, 0.9), (1, second, 0.8)):
        mine = table[table["run"] == run]
        np.testing.assert_array_equal(mine["bounce"], np.arange(times.size - 1))
        np.testing.assert_allclose(mine["interval"], np.diff(times), rtol=1e-12)
        np.testing.assert_allclose(mine["restitution"].dropna(), ratio, rtol=1e-9)
    assert (table["flag"] == "ok").all()


def test_unknown_and_bad_uncertainties():
    times = _geometric_train(10)
    sigma = np.full(times.size, 1e-4)
    sigma[4] = np.nan
    table = bounce_table(pd.DataFrame({"time": times, "time_uncertainty": sigma}), g=9.81)
    assert np.isnan(table["interval_uncertainty"][[3, 4]]).all()
    assert (table["interval_uncertainty"].drop(index=[3, 4]) > 0).all()
    assert (table["flag"] == "ok").all()
    for bad in (-1e-4, np.inf):
        sigma[4] = bad
        with pytest.raises(ValueError, match="time_uncertainty"):
            bounce_table(pd.DataFrame({"time": times, "time_uncertainty": sigma}), g=9.81)
