"""Measured speeds whose errors are correlated, as a motion sensor's are: the speeds of a run
share its fitted leg accelerations and bumper position, and a flight's rebound speed and the
next impact speed share that flight's parabola.

Checked against independent references: the reader's stated error structure against the
scatter of its speeds over fresh noise draws; the deterministic fits' whitened speed residuals
against eᵀC⁻¹e with C built element by element from the table's columns; the noise filter with
the errors as states against the exact multivariate normal of a linear Gaussian train (as
tests/test_noise_speeds.py checks the filter with independent errors). Seeds 20271126 + k,
never tuned on; tolerances binomial, three standard deviations.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from linear_trains import exact_neg2_log_likelihood, linear_train_model

from dashpot.fit import prepare_data
from dashpot.fit.noise_likelihood import (NoiseProblem, _correlated_speed_filter,
                                          _speed_filter)
from dashpot.fit.residuals import _residual_rows
from dashpot.fit.results import FLIGHT_CORRELATION_LIMIT, SpeedErrors
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import track_flight
from dashpot.scene import Scene

SEED = 20271126


def _error_columns(rng, count, rank):
    """Random shared components, own σ and flight correlations of `count` impacts (m/s)."""
    columns = {}
    for prefix in ("impact", "rebound"):
        for j in range(1, rank + 1):
            columns[f"{prefix}_speed_shared_{j}"] = rng.normal(0.0, 4e-3, count)
        columns[f"{prefix}_speed_own"] = rng.uniform(5e-4, 2e-3, count)
    columns["flight_correlation"] = rng.uniform(-0.99, 0.99, count)
    return columns


def _table_with_errors(rng, count, rank):
    """An impact table of `count` impacts with measured speeds (1σ 0.01 m/s) and `rank`
    shared error components (:func:`_error_columns`), drawn from `rng` in this order: times,
    impact speeds, rebound speeds, the error columns."""
    times = np.cumsum(rng.uniform(0.3, 0.5, count))
    return pd.DataFrame({"time": times, "time_uncertainty": 1e-3,
                         "impact_speed": rng.uniform(0.3, 1.0, count),
                         "rebound_speed": rng.uniform(0.2, 0.8, count),
                         "speed_uncertainty": 0.01, **_error_columns(rng, count, rank)})


def _dense_covariance(table, impact_rows, rebound_rows, rank):
    """The speeds' error covariance element by element: speed i of kind p at impact n and
    speed i' of kind p' at impact n' share Σ_j s_pnj·s_p'n'j, and their own errors add σ²
    on the diagonal and ρ_n·σ_out,n·σ_in,n+1 between impact n's rebound and n + 1's impact
    (ρ at most the fits' limit)."""
    entries = [("impact", n) for n in np.flatnonzero(impact_rows)] + \
              [("rebound", n) for n in np.flatnonzero(rebound_rows)]
    size = len(entries)
    cov = np.zeros((size, size))
    for a, (kind_a, n_a) in enumerate(entries):
        for b, (kind_b, n_b) in enumerate(entries):
            value = sum(table[f"{kind_a}_speed_shared_{j}"][n_a]
                        * table[f"{kind_b}_speed_shared_{j}"][n_b] for j in range(1, rank + 1))
            if a == b:
                value += table[f"{kind_a}_speed_own"][n_a] ** 2
            if {kind_a, kind_b} == {"impact", "rebound"} and (
                    (kind_a == "rebound" and (kind_b, n_b) == ("impact", n_a + 1))
                    or (kind_b == "rebound" and (kind_a, n_a) == ("impact", n_b + 1))):
                n = min(n_a, n_b)
                rho = float(np.clip(table["flight_correlation"][n], -FLIGHT_CORRELATION_LIMIT,
                                    FLIGHT_CORRELATION_LIMIT))
                value += rho * table["rebound_speed_own"][n] * table["impact_speed_own"][n + 1]
            cov[a, b] = value
    return cov


class _Stub:
    """A predictor of fixed times and speeds (the fit's residuals need nothing else)."""

    flight_parameters = ()

    def __init__(self, times, speeds, rebound):
        self.values = times, speeds, rebound

    def __call__(self, *args):
        return (None,) + tuple(v[None, :] for v in self.values)


def test_the_fits_weigh_the_speed_misfits_by_their_stated_covariance():
    """χ² of a fit's residuals = Σ (time misfit/σ)² + eᵀC⁻¹e, C the dense covariance of the
    table's speed errors (some speeds not measured, one rebound speed missing)."""
    rng = np.random.default_rng(SEED)
    count, rank = 9, 3
    table = _table_with_errors(rng, count, rank)
    table.loc[3, "rebound_speed"] = np.nan
    data = prepare_data(table, Scene())
    assert data.speed_errors is not None
    times = table["time"].to_numpy()
    predicted = (times - times[0] + rng.normal(0, 1e-3, count), rng.uniform(0.3, 1.0, count),
                 rng.uniform(0.2, 0.8, count))
    rows = _residual_rows(np.array([[0.1, 0.01, 1.0, 0.0]]), data=data,
                          predictor=_Stub(*predicted), priors=[])[0]
    impact_rows = np.isfinite(table["impact_speed"].to_numpy())
    rebound_rows = np.isfinite(table["rebound_speed"].to_numpy())
    misfit = np.concatenate([(table["impact_speed"] - predicted[1])[impact_rows],
                             (table["rebound_speed"] - predicted[2])[rebound_rows]])
    cov = _dense_covariance(table, impact_rows, rebound_rows, rank)
    expected_speeds = misfit @ np.linalg.solve(cov, misfit)
    time_part = np.sum(((data.times - predicted[0]) / data.sigma) ** 2)
    assert rows.size == count + impact_rows.sum() + rebound_rows.sum()
    assert np.sum(rows ** 2) == pytest.approx(time_part + expected_speeds, rel=1e-9)
    assert np.sum(rows[count:] ** 2) == pytest.approx(expected_speeds, rel=1e-9)


def test_a_table_without_the_columns_is_fitted_as_before():
    """No shared column: no whitening, the speeds' misfits over speed_uncertainty."""
    rng = np.random.default_rng(SEED + 1)
    count = 6
    times = np.cumsum(rng.uniform(0.3, 0.5, count))
    table = pd.DataFrame({"time": times, "time_uncertainty": 1e-3,
                          "impact_speed": rng.uniform(0.3, 1.0, count),
                          "rebound_speed": rng.uniform(0.2, 0.8, count),
                          "speed_uncertainty": rng.uniform(0.005, 0.01, count)})
    data = prepare_data(table, Scene())
    assert data.speed_errors is None and data.speed_whitening is None
    predicted = (times - times[0], np.full(count, 0.6), np.full(count, 0.5))
    rows = _residual_rows(np.array([[0.1, 0.01, 1.0, 0.0]]), data=data,
                          predictor=_Stub(*predicted), priors=[])[0]
    sigma = table["speed_uncertainty"].to_numpy()
    assert np.array_equal(rows[count:2 * count], (table["impact_speed"] - 0.6) / sigma)
    assert np.array_equal(rows[2 * count:], (table["rebound_speed"] - 0.5) / sigma)


def test_the_filter_with_correlated_speed_errors_is_the_multivariate_normal():
    """A linear Gaussian train (rebound V(1 + η_n) whatever the impact speed, a contact of
    fixed duration, the incline's two-acceleration flight) with speeds whose errors share
    two run-level components and, per flight, an own error of the rebound speed before it
    and the impact speed after it: the augmented filter's −2 ln L is that of the exact
    multivariate normal of the times (less the first) and the speeds, missing values left
    out."""
    rng = np.random.default_rng(SEED + 2)
    count, rank, rebound, process, contact = 10, 2, 0.4, 0.01, 2e-3
    up, down = 1.1, 0.95
    ratio, per_speed = math.sqrt(down / up), 1.0 / up + math.sqrt(down / up) / down
    timing = rng.uniform(0.5e-3, 2e-3, count)
    shared_in, shared_out = rng.normal(0, 4e-3, (2, count, rank))
    own_in, own_out = rng.uniform(5e-4, 3e-3, (2, count))
    flight_in, flight_out = rng.normal(0, 2e-3, (2, count))  # w_{n-1} in u_n, w_n in v_n
    flight_in[0] = 0.0
    u0 = 0.55
    # Noises: η (count), time errors (count), own impact, own rebound (count each), z (rank),
    # the flights' own w_n (count).
    kick, error = np.arange(count), count + np.arange(count)
    own_i, own_o = 2 * count + np.arange(count), 3 * count + np.arange(count)
    z, w = 4 * count + np.arange(rank), 4 * count + rank + np.arange(count)
    width = 5 * count + rank
    mean, rows = [], []
    for n in range(1, count):
        row = np.zeros(width)
        row[:n] = per_speed * rebound * process
        row[error[n]], row[error[0]] = timing[n], -timing[0]
        mean.append(n * (contact + per_speed * rebound))
        rows.append(row)
    for n in range(count):
        row = np.zeros(width)
        if n:
            row[kick[n - 1]] = ratio * rebound * process
            row[w[n - 1]] = flight_in[n]
        row[own_i[n]], row[z] = own_in[n], shared_in[n]
        mean.append(u0 if n == 0 else ratio * rebound)
        rows.append(row)
    for n in range(count):
        row = np.zeros(width)
        row[kick[n]] = rebound * process
        row[own_o[n]], row[z], row[w[n]] = own_out[n], shared_out[n], flight_out[n]
        mean.append(rebound)
        rows.append(row)
    matrix, mean = np.array(rows), np.array(mean)
    covariance = matrix @ matrix.T
    draws = rng.multivariate_normal(mean, covariance, size=3)
    base = 0.2
    times = np.concatenate([np.full((3, 1), base), base + draws[:, :count - 1]], axis=1)
    impact, rebounds = draws[:, count - 1:2 * count - 1], draws[:, 2 * count - 1:]
    times[1, [3, 7]] = np.nan
    impact[1, 5] = np.nan
    rebounds[1, [2, 9]] = np.nan
    impact[2, :2] = rebounds[2, :2] = np.nan
    model = linear_train_model(rebound, up, down, contact)
    errors = (shared_in, shared_out, flight_in, flight_out,
              np.where(np.isfinite(impact), own_in ** 2, np.nan),
              np.where(np.isfinite(rebounds), own_out ** 2, np.nan))
    result = _correlated_speed_filter(model, times, np.broadcast_to(timing ** 2, (3, count)),
                                      impact, rebounds, errors, np.full(3, u0),
                                      np.full(3, process))
    # The first time is always observed: no difference to a missing one arises.
    expected = exact_neg2_log_likelihood(times, impact, rebounds, base, mean, covariance)
    np.testing.assert_allclose(result.neg2_log_likelihood, expected, rtol=1e-9)
    assert result.speed_scored[1].sum() == 2 * count - 3


def test_without_shared_errors_it_is_the_filter_with_independent_speeds():
    """No shared component and no flight correlation: the augmented filter computes what the
    filter with independent speed errors does (−2 ln L, innovations) to rounding."""
    rng = np.random.default_rng(SEED + 3)
    count = 8
    model = TrainModel(lambda u: (0.8 * u, np.full_like(u, 0.8)),
                       lambda v: track_flight(v, 1.1, 0.95))
    times = 0.3 + np.cumsum(rng.uniform(0.5, 0.7, (2, count)), axis=1)
    impact = rng.uniform(0.3, 0.6, (2, count))
    rebounds = rng.uniform(0.2, 0.5, (2, count))
    impact[0, 3] = rebounds[1, 5] = np.nan
    variance = rng.uniform(1e-6, 1e-5, (2, count))
    timing = np.full((2, count), 1e-6)
    plain = _speed_filter(model, times, timing, impact, rebounds, variance, np.full(2, 0.6),
                          np.full(2, 0.01))
    zero = np.zeros((2, count, 0))
    augmented = _correlated_speed_filter(
        model, times, timing, impact, rebounds,
        (zero, zero, np.zeros((2, count)), np.zeros((2, count)),
         np.where(np.isfinite(impact), variance, np.nan),
         np.where(np.isfinite(rebounds), variance, np.nan)), np.full(2, 0.6), np.full(2, 0.01))
    assert augmented.neg2_log_likelihood == pytest.approx(plain.neg2_log_likelihood, rel=1e-10)
    assert np.allclose(augmented.speed_innovations, plain.speed_innovations, equal_nan=True,
                       rtol=1e-8, atol=1e-12)
    assert np.allclose(augmented.innovations, plain.innovations, equal_nan=True, rtol=1e-8,
                       atol=1e-12)


def test_the_noise_problem_states_the_tables_covariance():
    """The noise problem's split of each speed's error into shared, flight and independent
    parts has the covariance SpeedErrors states (dense, from the table's columns)."""
    rng = np.random.default_rng(SEED + 4)
    count, rank = 7, 3
    table = _table_with_errors(rng, count, rank)
    data = prepare_data(table, Scene())
    problem = NoiseProblem([data], "constant", Scene(), {})
    shared_in, shared_out, flight_in, flight_out, in_var, out_var = (
        a[0] for a in problem.speed_errors)
    loads = []  # each speed's loadings on z (rank), the flights' w (count), its own noise
    for kind in ("in", "out"):
        for n in range(count):
            row = np.zeros(rank + count + 2 * count)
            if kind == "in":
                row[:rank] = shared_in[n]
                if n:
                    row[rank + n - 1] = flight_in[n]
                row[rank + count + n] = math.sqrt(in_var[n])
            else:
                row[:rank] = shared_out[n]
                row[rank + n] = flight_out[n]
                row[rank + 2 * count + n] = math.sqrt(out_var[n])
            loads.append(row)
    loads = np.array(loads)
    every = np.ones(count, bool)
    assert np.allclose(loads @ loads.T, _dense_covariance(table, every, every, rank),
                       rtol=1e-10, atol=1e-14)


def test_the_motion_readers_stated_errors_are_those_of_its_speeds(tmp_path):
    """200 fresh three-run Capstone exports of the paper's cart (50 Hz, 1 mm noise): in every
    run the measured impact speeds' errors (measured less true), and its rebound speeds',
    have the covariance the table states (χ² against it at its 68.27 % and 95.45 % quantiles
    as often as those, within 3 binomial σ; with speed_uncertainty alone, independent, it
    is not); and the rebound speed of the first impact and the impact speed of the second,
    read from one flight, are correlated as stated (mean stated correlation of the
    standardized errors within 3σ of Fisher's z of the empirical one)."""
    from dashpot.ingest import read_impacts
    from dashpot.physics.sequence import bounce_sequence
    from dashpot.synth.tables import write_motion_sensor

    train = bounce_sequence("hybrid", beta=1.87, omega0=22.448887927243977,
                            g=2.895906542614473, v0=1.0, n_max=30)
    levels = (0.682689, 0.954500)
    below = {kind: [] for kind in ("impact", "rebound", "impact alone", "rebound alone")}
    pair, stated = [], []
    for k in range(200):
        path = tmp_path / "capstone.csv"
        truth = write_motion_sensor(path, train, runs=3, sample_rate=50.0, seed=SEED + 100 + k,
                                    overwrite=True)
        table = read_impacts(path)
        for run, true in enumerate(truth["runs"]):
            found = table[table["run"] == run].reset_index(drop=True)
            nearest = np.abs(found["time"].to_numpy()[:, None]
                             - np.asarray(true["impact_times"])[None, :]).argmin(axis=1)
            standard = {}
            for kind, speeds in (("impact", "impact_speeds"), ("rebound", "rebound_speeds")):
                error = found[f"{kind}_speed"].to_numpy() - np.asarray(true[speeds])[nearest]
                seen = np.isfinite(error)
                shared = found[[f"{kind}_speed_shared_{j}" for j in (1, 2, 3)]].to_numpy()
                own = found[f"{kind}_speed_own"].to_numpy()
                cov = shared[seen] @ shared[seen].T + np.diag(own[seen] ** 2)
                below[kind].append(stats.chi2.cdf(
                    error[seen] @ np.linalg.solve(cov, error[seen]), seen.sum()))
                sigma = found["speed_uncertainty"].to_numpy()[seen]
                below[f"{kind} alone"].append(stats.chi2.cdf(
                    np.sum((error[seen] / sigma) ** 2), seen.sum()))
                standard[kind] = (error, shared, own)
            (e_out, s_out, o_out), (e_in, s_in, o_in) = standard["rebound"], standard["impact"]
            total_out = math.sqrt(s_out[0] @ s_out[0] + o_out[0] ** 2)
            total_in = math.sqrt(s_in[1] @ s_in[1] + o_in[1] ** 2)
            pair.append((e_out[0] / total_out, e_in[1] / total_in))
            stated.append((s_out[0] @ s_in[1] + found["flight_correlation"][0] * o_out[0]
                           * o_in[1]) / (total_out * total_in))
    for kind, values in below.items():
        values = np.asarray(values)
        rates = [np.mean(values < level) for level in levels]
        holds = all(abs(rate - level) <= 3.0 * math.sqrt(level * (1 - level) / values.size)
                    for rate, level in zip(rates, levels))
        assert holds == ("alone" not in kind), (kind, rates)
    empirical = np.corrcoef(np.array(pair).T)[0, 1]
    assert abs(np.arctanh(empirical) - np.arctanh(np.mean(stated))) <= 3.0 / math.sqrt(
        len(pair) - 3), (empirical, np.mean(stated))



def test_the_error_columns_survive_the_csv_and_hdf5_round_trips(tmp_path):
    """The motion reader's error columns, written as `dashpot impacts` writes a table and
    read back, are the same numbers (and the fit prepares the same covariance from either);
    the HDF5 file of a fit holds them with their units."""
    from dashpot.cli import main
    from dashpot.ingest import is_speed_error_column, read_impacts
    from dashpot.physics.sequence import bounce_sequence
    from dashpot.store import read_fit
    from dashpot.synth.tables import write_motion_sensor

    train = bounce_sequence("hybrid", beta=1.87, omega0=22.448887927243977,
                            g=2.895906542614473, v0=1.0, n_max=30)
    export = tmp_path / "capstone.csv"
    write_motion_sensor(export, train, runs=2, sample_rate=50.0, seed=SEED + 5)
    original = read_impacts(export)
    columns = [c for c in original.columns if is_speed_error_column(c)]
    assert len(columns) == 2 * 3 + 3
    assert np.all(np.isfinite(original["impact_speed_shared_1"]))
    table = tmp_path / "impacts.csv"
    assert main(["impacts", str(export), "-o", str(table), "-q"]) == 0
    again = read_impacts(table)
    for column in columns:
        assert np.allclose(again[column], original[column], rtol=1e-12, atol=0,
                           equal_nan=True), column
    first = original[original["run"] == 0].reset_index(drop=True)
    reread = again[again["run"] == 0].reset_index(drop=True)
    assert np.allclose(prepare_data(reread, Scene()).speed_whitening,
                       prepare_data(first, Scene()).speed_whitening, rtol=1e-9)
    out = tmp_path / "fit.h5"
    assert main(["fit", str(table), "--models", "Ia", "-q", "-o", str(out)]) == 0
    stored = read_fit(out)["impacts"]
    for column in columns:
        assert np.allclose(stored[column], again[column], equal_nan=True), column
    import h5py

    with h5py.File(out, "r") as source:
        assert source["impacts/impact_speed_shared_2"].attrs["units"] == "m/s"
        assert source["impacts/flight_correlation"].attrs["units"] == "1"


def test_a_users_table_with_shared_columns_only(tmp_path):
    """A table of one's own with a shared column but no own σ: each speed's own σ is what
    speed_uncertainty leaves after the shared part, and a correlation outside [-1, 1] is
    refused with the row named."""
    from dashpot.errors import InputError
    from dashpot.ingest import read_impacts

    path = tmp_path / "mine.csv"
    pd.DataFrame({"time": [0.1, 0.6, 1.0, 1.3], "time_uncertainty": 1e-3,
                  "impact_speed": [1.0, 0.8, 0.64, 0.51],
                  "rebound_speed": [0.8, 0.64, 0.51, 0.41], "speed_uncertainty": 0.01,
                  "impact_speed_shared_1": 0.006,
                  "rebound_speed_shared_1": -0.008}).to_csv(path, index=False)
    table = read_impacts(path)
    data = prepare_data(table, Scene())
    assert np.allclose(data.speed_errors.own_in, 0.008)
    assert np.allclose(data.speed_errors.own_out, 0.006)
    cov = np.linalg.inv(data.speed_whitening.T @ data.speed_whitening)
    assert cov[0, 1] == pytest.approx(0.006 ** 2)
    assert cov[0, 4] == pytest.approx(-0.006 * 0.008)
    assert cov[0, 0] == pytest.approx(0.01 ** 2)
    bad = tmp_path / "bad.csv"
    frame = pd.read_csv(path)
    frame["flight_correlation"] = [0.5, 1.5, 0.0, np.nan]
    frame.to_csv(bad, index=False)
    with pytest.raises(InputError, match=r"row 2.*outside \[-1, 1\]"):
        read_impacts(bad)
