"""Measured impact and rebound speeds in the noise model's likelihood (a motion sensor's), and
the friction rung they make visible on an incline.

The filter with speeds (:func:`dashpot.fit.noise_likelihood._speed_filter`) is checked against
likelihoods written out independently: a linear Gaussian train (a rebound that does not depend
on the impact speed, under the incline's linear two-acceleration flight), whose joint density of
intervals and speeds is a multivariate normal, and the times-only filter
(:meth:`dashpot.likelihood.TrainModel.filter`) where no speed is measured; then by simulation:
its standardized innovations are N(0, 1). Cart trains are drawn as in tests/test_noise_drag.py
(6° incline prior, first impact speed unknown, σ_ε = 0.3 %, 1 ms timing), seeds 20261125 + k
for k from 16 (k < 16 are that file's); tolerances binomial, three standard deviations.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from cart_trains import measured_cart_run
from coverage_checks import assert_covers_at_both_levels, normal_binomial_range
from linear_trains import exact_neg2_log_likelihood, linear_train_model

from dashpot.fit import prepare_data
from dashpot.fit.noise_fit import fit_noise_models
from dashpot.fit.noise_likelihood import NoiseProblem, _speed_filter
from dashpot.likelihood import TrainModel
from dashpot.noise_selection import noise_selection_table
from dashpot.physics.flight import track_flight
from dashpot.physics.laws import LAWS
from dashpot.scene import Scene

G = 9.80665
INCLINE = 6.0  # degrees
G_EFF = G * math.sin(math.radians(INCLINE))  # m/s²
FRICTION = 0.03 * G_EFF  # m/s², 3 % of g_eff
EPS, SPEED, BOUNCES, SCATTER, TIMING = 0.8, 0.5, 15, 0.003, 1e-3
FIRST_SEED = 20261125 + 16



# --- the filter against independent likelihoods ----------------------------------------------

def test_a_linear_gaussian_train_with_speeds_is_the_multivariate_normal():
    """Every rebound V(1 + η_n) whatever the impact speed, a contact of fixed duration τ and
    the incline's flight (T = v/a_up + ρv/a_down, landing ρv, ρ = √(a_down/a_up)): times and
    speeds are then linear in the noises and jointly Gaussian. With the start time integrated
    out the likelihood is that of the times less the first one's, y_n − y_0 = n(τ + cV) +
    cV·Σ_{k<n} η_k + e_n − e_0 (c = T/v), with u_0 (a parameter) and u_n = ρV(1 + η_{n−1}),
    v_n = V(1 + η_n) measured with their own noises; missing times and speeds are left out
    of the density."""
    rng = np.random.default_rng(20261125)
    count, rebound, process, contact = 12, 0.4, 0.01, 2e-3
    up, down = 1.1, 0.95
    ratio, per_speed = math.sqrt(down / up), 1.0 / up + math.sqrt(down / up) / down
    timing = rng.uniform(0.5e-3, 2e-3, count)
    speed_sigma = rng.uniform(2e-3, 6e-3, count)
    u0 = 0.55
    # Observations as linear maps of the noises [η_0..η_{n−1}, e_0..e_{n−1}, the impact
    # speeds' noises, the rebound speeds'], each scaled to its σ.
    kick = np.arange(count)
    error = count + kick
    impact_error, rebound_error = 2 * count + kick, 3 * count + kick
    mean, rows = [], []
    for n in range(1, count):  # y_n − y_0
        row = np.zeros(4 * count)
        row[:n] = per_speed * rebound * process
        row[error[n]], row[error[0]] = timing[n], -timing[0]
        mean.append(n * (contact + per_speed * rebound))
        rows.append(row)
    for n in range(count):  # impact speeds
        row = np.zeros(4 * count)
        if n:
            row[kick[n - 1]] = ratio * rebound * process
        row[impact_error[n]] = speed_sigma[n]
        mean.append(u0 if n == 0 else ratio * rebound)
        rows.append(row)
    for n in range(count):  # rebound speeds
        row = np.zeros(4 * count)
        row[kick[n]] = rebound * process
        row[rebound_error[n]] = speed_sigma[n]
        mean.append(rebound)
        rows.append(row)
    matrix = np.array(rows)
    covariance = matrix @ matrix.T
    mean = np.array(mean)
    draws = rng.multivariate_normal(mean, covariance, size=3)
    base = 0.2  # the first impact's time
    times = np.concatenate([np.full((3, 1), base), base + draws[:, :count - 1]], axis=1)
    impact = draws[:, count - 1:2 * count - 1]
    rebounds = draws[:, 2 * count - 1:]
    # Row 1: two times, an impact speed and two rebound speeds missing; row 2: no speeds at
    # the first two impacts.
    times[1, [4, 9]] = np.nan
    impact[1, 6] = np.nan
    rebounds[1, [2, 11]] = np.nan
    impact[2, :2] = rebounds[2, :2] = np.nan
    model = linear_train_model(rebound, up, down, contact)
    result = _speed_filter(model, times, np.broadcast_to(timing ** 2, (3, count)), impact,
                           rebounds, np.broadcast_to(speed_sigma ** 2, (3, count)),
                           np.full(3, u0), np.full(3, process))
    # The first time is always observed: no difference to a missing one arises.
    expected = exact_neg2_log_likelihood(times, impact, rebounds, base, mean, covariance)
    np.testing.assert_allclose(result.neg2_log_likelihood, expected, rtol=1e-9)
    assert result.speed_scored[1].sum() == 2 * count - 3
    assert result.speed_scored[2].sum() == 2 * count - 4


@pytest.mark.parametrize("law", ["constant", "Ia"])
def test_without_measured_speeds_it_is_the_times_only_filter(law):
    """With every speed missing the split step (contact and bounce, then flight) composes to
    the times-only filter's: −2 ln L, innovations and predictions agree to rounding, for a
    constant ε and for a dashpot model (contact time and its slope), under friction."""
    datasets = [prepare_data(pd.DataFrame({"time": times, "time_uncertainty": TIMING}),
                             Scene(incline_angle=INCLINE, friction=True))
                for times in _cart_times(3)]
    problem = NoiseProblem(datasets, law, Scene(incline_angle=INCLINE, friction=True), {},
                           effects=("friction",))
    assert not problem.has_speeds
    rows = problem.starts()
    rows[:, problem.index("sigma_eps")] = math.log(0.004)
    rows[:, problem.index("sigma_j")] = math.log(3e-4)
    trains = np.arange(3)
    times_only = problem.run_filter(rows, trains)
    nothing = np.full(problem.times.shape, np.nan)
    jitter = np.exp(rows[:, problem.index("sigma_j")])
    split = _speed_filter(problem.model(rows, np.zeros(3, bool)), problem.times,
                          problem.detector ** 2 + jitter[:, None] ** 2, nothing, nothing,
                          nothing, rows[:, problem.index("v0")],
                          np.exp(rows[:, problem.index("sigma_eps")]))
    assert np.all(np.isfinite(times_only.neg2_log_likelihood))
    np.testing.assert_allclose(split.neg2_log_likelihood, times_only.neg2_log_likelihood,
                               rtol=1e-10)
    for name in ("innovations", "innovation_variance", "predicted_times", "filtered_speeds"):
        np.testing.assert_allclose(getattr(split, name), getattr(times_only, name),
                                   rtol=1e-9, atol=1e-15, err_msg=name)
    assert not split.speed_scored.any()


def test_standardized_innovations_of_times_and_speeds_are_standard_normal():
    """Cart trains with friction and speeds drawn by the model's simulator (σ_ε = 1 %, 10×
    this file's, so that the process noise shows in the speeds): at the true parameters the
    filter's standardized innovations, of the times and of both speeds pooled, are N(0, 1)
    (KS test at 1 %, mean square within 3σ of 1) and consecutive ones uncorrelated."""
    trials, process, sigma_v = 40, 0.01, 0.004
    rng = np.random.default_rng(FIRST_SEED)
    model = TrainModel(LAWS["constant"].bind(np.full(trials, EPS)),
                       lambda v: track_flight(v, G_EFF + FRICTION, G_EFF - FRICTION))
    drawn = model.simulate(BOUNCES, rng, start_time=0.0, start_speed=SPEED,
                           process_sigma=process, jitter=TIMING)
    impact = drawn.impact_speeds + sigma_v * rng.standard_normal(drawn.times.shape)
    rebound = drawn.rebound_speeds + sigma_v * rng.standard_normal(drawn.times.shape)
    result = _speed_filter(model, drawn.times, np.full(drawn.times.shape, TIMING ** 2), impact,
                           rebound, np.full(drawn.times.shape, sigma_v ** 2),
                           np.full(trials, SPEED), np.full(trials, process))
    # In the filter's order: time, impact speed, rebound speed of each impact.
    z = np.stack([result.standardized, result.speed_standardized[..., 0],
                  result.speed_standardized[..., 1]], axis=-1).reshape(trials, -1)
    pooled = z[np.isfinite(z)]
    assert pooled.size == trials * (3 * BOUNCES - 1)
    assert stats.kstest(pooled, "norm").pvalue > 0.01
    assert abs(np.mean(pooled ** 2) - 1.0) < 3.0 * math.sqrt(2.0 / pooled.size)
    pairs = np.stack([z[:, :-1].ravel(), z[:, 1:].ravel()])
    pairs = pairs[:, np.all(np.isfinite(pairs), axis=0)]
    assert abs(np.corrcoef(pairs)[0, 1]) < 3.0 / math.sqrt(pairs.shape[1])


# --- the friction rung on cart runs with measured speeds ----------------------------------------

def _cart_times(trials):
    return [table["time"].to_numpy() for table in cart_tables(trials, FRICTION, 0.005)]


def cart_tables(trials, friction, speed_sigma, first_seed=FIRST_SEED):
    """Impact tables of cart trains (a_away = g_eff + f, a_toward = g_eff − f) with each
    impact's and rebound's speed measured (Gaussian error `speed_sigma`), one per seed."""
    return [measured_cart_run(np.random.default_rng(first_seed + k), eps=EPS, g_eff=G_EFF,
                              friction=friction, bounces=BOUNCES, speed=SPEED,
                              scatter=SCATTER, timing=TIMING, speed_sigma=speed_sigma)
            for k in range(trials)]


def friction_rungs(tables):
    """The constant law and its friction rung on the incline scene (6° ± 0.5° prior, first
    impact speed unknown), and which is kept by the selection (ΔBIC ≥ 6)."""
    scene = Scene(incline_angle=INCLINE, friction=True)
    data = [prepare_data(table, scene) for table in tables]
    constant = fit_noise_models(data, "constant", scene, accuracy="fast")
    friction = fit_noise_models(data, "constant", scene, accuracy="fast", effects=("friction",))
    kept = [bool(noise_selection_table({"constant": c, "constant+friction": d})[0].set_index(
        "model").loc["constant+friction", "kept"]) for c, d in zip(constant, friction)]
    return constant, friction, np.array(kept)


def friction_sigma(speed_sigma, scene_sigma_g):
    """1σ of f that the train's speeds and times allow (Fisher information, σ_ε → 0), written
    out by hand: the deterministic train's impact times (t_0 free), impact and rebound speeds
    as functions of (ε, g_eff, f, v0, t_0), their derivatives by central differences, the
    information Jᵀ W J with the times' and speeds' weights and g_eff's prior, inverted."""
    def observations(p):
        eps, g_eff, friction, v0, t0 = p
        up, down = g_eff + friction, g_eff - friction
        times, impact, rebound, t, u = [], [], [], t0, v0
        for _ in range(BOUNCES):
            times.append(t)
            impact.append(u)
            v = eps * u
            rebound.append(v)
            t += v / up + v * math.sqrt(down / up) / down
            u = v * math.sqrt(down / up)
        return np.array(times + impact + rebound)

    truth = np.array([EPS, G_EFF, FRICTION, SPEED, 0.0])
    steps = 1e-6 * np.array([1.0, 1.0, 1.0, 1.0, 1.0])
    jacobian = np.column_stack([(observations(truth + h) - observations(truth - h)) / (2 * s)
                                for h, s in zip(np.diag(steps), steps)])
    weights = np.concatenate([np.full(BOUNCES, TIMING ** -2),
                              np.full(2 * BOUNCES, speed_sigma ** -2)])
    information = jacobian.T @ (weights[:, None] * jacobian)
    information[1, 1] += scene_sigma_g ** -2
    return math.sqrt(np.linalg.inv(information)[2, 2])


def test_measured_speeds_determine_friction_to_a_third_of_itself_at_one_percent():
    """Why tests/test_noise_drag.py's cart run with speeds measured to 0.005 m/s keeps the
    friction rung in only about a third of its trains: its speeds fall by ε·ρ ≈ 0.78 a
    flight, below the sensor's error after a few bounces, so speeds and times together give
    f to about 1/3 of itself (f/σ_f ≈ 3, not the 8 of a train whose every flight is at
    0.5 m/s); at 0.0025 m/s it is ≥ 5σ."""
    prior = Scene(incline_angle=INCLINE, friction=True).flight_acceleration.uncertainty
    assert 2.5 < FRICTION / friction_sigma(0.005, prior) < 3.5
    assert FRICTION / friction_sigma(0.0025, prior) >= 5.0


@pytest.fixture(scope="module")
def precise_speeds():
    """24 cart runs with friction, speeds measured to 0.0025 m/s (f ≥ 5σ_f)."""
    return friction_rungs(cart_tables(24, FRICTION, 0.0025))


@pytest.mark.slow
def test_the_friction_rung_is_kept_where_the_speeds_see_friction_at_five_sigma(precise_speeds):
    """Where the measured speeds put the friction at ≥ 5σ of its error (above), the rung is
    kept in ≥ 90 % of the runs (less 3σ binomial), and the 68 and 95 % intervals of f cover
    the truth at their nominal rates with widths matching the scatter of the estimates.
    Measured: kept in 24 of 24 (ΔBIC 21-56), 68/95 % coverage 18 and 24 of 24, median 68 %
    half-width 0.0053 m/s² against a spread of 0.0051."""
    constant, friction, kept = precise_speeds
    trials = kept.size
    assert all(fit.success for fit in friction)
    assert kept.sum() >= normal_binomial_range(trials, 0.9)[0], [
        round(c.bic - d.bic, 1) for c, d in zip(constant, friction)]
    f = [fit.estimates["friction"] for fit in friction]
    assert_covers_at_both_levels(f, FRICTION)
    half = np.median([0.5 * (e.high68 - e.low68) for e in f])
    spread = np.std([e.value for e in f], ddof=1)
    # The spread of 24 estimates is known to ±1/√(2·23) ≈ 15 %: 3σ either way.
    assert 0.55 * spread <= half <= 1.45 * spread, (half, spread)
    # Its speed innovations count as data: 14 times and 30 speeds.
    assert all(fit.ndata == (BOUNCES - 1) + 2 * BOUNCES for fit in friction)


@pytest.mark.slow
def test_the_95_percent_interval_of_friction_covers_at_its_rate_at_one_percent_speeds():
    """The test_noise_drag.py scenario (speeds to 0.005 m/s, f ≈ 3σ_f) on 24 fresh seeds:
    whether or not the rung is kept, the 95 % (and 68 %) intervals of f cover the truth at
    their nominal rates (3σ binomial). Measured: 23 and 14 of 24 (the rung kept in 9)."""
    _, friction, _ = friction_rungs(cart_tables(24, FRICTION, 0.005, FIRST_SEED + 24))
    f = [fit.estimates["friction"] for fit in friction]
    assert all(fit.success for fit in friction)
    assert_covers_at_both_levels(f, FRICTION)


@pytest.mark.slow
def test_an_incline_run_without_friction_does_not_keep_the_friction_rung():
    """24 cart runs without friction (speeds to 0.0025 m/s, where friction of 3 % would be
    seen at ≥ 5σ): the rung is a false positive in few of them. A step kept at ΔBIC ≥ 6 with
    ln n ≈ 3.8 needs Δ(−2 ln L) ≥ 13.6 from two parameters, a chance of about 1e-3 under
    the null; the test allows a rate of 5 % (its mean plus 3σ: at most 4 of 24). Measured:
    1 of 24 (ΔBIC 8.8, f = 0.020 ± 0.005 m/s² with σ_ε fitted at 0; the same with the
    speeds to 0.005 m/s), the truth inside 23 of the 24 95 % intervals."""
    _, friction, kept = friction_rungs(cart_tables(24, 0.0, 0.0025, FIRST_SEED + 48))
    assert all(fit.success for fit in friction)
    assert kept.sum() <= normal_binomial_range(24, 0.05)[1], kept
    # The truth, f = 0 at the bound, inside the 95 % intervals at their nominal rate.
    f = [fit.estimates["friction"] for fit in friction]
    assert sum(e.low95 <= 0.0 for e in f) >= normal_binomial_range(24, 0.9545)[0]


# --- the paper's soft-bumper cart through the motion reader ------------------------------------

@pytest.mark.slow
def test_the_paper_cart_from_a_motion_sensor_recovers_its_contact_with_the_speeds(tmp_path):
    """The paper's cart (model hybrid on its soft bumper, tests/test_multi_run.py's CART) as
    a 50 Hz Capstone export, 24 fresh seeds (20261125 + 800 + k), read by the motion reader:
    four impacts a run, whose intervals alone leave ω0 undetermined (the 0.15-0.2 s contacts
    trade against the restitution). With the reader's impact and rebound speeds in the noise
    model the 68 and 95 % intervals of ω0 and β cover the truth at their nominal rates (3σ
    binomial) and ω0's error is a fifth or less of the times-only fit's."""
    from dashpot.ingest import read_impacts
    from dashpot.physics.sequence import bounce_sequence
    from dashpot.synth.tables import write_motion_sensor

    cart = {"beta": 1.87, "omega0": 22.448887927243977, "g": 2.895906542614473}
    train = bounce_sequence("hybrid", beta=cart["beta"], omega0=cart["omega0"], g=cart["g"],
                            v0=1.0, n_max=30)
    scene = Scene(g_eff=cart["g"])
    tables = []
    for k in range(24):
        path = tmp_path / f"capstone-{k}.csv"
        write_motion_sensor(path, train, runs=1, sample_rate=50.0, seed=20261125 + 800 + k)
        tables.append(read_impacts(path))
    with_speeds = fit_noise_models([prepare_data(t, scene) for t in tables], "hybrid", scene)
    times_only = fit_noise_models(
        [prepare_data(t.drop(columns=["impact_speed", "rebound_speed", "speed_uncertainty"]),
                      scene) for t in tables], "hybrid", scene)
    assert all(fit.success for fit in with_speeds)
    for name in ("omega0", "beta"):
        estimates = [fit.estimates[name] for fit in with_speeds]
        assert_covers_at_both_levels(estimates, cart[name], name)
    ratio = (np.median([fit.estimates["omega0"].stderr for fit in times_only])
             / np.median([fit.estimates["omega0"].stderr for fit in with_speeds]))
    assert ratio >= 5.0, ratio
