"""Fits under the noise model: intervals of every reported parameter cover the truth at their
stated rates and are as wide as the scatter of the estimates.

Trains are drawn by the noise model's simulator (:meth:`TrainModel.simulate`, which applies the
bounce map exactly, not the filter's linearization), rebound scatter σ_ε = 0.3 %, a detector
stating σ_i = 10 µs and a further jitter σ_j = √3·10 µs (20 µs in all), and fitted in one batch
per law (:func:`fit_noise_models`); with air drag, k_d is judged too. Each fit must also be at
its optimum: no worse than the truth, nor than any point on a line of σ_ε or σ_j through it.
Tolerances as in tests/coverage_checks.py (central 99.9 % binomial range of the coverage
counts; mean half-width of the 68.27 % interval and mean standard error within [0.7, 1.4] of
the spread of the estimates).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from coverage_checks import judge_all
from dashpot.fit import prepare_data
from dashpot.fit.noise_fit import fit_noise_models
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import drag_flight, gravity_flight
from dashpot.physics.laws import LAWS, dashpot_contact_time
from dashpot.physics.models import MODELS
from dashpot.scene import Known, Scene

G = 9.80665  # the default scene's g
DETECTOR, JITTER, SCATTER = 10e-6, math.sqrt(3.0) * 10e-6, 0.003
SEED = 20261125  # the date these trials were set up; not tuned


def train_model(law, params, trials, scene=None, drag_constant=None):
    """The noise model's TrainModel of `law` for `trials` trains (parameters in the registry's
    order, each a number or one value per train), and its g: a scene with air drag (mass and
    diameter) flies the trains with drag, at its effective gravity and its k_d (or at
    `drag_constant`, 1/m, one value or one per train)."""
    scene = scene or Scene()
    params = [np.broadcast_to(np.asarray(p, float), (trials,)) for p in params]
    g = G
    if scene.needs_drag:
        g = scene.drag.effective_gravity.value
        k_d = scene.drag.drag_constant.value if drag_constant is None else np.broadcast_to(
            np.asarray(drag_constant, float), (trials,))

        def flight(v):
            return drag_flight(v, g, k_d)
    else:
        def flight(v):
            return gravity_flight(v, g)
    contact = None
    if law in MODELS:
        def contact(impact_speed):
            return dashpot_contact_time(law, impact_speed, *params, g)
    return TrainModel(LAWS[law].bind(*params), flight, contact), g


def drag_prior(drag_constant, scenes):
    """((k_d − centre)/sd)² of each train's scene's prior on k_d (0 without drag), the term
    the fits add to −2 ln L."""
    if scenes is None or not scenes[0].needs_drag:
        return 0.0
    centre = np.array([scene.drag.drag_constant.value for scene in scenes])
    spread = np.array([scene.drag.drag_constant.uncertainty for scene in scenes])
    return ((np.asarray(drag_constant, float) - centre) / spread) ** 2


def simulated_trains(law, params, trials, *, count, speed, seed, scatter=SCATTER,
                     jitter=JITTER, scene=None):
    """FitData of `trials` trains of `law` drawn by :func:`train_model`'s model; with
    scatter = jitter = 0 the noise-free train."""
    model, g = train_model(law, params, trials, scene)
    drawn = model.simulate(count, np.random.default_rng(seed), start_time=0.25,
                           start_speed=speed, process_sigma=scatter, jitter=jitter,
                           detector_sigma=DETECTOR)
    assert np.all(np.isfinite(drawn.times)), "the train must not be captured"
    data = [prepare_data(pd.DataFrame({"time": times, "time_uncertainty": DETECTOR}),
                         scene or Scene()) for times in drawn.times]
    assert data[0].g == g
    return data


def neg2_log_likelihood_along(law, results, data, name, grid, scene=None, scenes=None):
    """−2 ln L of each train on a line through its fit: the noise parameter `name`
    ("sigma_eps" or "sigma_j") at each value of `grid`, every other parameter at the fit (the
    filter run directly, plus the prior on k_d of each train's scene in `scenes` where the
    fit has one). Shape (trains, grid points)."""
    trials, points = len(results), len(grid)
    fitted = {key: np.repeat([fit.estimates[key].value for fit in results], points)
              for key in results[0].estimates}
    noise = {key: fitted[key] for key in ("sigma_eps", "sigma_j")}
    noise[name] = np.tile(np.asarray(grid, float), trials)
    model, _ = train_model(law, [fitted[p.name] for p in LAWS[law].parameters],
                           trials * points, scene, fitted.get("k_d"))
    likelihood = model.filter(
        np.repeat([d.times for d in data], points, axis=0), start_time=None,
        start_speed=fitted["v0"], process_sigma=noise["sigma_eps"], jitter=noise["sigma_j"],
        detector_sigma=np.repeat([d.sigma for d in data], points, axis=0)
    ).neg2_log_likelihood.reshape(trials, points)
    if "k_d" in fitted:
        likelihood = likelihood + drag_prior(fitted["k_d"].reshape(trials, points)[:, 0],
                                             scenes)[:, None]
    return likelihood


# Lines through each fit along which no point may beat it: σ_ε and σ_j over their useful range.
LINES = {"sigma_eps": np.r_[0.0, np.geomspace(1e-6, 0.03, 40)],
         "sigma_j": np.geomspace(1e-7, 1e-3, 41)}


def neg2_log_likelihood_of_the_truth(law, params, data, *, speed, scatter, scene=None,
                                     scenes=None):
    """−2 ln L of each train at the true parameters (the filter of :mod:`dashpot.likelihood`
    run directly, start time integrated out as in the fits), plus the prior on k_d of each
    train's scene in `scenes` at the true k_d."""
    model, _ = train_model(law, params, len(data), scene)
    likelihood = model.filter(np.array([d.times for d in data]), start_time=None,
                              start_speed=speed, process_sigma=scatter, jitter=JITTER,
                              detector_sigma=np.array([d.sigma for d in data])
                              ).neg2_log_likelihood
    if scene is not None and scene.needs_drag:
        likelihood = likelihood + drag_prior(scene.drag.drag_constant.value, scenes)
    return likelihood


# Each case: law, its parameters, impacts, first impact speed (m/s), trains, and optionally the
# scatter σ_ε (0: the deterministic train) and a scene. The dashpot model's train is a soft
# contact (ω0 = g/v* = 150 rad/s, ṽ from 15 down to about 2.6) where its v*, and so ω0 and β,
# are determined. The drag case is a table-tennis ball (2.7 g, 40 mm: k_d ≈ 0.125 1/m,
# terminal speed 8.8 m/s): k_d is fitted with the prior of the scene's C_d (0.45 ± 0.05), whose
# centre each trial draws anew about the truth (as a measured C_d would be; those trains are
# fitted one by one), so that the prior does not hand the fit the truth.
BALL_MASS, BALL_DIAMETER, DRAG_COEFFICIENT, DRAG_COEFFICIENT_SD = 0.0027, 0.040, 0.45, 0.05


def ball(drag_coefficient=DRAG_COEFFICIENT):
    """The table-tennis ball's scene, its C_d known to ± DRAG_COEFFICIENT_SD."""
    return Scene(mass=Known(BALL_MASS), diameter=Known(BALL_DIAMETER),
                 drag_coefficient=Known(drag_coefficient, DRAG_COEFFICIENT_SD))


BALL = ball()
CASES = {
    "constant": dict(law="constant", params=(0.93,), count=40, speed=2.0, trials=100),
    "linear": dict(law="linear", params=(0.97, 0.015), count=40, speed=2.0, trials=60),
    "Ib": dict(law="Ib", params=(0.04, 0.0654), count=15, speed=1.0, trials=40),
    "constant, no scatter": dict(law="constant", params=(0.93,), count=40, speed=2.0,
                                 trials=60, scatter=0.0),
    "constant, drag": dict(law="constant", params=(0.93,), count=40, speed=3.0, trials=60,
                           scene=BALL),
    "Ib, no scatter": dict(law="Ib", params=(0.04, 0.0654), count=15, speed=1.0, trials=40,
                           scatter=0.0),
    # A longer train of a less damped contact (ṽ from 15 down to about 3 over 25 impacts).
    "Ib, 25 impacts": dict(law="Ib", params=(0.02, 0.0654), count=25, speed=1.0, trials=40),
}
# The best fit is at least as likely as the truth, and as any point on a line of σ_ε or σ_j
# through it: −2 ln L of the fit may exceed theirs by no more than this (the optimizers stop
# within 1e-6; the fast level's tabulated filter is within about 1e-3 of the direct one).
OPTIMUM_SLACK = 0.05
# Measured with seed SEED + index, on the code as it stands: what fails and by how much.
KNOWN_FAILURES = {}


def _truth(law, params, speed, scatter, scene=None):
    truth = dict(zip((p.name for p in LAWS[law].parameters), params))
    truth.update(v0=speed, sigma_eps=scatter, sigma_j=JITTER)
    if scene is not None and scene.needs_drag:
        truth["k_d"] = scene.drag.drag_constant.value
    if law in MODELS:
        truth["omega0"] = G / truth["v_star"]
        truth["beta"] = truth["zeta"] * truth["omega0"]
    return truth


# σ_ε = 0 lies on the bound of its range: there the likelihood-ratio interval holds it with
# probability ½ + ½·(nominal rate) (half the trials put σ_ε at 0; Self and Liang, J. Am. Statist.
# Assoc. 82, 605 (1987)), and that is the rate asked of it.
AT_ZERO = {"68": 0.5 + 0.5 * 0.6827, "95": 0.5 + 0.5 * 0.9545}


@pytest.mark.slow
@pytest.mark.parametrize("case", [
    pytest.param(case, marks=pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[case]))
    if case in KNOWN_FAILURES else case for case in CASES])
def test_every_reported_parameter_covers_at_its_stated_rates(case, capsys):
    setting = dict(CASES[case])
    law, params, trials = setting.pop("law"), setting.pop("params"), setting.pop("trials")
    scatter, scene = setting.get("scatter", SCATTER), setting.get("scene")
    data = simulated_trains(law, params, trials, seed=SEED + list(CASES).index(case),
                            **setting)
    scenes = None
    if scene is not None and scene.needs_drag:
        draws = np.random.default_rng([SEED, 99]).normal(DRAG_COEFFICIENT, DRAG_COEFFICIENT_SD,
                                                         trials)
        scenes = [ball(measured) for measured in draws]
        results = [fit_noise_models([train], law, own)[0] for train, own in zip(data, scenes)]
    else:
        results = fit_noise_models(data, law, scene)
    assert all(fit.success for fit in results)
    # The fit reached the optimum: no worse than the true parameters in any train.
    excess = (np.array([fit.neg2_log_likelihood for fit in results])
              - neg2_log_likelihood_of_the_truth(law, params, data, speed=setting["speed"],
                                                 scatter=scatter, scene=scene, scenes=scenes))
    missed = np.flatnonzero(excess > OPTIMUM_SLACK)
    # ...and at the optimum: no point on a line of σ_ε or σ_j through it does better.
    beaten = {name: np.flatnonzero(
        np.array([fit.neg2_log_likelihood for fit in results])
        - neg2_log_likelihood_along(law, results, data, name, grid, scene, scenes).min(axis=1)
        > OPTIMUM_SLACK) for name, grid in LINES.items()}
    truth = _truth(law, params, setting["speed"], scatter, scene)
    # Every parameter the fit reports with an interval is judged.
    assert set(results[0].estimates) == set(truth)
    rates = {"sigma_eps": AT_ZERO} if scatter == 0.0 else {}
    lines, failures = judge_all(results, truth, rates)
    if missed.size:
        failures.append(f"-2 ln L of the fit above the truth's in {missed.size}/{trials} "
                        f"trains (by {', '.join(f'{x:.2f}' for x in excess[missed])})")
    failures += [f"a point on the {name} line beats the fit in {rows.size}/{trials} trains"
                 for name, rows in beaten.items() if rows.size]
    with capsys.disabled():  # the measured figures, shown with `pytest -n 0 -s`
        print(f"\n{case} under the noise model, {trials} trains of {setting['count']} "
              f"impacts (fit above the truth's -2 ln L in {missed.size}, beaten on a line of "
              f"{', '.join(f'{name} in {rows.size}' for name, rows in beaten.items())}):\n"
              + "\n".join(lines))
    assert not failures, failures


def test_a_fit_with_its_noise_held_reaches_the_truth_on_a_noise_free_train():
    law, params, speed = "Ib", CASES["Ib"]["params"], CASES["Ib"]["speed"]
    clean = simulated_trains(law, params, 1, count=CASES["Ib"]["count"], speed=speed, seed=0,
                             scatter=0.0, jitter=0.0)
    fit = fit_noise_models(clean, law, fixed={"sigma_eps": SCATTER, "sigma_j": JITTER},
                           profile=False)[0]
    truth = neg2_log_likelihood_of_the_truth(law, params, clean, speed=speed, scatter=SCATTER)
    assert fit.success
    assert fit.neg2_log_likelihood <= truth[0] + OPTIMUM_SLACK


def test_a_train_fitted_in_a_batch_gets_the_fit_it_gets_alone():
    """fit_noise_models fits each data set on its own (its docstring): the batch is only a way
    of evaluating many at once."""
    setting = dict(CASES["linear"])
    law, params, trials = setting.pop("law"), setting.pop("params"), setting.pop("trials")
    data = simulated_trains(law, params, trials, seed=SEED + list(CASES).index("linear"),
                            **setting)
    batch = fit_noise_models(data, law, profile=False)
    alone = [fit_noise_models([train], law, profile=False)[0] for train in data]
    differ = [(k, round(b.neg2_log_likelihood - a.neg2_log_likelihood, 2))
              for k, (b, a) in enumerate(zip(batch, alone))
              if abs(b.neg2_log_likelihood - a.neg2_log_likelihood) > OPTIMUM_SLACK]
    assert not differ, differ
