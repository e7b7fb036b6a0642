"""The bounce-train likelihood with process noise (σ_ε) and timing noise (σ_t).

Exact checks against likelihoods written out independently (deterministic train, a linear
Gaussian train, the small-noise linearization), then checks by simulation with seeds chosen
once: the standardized innovations are N(0, 1), a maximum-likelihood fit recovers the truth, and
its intervals cover at their nominal rates.
"""

import math

import numpy as np
import pytest
from scipy import optimize, stats

from dashpot.likelihood import TrainModel
from dashpot.physics.flight import drag_constant, drag_flight, effective_gravity, gravity_flight

G = 9.81


def constant_restitution(eps):
    """The law v = ε·u, for one ε or one per batch element."""
    eps = np.asarray(eps, dtype=float)
    return lambda speed: (eps * speed, np.broadcast_to(eps, np.shape(speed * eps)))


def gravity_train(eps, contact=0.0):
    return TrainModel(constant_restitution(eps), lambda v: gravity_flight(v, G),
                      None if contact == 0.0 else lambda u: (np.full_like(u, contact),
                                                             np.zeros_like(u)))


def deterministic_times(t0, v0, eps, count, contact=0.0):
    """t_n of a train with constant ε under gravity, by hand: t_{n+1} = t_n + τ + 2εu_n/g."""
    times, speed = [t0], v0
    for _ in range(count - 1):
        times.append(times[-1] + contact + 2.0 * eps * speed / G)
        speed *= eps
    return np.array(times)


def test_without_process_noise_it_is_the_deterministic_chi_square():
    rng = np.random.default_rng(20250611)
    count, eps, v0, t0, contact = 25, 0.93, 1.7, 0.31, 4e-4
    detector = rng.uniform(5e-6, 40e-6, count)
    scale, jitter = 1.7, 8e-6
    truth = deterministic_times(t0, v0, eps, count, contact)
    sigma = np.sqrt((scale * detector) ** 2 + jitter ** 2)
    times = truth + sigma * rng.standard_normal(count)
    # Evaluated a little off the truth, so that the residuals are not the noise drawn.
    t0_fit, v0_fit = t0 + 3e-5, v0 * (1.0 + 2e-5)
    predicted = deterministic_times(t0_fit, v0_fit, eps, count, contact)
    chi_square = np.sum(((times - predicted) / sigma) ** 2)
    expected = chi_square + np.sum(np.log(2.0 * math.pi * sigma ** 2))

    result = gravity_train(eps, contact).filter(
        times, start_time=t0_fit, start_speed=v0_fit, process_sigma=0.0, jitter=jitter,
        detector_sigma=detector, sigma_scale=scale)
    assert result.neg2_log_likelihood == pytest.approx(expected, rel=1e-9)
    assert result.chi_square == pytest.approx(chi_square, rel=1e-9)
    np.testing.assert_allclose(result.predicted_times, predicted, rtol=1e-13)
    np.testing.assert_allclose(result.standardized, (times - predicted) / sigma, rtol=1e-7,
                               atol=1e-9)

    # A free start time: the same train integrated over t0 with a flat prior, in closed form:
    # χ² at the weighted-mean t0 + Σ ln 2πσ² + ln Σw − ln 2π.
    offsets = predicted - t0_fit
    weights = sigma ** -2.0
    best = np.sum(weights * (times - offsets)) / np.sum(weights)
    marginal = (np.sum(weights * (times - offsets - best) ** 2)
                + np.sum(np.log(2.0 * math.pi * sigma ** 2))
                + math.log(np.sum(weights)) - math.log(2.0 * math.pi))
    free = gravity_train(eps, contact).filter(
        times, start_time=None, start_speed=v0_fit, process_sigma=0.0, jitter=jitter,
        detector_sigma=detector, sigma_scale=scale)
    assert free.neg2_log_likelihood == pytest.approx(marginal, rel=1e-9)
    assert not free.scored[0] and free.scored[1:].all()


def linear_gaussian_covariance(count, speed, process, timing):
    """Covariance of the times when every rebound is speed·(1 + η) whatever the impact: the
    train is then linear and Gaussian, t_n = t_0 + (2·speed/g)·Σ_{k<n}(1 + η_k) + e_n."""
    step = 2.0 * speed * process / G
    index = np.arange(count)
    return step ** 2 * np.minimum.outer(index, index) + timing ** 2 * np.eye(count)


def test_linear_gaussian_train_matches_the_multivariate_normal():
    """Process noise exactly: a law whose rebound does not depend on the impact speed."""
    rng = np.random.default_rng(9)
    count, speed, process, timing, t0 = 30, 1.2, 0.004, 30e-6, 0.05
    model = TrainModel(lambda u: (np.full_like(u, speed), np.zeros_like(u)),
                       lambda v: gravity_flight(v, G))
    mean = t0 + 2.0 * speed / G * np.arange(count)
    covariance = linear_gaussian_covariance(count, speed, process, timing)
    times = rng.multivariate_normal(mean, covariance, size=3)
    times[2, [4, 5, 17]] = np.nan  # undetected impacts: the marginal of the others
    result = model.filter(times, start_time=t0, start_speed=speed, process_sigma=process,
                          jitter=timing)
    for row, expected_times in enumerate(times):
        seen = np.isfinite(expected_times)
        expected = -2.0 * stats.multivariate_normal(
            mean[seen], covariance[np.ix_(seen, seen)]).logpdf(expected_times[seen])
        assert result.neg2_log_likelihood[row] == pytest.approx(expected, rel=1e-9)
    assert result.scored.sum(axis=1).tolist() == [30, 30, 27]


def test_small_noise_filter_matches_the_linearized_train():
    """Constant ε: the filter against y ~ N(t(0), J Σ_η Jᵀ + σ_t²) with J = ∂t_n/∂η_k of the
    deterministic train, written out by hand; they differ only at second order in σ_ε."""
    rng = np.random.default_rng(31)
    count, eps, v0, t0, process, timing = 30, 0.9, 2.0, 0.0, 3e-4, 20e-6
    mean = deterministic_times(t0, v0, eps, count)
    rebounds = v0 * eps ** np.arange(1, count + 1)  # v_k = ε^{k+1}·u_0
    # ∂t_n/∂η_k = Σ_{k ≤ j < n} 2v_j/g: a kick to rebound k speeds up every later one.
    jacobian = np.array([[2.0 * rebounds[k:n].sum() / G if k < n else 0.0
                          for k in range(count)] for n in range(count)])
    covariance = process ** 2 * jacobian @ jacobian.T + timing ** 2 * np.eye(count)
    times = rng.multivariate_normal(mean, covariance)
    expected = -2.0 * stats.multivariate_normal(mean, covariance).logpdf(times)
    result = gravity_train(eps).filter(times, start_time=t0, start_speed=v0,
                                       process_sigma=process, jitter=timing)
    # The linearizations differ by O(σ_ε) in each variance: ~1e-3 in −2 ln L here.
    assert result.neg2_log_likelihood == pytest.approx(expected, abs=1e-2)
    # ...while a process noise 10 % off changes it by far more than that.
    off = gravity_train(eps).filter(times, start_time=t0, start_speed=v0,
                                    process_sigma=1.1 * process, jitter=timing)
    assert abs(off.neg2_log_likelihood - expected) > 0.1


def test_batch_rows_are_independent_filters():
    rng = np.random.default_rng(5)
    eps = np.array([0.9, 0.95, 0.97])
    model = gravity_train(eps)
    simulated = model.simulate(20, rng, start_time=0.0, start_speed=[1.0, 2.0, 3.0],
                               process_sigma=[0.0, 0.002, 0.01], jitter=[1e-5, 2e-5, 5e-5])
    batch = model.filter(simulated.times, start_time=None, start_speed=[1.0, 2.0, 3.0],
                         process_sigma=[0.0, 0.002, 0.01], jitter=[1e-5, 2e-5, 5e-5])
    for row in range(3):
        alone = gravity_train(eps[row]).filter(
            simulated.times[row], start_time=None, start_speed=[1.0, 2.0, 3.0][row],
            process_sigma=[0.0, 0.002, 0.01][row], jitter=[1e-5, 2e-5, 5e-5][row])
        assert alone.neg2_log_likelihood == batch.neg2_log_likelihood[row]
        np.testing.assert_array_equal(alone.innovations, batch.innovations[row])


def test_simulator_draws_the_stated_noise():
    rng = np.random.default_rng(77)
    model = gravity_train(0.95)
    simulated = model.simulate(30, rng, start_time=0.2, start_speed=np.full(400, 2.0),
                               process_sigma=0.003, jitter=20e-6)
    kicks = simulated.rebound_speeds / (0.95 * simulated.impact_speeds) - 1.0
    assert stats.kstest(kicks.ravel() / 0.003, "norm").pvalue > 0.01
    timing = (simulated.times - simulated.true_times).ravel()
    assert stats.kstest(timing / 20e-6, "norm").pvalue > 0.01
    # Between impacts the ball flies: the next impact speed is the rebound speed (gravity).
    np.testing.assert_allclose(simulated.impact_speeds[:, 1:], simulated.rebound_speeds[:, :-1])
    np.testing.assert_allclose(np.diff(simulated.true_times),
                               2.0 * simulated.rebound_speeds[:, :-1] / G, rtol=1e-12)


def test_no_timing_noise_and_a_certain_first_impact_is_impossible_not_nan():
    times = deterministic_times(0.0, 1.0, 0.9, 5) + 1e-6
    result = gravity_train(0.9).filter(times, start_time=0.0, start_speed=1.0,
                                       process_sigma=0.01, jitter=0.0)
    assert result.neg2_log_likelihood == math.inf


# --- Simulation: a light ball (table-tennis drag), constant ε, 40 bounces, 100 trials ------

MASS, DIAMETER, DRAG_COEFFICIENT, AIR = 2.7e-3, 0.040, 0.45, 1.2
G_EFF = effective_gravity(G, MASS, DIAMETER, AIR)
K_D = drag_constant(MASS, DIAMETER, DRAG_COEFFICIENT, AIR)
EPS, PROCESS, TIMING, SPEED, BOUNCES, TRIALS = 0.9, 0.003, 20e-6, 2.0, 40, 100
# Fitted parameters: ε, ln σ_ε, ln σ_t, u_0; the start time is integrated out (start_time=None).
TRUTH = np.array([EPS, math.log(PROCESS), math.log(TIMING), SPEED])
UNITS = np.array([1e-3, 1.0, 1.0, 1e-3])  # parameter units of order one standard error
STEP = 1e-2  # finite-difference step in those units


def light_ball(eps):
    return TrainModel(constant_restitution(eps), lambda v: drag_flight(v, G_EFF, K_D))


def neg2_log_likelihood(times, parameters):
    """−2 ln L for parameter rows (..., 4) against trains (..., impacts)."""
    return light_ball(parameters[..., 0]).filter(
        times, start_time=None, start_speed=parameters[..., 3],
        process_sigma=np.exp(parameters[..., 1]), jitter=np.exp(parameters[..., 2]))


def stencil(count):
    """Offsets of the central-difference gradient and Hessian in `count` dimensions."""
    unit = np.eye(count)
    rows = [np.zeros(count)] + [sign * unit[i] for i in range(count) for sign in (1, -1)]
    pairs = [(i, j) for i in range(count) for j in range(i + 1, count)]
    rows += [a * unit[i] + b * unit[j] for i, j in pairs for a, b in
             ((1, 1), (1, -1), (-1, 1), (-1, -1))]
    return STEP * np.array(rows), pairs


def fit_all(times, start, free, iterations=60):
    """Maximum likelihood for every trial at once: Levenberg-damped Newton steps with
    central-difference derivatives, one batched filter call per step.
    Returns (parameters, −2 ln L, Hessian in UNITS)."""
    trials, count = len(times), len(free)
    offsets, pairs = stencil(count)
    parameters, damping = start.copy(), np.full(trials, 1.0)

    def evaluate(moves):  # moves: (trials, points, free) in UNITS
        rows = np.repeat(parameters[:, None, :], moves.shape[1], axis=1)
        rows[..., free] += moves * UNITS[free]
        return neg2_log_likelihood(times[:, None, :], rows).neg2_log_likelihood

    for _ in range(iterations):
        f = evaluate(np.broadcast_to(offsets, (trials,) + offsets.shape))
        centre, plus, minus = f[:, 0], f[:, 1:2 * count:2], f[:, 2:2 * count + 1:2]
        gradient = (plus - minus) / (2.0 * STEP)
        hessian = np.zeros((trials, count, count))
        hessian[:, range(count), range(count)] = (plus - 2.0 * centre[:, None] + minus) / STEP ** 2
        for k, (i, j) in enumerate(pairs):
            a, b, c, d = f[:, 1 + 2 * count + 4 * k:5 + 2 * count + 4 * k].T
            hessian[:, i, j] = hessian[:, j, i] = (a - b - c + d) / (4.0 * STEP ** 2)
        scale = np.abs(np.diagonal(hessian, axis1=1, axis2=2)) + 1e-12
        step = -np.linalg.solve(hessian + damping[:, None, None] * scale[:, :, None]
                                * np.eye(count), gradient[..., None])[..., 0]
        step = np.clip(step, -3.0, 3.0)
        better = evaluate(step[:, None, :])[:, 0] < centre
        moved = parameters.copy()
        moved[:, free] += step * UNITS[free]
        parameters = np.where(better[:, None], moved, parameters)
        damping = np.where(better, np.maximum(damping / 4.0, 1e-6), damping * 8.0)
        if np.all(np.abs(step) < 1e-6):
            break
    return parameters, centre, hessian


@pytest.fixture(scope="module")
def trials():
    rng = np.random.default_rng(20250612)
    simulated = light_ball(np.full(TRIALS, EPS)).simulate(
        BOUNCES, rng, start_time=0.1, start_speed=SPEED, process_sigma=PROCESS, jitter=TIMING)
    intervals = np.diff(simulated.times, axis=1)
    eps_start = np.median(intervals[:, 1:] / intervals[:, :-1], axis=1)
    # Two starts of the timing noise, the better fit kept: from one start alone a few trains
    # drift to σ_t → 0, where the likelihood is flat in ln σ_t, and stop there.
    fits = []
    for timing_start in (1e-4, 1e-5):
        start = np.column_stack([eps_start, np.full(TRIALS, math.log(0.01)),
                                 np.full(TRIALS, math.log(timing_start)),
                                 intervals[:, 0] * G / (2.0 * eps_start)])
        fits.append(fit_all(simulated.times, start, [0, 1, 2, 3]))
    better = fits[1][1] < fits[0][1]
    best, best_value, hessian = (np.where(better.reshape((-1,) + (1,) * (a.ndim - 1)), b, a)
                                 for a, b in zip(*fits))
    return simulated.times, best, best_value, hessian


def test_standardized_innovations_are_standard_normal(trials):
    times, best, _, _ = trials
    at_truth = neg2_log_likelihood(times, TRUTH).standardized[:, 1:]
    assert stats.kstest(at_truth.ravel(), "norm").pvalue > 0.01
    fitted = neg2_log_likelihood(times, best)
    z = fitted.standardized[:, 1:]
    # Per train at the fit (39 innovations, 4 parameters): the KS p-values are not piled at 0.
    p_values = np.array([stats.kstest(row, "norm").pvalue for row in z])
    assert np.mean(p_values < 0.01) <= 0.01 + 2.5 * math.sqrt(0.01 * 0.99 / TRIALS)
    # Σz² over the 39 scored innovations: ≈ 39 at the ML noise parameters, which are fitted
    # to make it so (not 39 − 4).
    reduced = fitted.chi_square.sum() / (TRIALS * (BOUNCES - 1))
    assert 0.95 < reduced < 1.05


def test_maximum_likelihood_recovers_the_truth_and_covers_it(trials):
    times, best, best_value, hessian = trials
    assert np.all(np.isfinite(best_value))
    median = np.median(best, axis=0)
    assert median[0] == pytest.approx(EPS, abs=2e-4)
    assert math.exp(median[1]) == pytest.approx(PROCESS, rel=0.15)
    assert math.exp(median[2]) == pytest.approx(TIMING, rel=0.3)
    assert median[3] == pytest.approx(SPEED, rel=2e-3)

    # Profile-likelihood intervals: the truth lies in the 68/95 % interval of a parameter where
    # −2 ln L, minimized over the others with that parameter held at its true value, rises by
    # less than 1 / 4. (Wald intervals from the Hessian cover alike for σ_ε in ln σ_ε, but
    # ε's fall a little short at 40 bounces: 90 % at 95 %.)
    rises = []
    for index in (0, 1):
        held = best.copy()
        held[:, index] = TRUTH[index]
        _, profiled, _ = fit_all(times, held, [k for k in range(4) if k != index])
        rises.append(profiled - best_value)
    rises = np.array(rises)
    assert np.all(rises > -1e-6)  # the full fits are the global ones
    for level, threshold in ((0.6827, 1.0), (0.9545, 4.0)):
        tolerance = 2.5 * math.sqrt(level * (1.0 - level) / TRIALS)
        np.testing.assert_allclose(np.mean(rises < threshold, axis=1), level, atol=tolerance)
    # The Hessian's standard errors are the size of the scatter of the estimates. A train
    # whose σ_t went to its bound 0 has a flat direction (ln σ_t → −∞, the likelihood no
    # longer changes with it): the pseudo-inverse leaves that direction out, where the
    # inverse would be the rounding noise of a zero curvature.
    covariance = 2.0 * np.linalg.pinv(hessian, rcond=1e-8, hermitian=True) * np.outer(UNITS,
                                                                                     UNITS)
    errors = np.sqrt(np.diagonal(covariance, axis1=1, axis2=2))
    spread = np.std(best[:, :2], axis=0)
    np.testing.assert_allclose(np.median(errors[:, :2], axis=0), spread, rtol=0.3)


def test_the_deterministic_fit_of_the_same_trains_is_a_misfit(trials):
    times, best, _, _ = trials
    start = best.copy()
    start[:, 1], start[:, 2] = -np.inf, TRUTH[2]  # σ_ε = 0, σ_t known
    deterministic, _, _ = fit_all(times, start, [0, 3])
    chi_square = neg2_log_likelihood(times, deterministic).chi_square / (BOUNCES - 1 - 2)
    assert np.median(chi_square) > 100.0
    assert np.median(neg2_log_likelihood(times, best).chi_square / (BOUNCES - 1)) < 1.1
