"""Fits under the noise model: intervals of every reported parameter cover the truth at their
stated rates and are as wide as the scatter of the estimates.

Trains are drawn by the noise model's simulator (:meth:`TrainModel.simulate`, which applies the
bounce map exactly, not the filter's linearization), rebound scatter σ_ε = 0.3 %, a detector
stating σ_i = 10 µs and a further jitter σ_j = √3·10 µs (20 µs in all), and fitted in one batch
per law (:func:`fit_noise_models`). Tolerances as in tests/coverage_checks.py (central 99.9 %
binomial range of the coverage counts; mean half-width of the 68.27 % interval and mean
standard error within [0.7, 1.4] of the spread of the estimates).
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
from dashpot.physics.flight import gravity_flight
from dashpot.physics.laws import LAWS, dashpot_contact_time
from dashpot.physics.models import MODELS
from dashpot.scene import Scene

G = 9.80665  # the default scene's g
DETECTOR, JITTER, SCATTER = 10e-6, math.sqrt(3.0) * 10e-6, 0.003
SEED = 20261125  # the date these trials were set up; not tuned


def simulated_trains(law, params, trials, *, count, speed, seed, scatter=SCATTER,
                     jitter=JITTER):
    """FitData of `trials` trains of `law` (parameters in the registry's order); with
    scatter = jitter = 0 the noise-free train."""
    params = [np.full(trials, float(p)) for p in params]
    contact = None
    if law in MODELS:
        def contact(impact_speed):
            return dashpot_contact_time(law, impact_speed, *params, G)
    model = TrainModel(LAWS[law].bind(*params), lambda v: gravity_flight(v, G), contact)
    drawn = model.simulate(count, np.random.default_rng(seed), start_time=0.25,
                           start_speed=speed, process_sigma=scatter, jitter=jitter,
                           detector_sigma=DETECTOR)
    assert np.all(np.isfinite(drawn.times)), "the train must not be captured"
    return [prepare_data(pd.DataFrame({"time": times, "time_uncertainty": DETECTOR}), Scene())
            for times in drawn.times]


# law: (its parameters, impacts, first impact speed m/s, trials). The dashpot model's scene is
# a soft contact (ω0 = g/v* = 150 rad/s, ṽ from 15 down to about 2.6) where its v*, and so ω0
# and β, are determined by the train.
SCENES = {
    "constant": ((0.93,), 40, 2.0, 100),
    "linear": ((0.97, 0.015), 40, 2.0, 60),
    "Ib": ((0.04, 0.0654), 15, 1.0, 40),
}
# Measured with seed SEED + index, on the code as it stands: what fails and by how much.
KNOWN_FAILURES = {
    "Ib": ("measured over 40 trains (seed SEED + 2): 95 % intervals hold the truth in 29/40 (v0) "
           "and 31/40 (beta), below the binomial range 33-40; 68 %: v0 18/40, beta 19/40; "
           "half-width/spread 0.58-0.75 and stderr/spread 0.58-0.66 for zeta, v_star, omega0 "
           "and beta. In about a fifth of these 15-impact trains the fit puts sigma_eps at or "
           "near 0 (the noise-free branch), and the intervals of v0 (Hessian) and of beta "
           "(linear propagation) are then those of the deterministic train: too narrow while "
           "zeta and v_star sit off the truth"),
}


def _truth(law, params, speed):
    truth = dict(zip((p.name for p in LAWS[law].parameters), params))
    truth.update(v0=speed, sigma_eps=SCATTER, sigma_j=JITTER)
    if law in MODELS:
        truth["omega0"] = G / truth["v_star"]
        truth["beta"] = truth["zeta"] * truth["omega0"]
    return truth


@pytest.mark.parametrize("law", [
    "constant", "linear",
    pytest.param("Ib", marks=pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES["Ib"]))])
def test_every_reported_parameter_covers_at_its_stated_rates(law, capsys):
    params, count, speed, trials = SCENES[law]
    data = simulated_trains(law, params, trials, count=count, speed=speed,
                            seed=SEED + list(SCENES).index(law))
    results = fit_noise_models(data, law)
    assert all(fit.success for fit in results)
    truth = _truth(law, params, speed)
    # Every parameter the fit reports with an interval is judged.
    assert set(results[0].estimates) == set(truth)
    lines, failures = judge_all(results, truth)
    with capsys.disabled():  # the measured figures, shown with `pytest -n 0 -s`
        print(f"\n{law} under the noise model, {trials} trains of {count} impacts:\n"
              + "\n".join(lines))
    assert not failures, failures
