"""Model selection: Akaike weights, and no model called preferred on a misfit they share."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from dashpot.select import selection_table

NDATA, NVARYS = 40, 4


def _results(chisqr, *, success=None):
    """Fit results of five models with these χ² (known timing errors: AIC = χ² + 2K)."""
    success = success or [True] * len(chisqr)
    return {model: SimpleNamespace(success=ok, nvarys=NVARYS, ndata=NDATA, chisqr=value,
                                   redchi=value / (NDATA - NVARYS), aic=value + 2 * NVARYS,
                                   bic=value + NVARYS * math.log(NDATA))
            for model, value, ok in zip(("Ia", "Ib", "IIa", "IIb", "hybrid"), chisqr, success)}


def _weights(delta):
    relative = np.exp(-0.5 * np.asarray(delta))
    return relative / relative.sum()


def test_a_shared_misfit_scales_the_comparison_and_prefers_nothing():
    # χ²/ν ≈ 1.6e4 (the ping-pong recording's size) with AIC gaps of 1.6e4 and more: on the
    # raw AIC the best model would be "clearly preferred" with weight 1.00.
    chisqr = np.array([5.9e5, 5.76e5, 6.1e5, 5.92e5, 6.5e5])
    table, verdict = selection_table(_results(chisqr))
    c_hat = chisqr.min() / (NDATA - NVARYS)
    delta_aic = chisqr - chisqr.min()
    np.testing.assert_allclose(table["delta_aic"], delta_aic)
    np.testing.assert_allclose(table["delta_qaic"], delta_aic / c_hat)
    np.testing.assert_allclose(table["akaike_weight"], _weights(delta_aic / c_hat))
    assert table["akaike_weight"].max() < 0.5
    assert verdict.startswith("not selectable: none describes the data")
    assert "preferred" not in verdict and "QAIC" in verdict
    assert "Ib, Ia, IIb" in verdict  # the three within ΔQAIC < 2, best first


def test_a_model_that_misfits_least_by_far_is_named_but_not_preferred():
    chisqr = np.array([9.0e4, 1.0e3, 9.1e4, 9.2e4, 9.3e4])
    table, verdict = selection_table(_results(chisqr))
    c_hat = 1.0e3 / (NDATA - NVARYS)
    assert table.loc[1, "delta_qaic"] == pytest.approx(0.0)
    assert table.loc[0, "delta_qaic"] == pytest.approx((9.0e4 - 1.0e3) / c_hat)
    assert "Ib misfits least (next Ia has ΔQAIC = " in verdict
    assert "preferred" not in verdict


@pytest.mark.parametrize("sigma_known", [True, False])
def test_data_described_within_their_errors_are_compared_on_aic(sigma_known):
    chisqr = np.array([52.0, 36.0, 53.0, 49.0, 37.5])  # ν = 36: the best fits its errors
    table, verdict = selection_table(_results(chisqr), sigma_known=sigma_known)
    np.testing.assert_array_equal(table["delta_qaic"], table["delta_aic"])
    np.testing.assert_allclose(table["akaike_weight"], _weights(chisqr - chisqr.min()))
    assert verdict.startswith("the data do not distinguish Ib, hybrid (ΔAIC < 2)")


def test_errors_fitted_from_the_scatter_are_never_rescaled():
    # Without known timing errors a large χ² says nothing about the models' adequacy.
    chisqr = np.array([5.9e5, 5.0e5, 6.1e5, 5.92e5, 6.5e5])
    table, verdict = selection_table(_results(chisqr), sigma_known=False)
    np.testing.assert_array_equal(table["delta_qaic"], table["delta_aic"])
    assert "clearly preferred" in verdict and "not selectable" not in verdict


def test_failed_fits_keep_no_weight_under_the_misfit_scale():
    chisqr = np.array([5.9e5, 5.76e5, np.nan, 5.92e5, 6.5e5])
    table, _ = selection_table(_results(chisqr, success=[True, True, False, True, True]))
    assert table.loc[2, "akaike_weight"] == 0 and math.isinf(table.loc[2, "delta_qaic"])
    assert table["akaike_weight"].sum() == pytest.approx(1.0)


def _noise_results(bic):
    """Noise fits with these BIC (same K = 4, n = 39): −2 ln L = BIC − 4 ln 39."""
    from dashpot.fit import Estimate

    scatter = Estimate(0.003, 3e-4, 0.0027, 0.0033, 0.0024, 0.0036, "1", "fitted")
    return {name: SimpleNamespace(success=True, nvarys=4, ndata=39, chisqr=39.0, redchi=1.0,
                                  aic=value - 4 * math.log(39) + 8, bic=value,
                                  neg2_log_likelihood=value - 4 * math.log(39),
                                  estimates={"sigma_eps": scatter})
            for name, value in bic.items()}


def test_an_effect_a_kept_fit_carries_is_required_even_where_its_own_step_failed():
    # With ω0 known, Ia (constant ε plus the known contact duration) is worse than the
    # constant law, while Ib (the same contact duration plus gravity in contact) beats it:
    # the selected Ib carries the contact duration, so the data required it.
    from dashpot.noise_selection import noise_selection_table

    table, verdict = noise_selection_table(_noise_results({"constant": -150.0, "Ia": -137.0,
                                                           "Ib": -186.0}))
    table = table.set_index("model")
    assert table.loc["Ib", "selected"] and not table.loc["Ia", "kept"]
    assert table.loc["Ib", "simpler"] == "constant"  # Ia not kept: the next rung down
    assert table.loc["Ib", "bic_gain"] == pytest.approx(36.0)
    required, _, not_required = verdict.partition("not required")
    assert "gravity in contact (Ib: ΔBIC = 36.0 against constant)" in required
    assert "contact duration (carried by Ib; Ia: ΔBIC = -13.0 against constant)" in required
    assert "contact duration" not in not_required
    # Where no kept fit carries it, the failed step leaves it not required.
    _, verdict = noise_selection_table(_noise_results({"constant": -150.0, "Ia": -137.0,
                                                       "Ib": -140.0}))
    assert "noise model: constant selected" in verdict
    assert "not required (ΔBIC < 6): contact duration (Ia: ΔBIC = -13.0" in verdict


@pytest.mark.parametrize("rounding", [-1e-9, 1e-9])
def test_models_equal_but_for_rounding_are_named_in_the_tables_order(rounding):
    # Ia and IIa fit alike to the last digits, which the platform's arithmetic decides: the
    # verdict must not change with it. Ib is 1 worse, hybrid far worse.
    chisqr = np.array([30.0, 31.0, 30.0 + rounding, 31.5, 60.0])
    _, verdict = selection_table(_results(chisqr))
    assert verdict == ("the data do not distinguish Ia, IIa, Ib, IIb (ΔAIC < 2); Ia fits "
                       "marginally best")
