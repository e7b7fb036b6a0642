"""The fit's uncertainty plumbing: linear error propagation, the covariance's scaling under a
misfit, and the registry of interval methods (a new method is one function and one entry)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

import dashpot
from dashpot.fit import UNCERTAINTY_METHODS, fit_model, model_fit, prepare_data
from dashpot.fit.covariance import _misfit_bound, _propagated_sd, _scaled_covariance
from dashpot.fit.uncertainty import INTERVAL_METHODS, IntervalInputs
from dashpot.scene import Scene

G = 9.80665


def test_propagated_sd_is_the_closed_form_of_a_product():
    # q = x·y: var(q)/q² = var(x)/x² + var(y)/y² + 2 cov(x, y)/(x y) (Bevington eq. 3.14).
    x, y, sx, sy, rho = 3.0, 0.5, 0.2, 0.01, -0.4
    cov = np.array([[sx ** 2, rho * sx * sy], [rho * sx * sy, sy ** 2]])
    expected = x * y * math.sqrt((sx / x) ** 2 + (sy / y) ** 2 + 2 * rho * sx * sy / (x * y))
    assert _propagated_sd(cov, ("x", "y"), {"x": y, "y": x}) == pytest.approx(expected,
                                                                             rel=1e-12)
    # A parameter that is not varied adds nothing; a quantity of none of them has sd 0.
    assert _propagated_sd(cov, ("x", "y"), {"x": 1.0, "fixed": 5.0}) == pytest.approx(sx)
    assert _propagated_sd(cov, ("x", "y"), {"fixed": 5.0}) == 0.0


def test_propagated_sd_is_infinite_where_the_covariance_is():
    cov = np.array([[np.inf, np.inf], [np.inf, 1.0]])
    assert _propagated_sd(cov, ("x", "y"), {"x": 1.0}) == math.inf
    assert _propagated_sd(cov, ("x", "y"), {"y": 2.0}) == pytest.approx(2.0)


def _result(chisqr, nfree, covar):
    return SimpleNamespace(var_names=["a", "b"], covar=covar, chisqr=chisqr, nfree=nfree,
                           redchi=chisqr / nfree)


def test_covariance_is_scaled_by_the_reduced_chi_square_only_under_a_misfit():
    covar = np.diag([4.0, 9.0])
    nfree = 50
    edge = _misfit_bound(nfree)
    assert edge == pytest.approx(nfree + 3 * math.sqrt(2 * nfree))
    notes = []
    cov, scale = _scaled_covariance(_result(0.99 * edge, nfree, covar), True, notes, "x")
    assert scale == 1.0 and np.array_equal(cov, covar) and not notes
    cov, scale = _scaled_covariance(_result(4.0 * nfree, nfree, covar), True, notes,
                                    "the model misses")
    assert scale == pytest.approx(4.0)
    assert np.allclose(cov, 4.0 * covar)
    assert notes and "the model misses" in notes[0] and "sqrt(redchi) = 2" in notes[0]
    # Errors not known: lmfit scaled the covariance already; χ²/ν is the divisor.
    notes = []
    cov, scale = _scaled_covariance(_result(4.0 * nfree, nfree, covar), False, notes, "x")
    assert np.array_equal(cov, covar) and scale == pytest.approx(4.0) and not notes
    # No covariance: infinite errors, and a note.
    cov, _ = _scaled_covariance(_result(nfree, nfree, None), True, notes, "x")
    assert np.all(np.isinf(cov)) and "singular Jacobian" in notes[0]


def test_the_registry_names_every_method_but_the_covariance():
    assert set(INTERVAL_METHODS) | {"covariance"} == set(UNCERTAINTY_METHODS)


def test_a_registered_method_is_called_with_the_fit_and_its_row_reported(monkeypatch):
    """One function and one registry entry make a new method: it gets the finished fit and
    its row lands in the fit's intervals with its CPU time."""
    seen = {}

    def half_width_of_two_sigma(inputs: IntervalInputs) -> dict:
        seen["inputs"] = inputs
        beta = inputs.result.params["zeta"].value * G / inputs.result.params["v_star"].value
        return {"low68": beta - 1.0, "high68": beta + 1.0, "low95": beta - 2.0,
                "high95": beta + 2.0}

    monkeypatch.setitem(INTERVAL_METHODS, "toy", half_width_of_two_sigma)
    monkeypatch.setattr(model_fit, "UNCERTAINTY_METHODS", UNCERTAINTY_METHODS + ("toy",))
    sequence = dashpot.bounce_sequence("Ia", beta=5.0, omega0=500.0, g=G, v0=1.0, n_max=12)
    impacts = pd.DataFrame({"time": 0.25 + sequence.impact_times, "time_uncertainty": 1e-6})
    fit = fit_model(prepare_data(impacts, Scene()), "Ia", Scene(),
                    uncertainty=("covariance", "toy"))
    assert fit.success
    assert seen["inputs"].model == "Ia" and seen["inputs"].data.count == 12
    row = fit.intervals["toy"]
    assert row["high95"] - row["low95"] == pytest.approx(4.0)
    assert (row["low68"] + row["high68"]) / 2 == pytest.approx(5.0, rel=1e-4)
    assert row["cpu_seconds"] >= 0.0
    assert set(fit.intervals) == {"covariance", "toy"}
