"""Intervals of every parameter a deterministic fit reports cover the truth at their stated
rates, and are as wide as the scatter of the estimates: on trains whose truth is integrated
independently of dashpot.

The noise-free train of each model comes from the event-driven scipy ``solve_ivp`` simulation
of tests/test_bounce_train.py (every contact integrated, no closed form of dashpot's); each
trial adds Gaussian timing noise of a known σ. The scene is a soft contact where gravity in
contact is observable (ζ = 0.04, ω0 = 150 rad/s, ṽ from 7.6 down to about 1.4 over 10 impacts,
σ = 20 µs), a regime apart from test_fit's coverage test (ω0 = 500 rad/s, ṽ0 ≈ 51).
The tolerances are those of tests/coverage_checks.py: coverage counts inside the central
99.9 % binomial range, mean half-width and standard error within [0.7, 1.4] of the spread.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from coverage_checks import judge_all
from dashpot.fit import fit_model, prepare_data
from dashpot.scene import Scene
from test_bounce_train import simulate_train

G = 9.80665
ZETA, OMEGA0, VTILDE0, COUNT, SIGMA = 0.04, 150.0, 7.6, 10, 2e-5
T0 = 0.25
TRIALS = 50
SEED = 20261125  # the date these trials were set up; not tuned


@pytest.mark.slow
@pytest.mark.parametrize("model", ["Ia", "Ib", "IIb", "hybrid"])
def test_every_reported_parameter_covers_at_its_stated_rates(model, capsys):
    v0 = VTILDE0 * G / OMEGA0
    train = simulate_train(model, beta=ZETA * OMEGA0, omega0=OMEGA0, g=G, v0=v0, n_max=COUNT)
    assert train.impact_times.size == COUNT and train.stop_reason == "n_max"
    truth = {"zeta": ZETA, "omega0": OMEGA0, "v_star": G / OMEGA0, "beta": ZETA * OMEGA0,
             "v0": v0, "t0": T0}
    rng = np.random.default_rng([SEED, ["Ia", "Ib", "IIb", "hybrid"].index(model)])
    fits = []
    for _ in range(TRIALS):
        impacts = pd.DataFrame({"time": T0 + train.impact_times
                                + rng.normal(0.0, SIGMA, COUNT), "time_uncertainty": SIGMA})
        fit = fit_model(prepare_data(impacts, Scene()), model, Scene())
        assert fit.success, fit.message
        fits.append(fit)
    lines, failures = judge_all(fits, truth)
    with capsys.disabled():  # the measured figures, shown with `pytest -n 0 -s`
        print(f"\n{model}, {TRIALS} trials (deterministic fit, solve_ivp truth):\n"
              + "\n".join(lines))
    assert not failures, failures
    assert math.isfinite(fits[0].estimates["beta"].stderr)
