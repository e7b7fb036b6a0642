"""Random clicks and random times are not a bounce train (issue 12, point 7).

Before: 60 s of noise with 200 random clicks gave a chain of some 40 "impacts" whose interval
ratios went up to 1.2, `dashpot impacts` exited 0 and `fit` called a model clearly preferred.
Seeds here were not used to set any threshold.
"""

import numpy as np
import pandas as pd
import pytest

import dashpot
from dashpot.errors import InputError
from dashpot.ingest.audio import _best_chain, detect_impacts
from dashpot.plausibility import NOT_A_BOUNCE_TRAIN, bounce_train_problem, check_bounce_train
from dashpot.synth.audio import impact_sound, write_audio
from dashpot.synth.tables import write_timestamps

from cli_run import run_cli

CLICK_SEEDS = (8101, 8102, 8103, 8104)


def _clicks(folder, seed, count=200, duration=60.0):
    """`duration` s of noise with `count` clicks at uniformly random times and loudness."""
    rng = np.random.default_rng(seed)
    times = np.sort(rng.uniform(0.0, duration - 0.5, count))
    loudness = rng.uniform(0.3, 1.0, count)
    samples, _ = impact_sound(times - times[0], loudness, lead_in=times[0] + 0.1,
                              duration=duration, snr_db=40.0, seed=seed)
    return write_audio(folder / f"clicks{seed}.wav", samples, 44100)


def _train(seed, count=25, sigma=20e-6):
    """Impact times of a ball bouncing to rest, with Gaussian timing noise (s)."""
    sequence = dashpot.bounce_sequence("hybrid", beta=60.0, omega0=2500.0, g=9.81, v0=1.5,
                                       n_max=count)
    rng = np.random.default_rng(seed)
    return sequence.impact_times + rng.normal(0.0, sigma, sequence.impact_times.size)


@pytest.mark.parametrize("seed", CLICK_SEEDS)
def test_random_clicks_are_refused_by_the_detector(tmp_path, seed):
    path = _clicks(tmp_path, seed)
    with pytest.raises(InputError) as caught:
        detect_impacts(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: {NOT_A_BOUNCE_TRAIN}: ")
    assert "\n" not in message


def test_impacts_fit_and_analyze_on_random_clicks_exit_2_and_write_nothing(tmp_path):
    path = _clicks(tmp_path, 8105)
    for argv, output in ((["impacts", str(path), "-o", str(tmp_path / "impacts.csv")],
                          tmp_path / "impacts.csv"),
                         (["fit", str(path), "-o", str(tmp_path / "fit.h5")],
                          tmp_path / "fit.h5"),
                         (["analyze", str(path), "-o", str(tmp_path / "out")],
                          tmp_path / "out")):
        status, out, err = run_cli(argv)
        assert status == 2, argv
        assert err.count("\n") == 1 and str(path) in err and NOT_A_BOUNCE_TRAIN in err
        assert not output.exists() or not any(output.iterdir())


@pytest.mark.parametrize("seed", (8201, 8202, 8203))
def test_a_timestamp_table_of_random_times_is_not_fitted(tmp_path, seed):
    rng = np.random.default_rng(seed)
    table = tmp_path / "times.csv"
    write_timestamps(table, np.sort(rng.uniform(0.0, 30.0, 25)))
    status, out, err = run_cli(["fit", str(table), "-o", str(tmp_path / "fit.h5")])
    assert status == 2
    assert err.startswith(f"dashpot fit: error: {table}: {NOT_A_BOUNCE_TRAIN}: ")
    assert not (tmp_path / "fit.h5").exists()


def test_an_impact_table_with_ratios_up_to_1_2_is_not_fitted(tmp_path):
    """What the detector used to write for random clicks: ratios anywhere in [0.8, 1.2]."""
    rng = np.random.default_rng(8301)
    intervals = 2.0 * np.cumprod(rng.uniform(0.8, 1.2, 30))
    times = np.concatenate([[0.5], 0.5 + np.cumsum(intervals)])
    table = tmp_path / "impacts.csv"
    pd.DataFrame({"time": times, "time_uncertainty": 2e-5}).to_csv(table, index=False)
    status, _, err = run_cli(["fit", str(table), "-o", str(tmp_path / "fit.h5")])
    assert status == 2 and NOT_A_BOUNCE_TRAIN in err and str(table) in err


def test_erratic_but_shrinking_intervals_are_not_a_bounce_train():
    rng = np.random.default_rng(8401)
    intervals = np.cumprod(rng.uniform(0.6, 0.98, 20))
    problem = bounce_train_problem(np.concatenate([[0.0], np.cumsum(intervals)]))
    assert "scatter" in problem


@pytest.mark.parametrize("seed", (8501, 8502))
def test_bounce_trains_pass_with_a_missed_and_a_spurious_impact(seed):
    times = _train(seed)
    assert bounce_train_problem(times, np.full(times.size, 20e-6)) == ""
    missed = np.delete(times, 6)
    assert bounce_train_problem(missed, np.full(missed.size, 20e-6)) == ""
    spurious = np.sort(np.append(times, times[10] + 0.3 * (times[11] - times[10])))
    assert bounce_train_problem(spurious, np.full(spurious.size, 20e-6)) == ""


def test_a_stopwatch_table_rounded_to_1_ms_passes():
    """Short intervals written to the ms: the timing noise, not the ball, scatters the ratios."""
    times = np.round(_train(8601, count=40), 3)
    assert np.diff(times).min() < 0.03
    assert bounce_train_problem(times, np.full(times.size, 1e-3 / np.sqrt(12))) == ""


def test_a_few_impacts_of_a_cart_pass_and_one_growing_interval_of_three_does_not():
    cart = np.array([0.0, 1.2, 2.16, 2.93])  # ratios 0.8
    assert bounce_train_problem(cart) == ""
    with pytest.raises(InputError, match=NOT_A_BOUNCE_TRAIN):
        check_bounce_train(pd.DataFrame({"time": [0.0, 1.0, 2.3]}), "three.csv")


def test_only_the_fitted_run_is_checked():
    """Runs side by side interleave in time; the fit uses the first one."""
    first = _train(8701, count=12)
    table = pd.DataFrame({"time": np.concatenate([first, first + 0.37]),
                          "time_uncertainty": 2e-5, "run": np.repeat([0, 1], first.size)})
    table = table.sort_values("time", ignore_index=True)
    check_bounce_train(table, "runs.csv")  # no error


def test_the_chain_search_does_not_follow_growing_intervals():
    """Intervals of 0.3 s growing by 10 % each: within the old bound of 1.2, not a ball's."""
    intervals = 0.3 * 1.1 ** np.arange(12)
    times = np.concatenate([[0.0], np.cumsum(intervals)])
    chain = times[_best_chain(times, np.ones(times.size))]
    assert np.all(np.diff(chain)[1:] / np.diff(chain)[:-1] < 1.08)  # was all 13, ratios 1.1
    shrinking = np.concatenate([[0.0], np.cumsum(0.3 * 0.9 ** np.arange(12))])
    assert _best_chain(shrinking, np.ones(shrinking.size)).size == shrinking.size


def test_bounces_of_random_times_says_they_are_no_bounce_train(tmp_path):
    """`dashpot bounces` writes the table (to inspect the intervals) but says, per run, that
    random times are not a bounce train, where `fit` refuses them."""
    rng = np.random.default_rng(8601)
    train = _train(8602)
    random_times = np.sort(rng.uniform(0.0, 30.0, 25))
    table = tmp_path / "impacts.csv"
    pd.DataFrame({"time": np.concatenate([train, random_times]),
                  "time_uncertainty": 20e-6,
                  "run": np.repeat([0, 1], [train.size, random_times.size])}).to_csv(
        table, index=False)
    output = tmp_path / "bounces.csv"
    status, out, err = run_cli(["bounces", str(table), "-o", str(output)])
    assert status == 0, err
    warnings = [line for line in out.splitlines() if NOT_A_BOUNCE_TRAIN in line]
    assert len(warnings) == 1 and warnings[0].startswith("  note: run 1: ")
    assert output.exists()


@pytest.mark.parametrize("seed", (8701, 8702))
def test_random_times_without_uncertainties_are_not_fitted(tmp_path, seed):
    """A table of times alone (no time_uncertainty column: unknown σ) is judged with σ = 0,
    not waved through by a NaN tolerance."""
    rng = np.random.default_rng(seed)
    table = tmp_path / "times.csv"
    pd.DataFrame({"time": np.sort(rng.uniform(0.0, 30.0, 25))}).to_csv(table, index=False)
    status, _, err = run_cli(["fit", str(table), "-o", str(tmp_path / "fit.h5")])
    assert status == 2 and NOT_A_BOUNCE_TRAIN in err and str(table) in err
    status, out, _ = run_cli(["bounces", str(table), "-o", str(tmp_path / "bounces.csv")])
    assert status == 0 and NOT_A_BOUNCE_TRAIN in out
