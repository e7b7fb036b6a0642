"""Accuracy levels of the fit: the fast level's optimizer and what each level guarantees.

References: a linear least-squares problem has a closed-form solution and covariance; for the
contact models the exact level (lmfit's MINPACK to machine precision on the exact solver, checked
against the truth in test_fit.py) is the reference of the cheaper levels.
"""

from __future__ import annotations

import lmfit
import numpy as np
import pandas as pd
import pytest
from scipy.optimize import least_squares

import dashpot
from dashpot.fit import (FAST_STEP_SE, PARAMETERS, _levenberg_marquardt, choose_accuracy,
                         fit_model, prepare_data)
from dashpot.scene import Scene

G = 9.80665


def _parameters(values, vary=(True, True, True, True)):
    params = lmfit.Parameters()
    for name, value, free in zip(PARAMETERS, values, vary):
        params.add(name, value=value, vary=free)
    return params


@pytest.mark.parametrize("sigma_known", [True, False])
def test_levenberg_marquardt_solves_a_linear_problem_with_its_closed_form_covariance(
        sigma_known):
    rng = np.random.default_rng(4)
    design = rng.normal(size=(40, 3))
    data = design @ np.array([0.3, -2.0, 5.0]) + rng.normal(size=40)

    def residual_rows(values):
        # zeta, v_star, v0 enter through the design matrix; t0 is fixed at 0 here.
        return data[None, :] - values[:, :3] @ design.T

    fit = _levenberg_marquardt(residual_rows, _parameters([1.0, 1.0, 1.0, 0.0],
                                                          (True, True, True, False)),
                               {}, max_nfev=200, sigma_known=sigma_known)
    solution, *_ = np.linalg.lstsq(design, data, rcond=None)
    covariance = np.linalg.inv(design.T @ design)
    chisqr = np.sum((data - design @ solution) ** 2)
    if not sigma_known:
        covariance = covariance * chisqr / (40 - 3)
    assert fit.success, fit.message
    values = np.array([fit.params[name].value for name in PARAMETERS[:3]])
    # The step left is below FAST_STEP_SE standard errors; a linear problem takes one step.
    step = values - solution
    assert step @ np.linalg.inv(covariance) @ step <= FAST_STEP_SE ** 2
    np.testing.assert_allclose(fit.covar, covariance, rtol=1e-4)
    assert fit.chisqr == pytest.approx(chisqr, rel=1e-8)
    assert fit.var_names == ["zeta", "v_star", "v0"]
    assert not fit.params["t0"].vary and fit.params["t0"].value == 0.0


def test_levenberg_marquardt_with_an_exact_column_stops_within_its_tolerance():
    # A decaying exponential plus an offset (t0, given its exact column), σ = 0.01; the
    # reference is scipy's trust-region least squares run to machine precision.
    times = np.linspace(0.0, 1.0, 30)
    sigma = 0.01
    observed = (0.7 + 2.0 * np.exp(-times / 0.3)
                + np.random.default_rng(8).normal(0.0, sigma, times.size))

    def model_residual(v_star, v0, t0):
        return (observed - t0 - v0 * np.exp(-times / v_star)) / sigma

    def residual_rows(values):
        return model_residual(values[:, 1, None], values[:, 2, None], values[:, 3, None])

    fit = _levenberg_marquardt(residual_rows, _parameters([0.0, 0.25, 1.5, 0.0],
                                                          (False, True, True, True)),
                               {"t0": np.full(times.size, -1.0 / sigma)}, max_nfev=500,
                               sigma_known=True)
    reference = least_squares(lambda p: model_residual(*p), [0.25, 1.5, 0.0], xtol=1e-15,
                              ftol=1e-15, gtol=1e-15)
    covariance = np.linalg.inv(reference.jac.T @ reference.jac)
    assert fit.success, fit.message
    step = np.array([fit.params[name].value for name in PARAMETERS[1:]]) - reference.x
    assert step @ np.linalg.inv(covariance) @ step <= FAST_STEP_SE ** 2
    np.testing.assert_allclose(fit.covar, covariance, rtol=1e-3)


def _scene(model, count=20, sigma=2e-5, seed=5):
    sequence = dashpot.bounce_sequence(model, beta=5.0, omega0=500.0, g=G, v0=1.0, n_max=count)
    noise = np.random.default_rng(seed).normal(0.0, sigma, count)
    impacts = pd.DataFrame({"time": 0.25 + sequence.impact_times + noise,
                            "time_uncertainty": sigma})
    return prepare_data(impacts, Scene())


@pytest.mark.parametrize("model", dashpot.MODELS)
def test_fast_and_standard_levels_agree_with_exact_within_a_tenth_of_a_standard_error(model):
    data = _scene(model)
    exact = fit_model(data, model, Scene(), accuracy="exact")
    assert exact.success and exact.accuracy == "exact"
    for level in ("fast", "standard"):
        fit = fit_model(data, model, Scene(), accuracy=level)
        assert fit.success, (level, fit.message)
        assert fit.accuracy == level and any(note.startswith(f"accuracy {level}")
                                             for note in fit.notes)
        for name in ("beta", "omega0", "v0", "t0"):
            reference = exact.estimates[name]
            shift = abs(fit.estimates[name].value - reference.value) / reference.stderr
            assert shift <= 0.1, (level, name, shift)
            assert fit.estimates[name].stderr == pytest.approx(reference.stderr, rel=0.02)


def test_auto_takes_the_cheapest_level_the_timing_noise_allows():
    coarse, fine = _scene("hybrid", sigma=1e-3), _scene("hybrid", sigma=1e-8)
    level, _, bound, reason = choose_accuracy(coarse, "auto", "hybrid")
    assert level == "fast" and "<=" in reason
    level, _, bound, _ = choose_accuracy(fine, "auto", "hybrid")
    assert level == "exact" and bound <= 1e-12
    # Models without gravity are closed forms: exact physics at every level, so auto takes
    # the fast level's optimizer with the exact solver's bound.
    for data in (coarse, fine):
        level, _, bound, _ = choose_accuracy(data, "auto", "Ia")
        assert level == "fast" and bound <= 1e-12
    with pytest.raises(ValueError, match="accuracy must be"):
        choose_accuracy(coarse, "quick", "Ib")
