"""Conversions between (m, k, γ), (β, ω0), (ζ, v*) and (τ, ε), for every model."""

import numpy as np
import pytest

import dashpot


def test_parameter_round_trip():
    mass, k, gamma = 0.506, 255.0, 1.892
    beta, omega0 = dashpot.natural_parameters(mass, k, gamma)
    assert beta == pytest.approx(gamma / (2 * mass), rel=1e-15)
    assert omega0 == pytest.approx(np.sqrt(k / mass), rel=1e-15)
    k2, gamma2 = dashpot.contact_coefficients(mass, beta, omega0)
    assert k2 == pytest.approx(k, rel=1e-14) and gamma2 == pytest.approx(gamma, rel=1e-14)
    zeta, v_star = dashpot.dimensionless_parameters(beta, omega0, 2.90)
    # The paper's cart: v* = 0.129 m/s with m = 0.506 kg and k = 255 N/m means g_eff ≈ 2.90 m/s².
    assert v_star == pytest.approx(0.129, abs=5e-4)
    assert zeta == pytest.approx(beta / omega0)


def test_ia_matches_dem_closed_form():
    """DEM codes: k = m(π² + ln²ε)/τ², γ = −2m ln ε/τ for the gravity-free position model."""
    mass, tau, eps = 0.0027, np.array([1e-4, 3e-3, 0.1]), np.array([0.9, 0.5, 0.05])
    k, gamma = dashpot.contact_from_restitution("Ia", tau, eps, mass=mass, v0=1.0, g=9.81)
    np.testing.assert_allclose(k, mass * (np.pi**2 + np.log(eps) ** 2) / tau**2, rtol=1e-11)
    np.testing.assert_allclose(gamma, -2 * mass * np.log(eps) / tau, rtol=1e-10)


@pytest.mark.parametrize("model", dashpot.MODELS)
def test_contact_restitution_round_trip(model):
    mass, v0, g = 0.506, np.array([0.3, 1.0, 3.0]), 2.90
    k, gamma = np.array([255.0, 1e3, 5e4]), np.array([1.9, 5.0, 3.0])
    tau, eps = dashpot.restitution_from_contact(model, k, gamma, mass=mass, v0=v0, g=g)
    assert np.all(np.isfinite(tau)) and np.all((eps > 0) & (eps < 1))
    k2, gamma2 = dashpot.contact_from_restitution(model, tau, eps, mass=mass, v0=v0, g=g)
    np.testing.assert_allclose(k2, k, rtol=1e-9)
    np.testing.assert_allclose(gamma2, gamma, rtol=1e-8)


def test_unreachable_restitution_is_an_error():
    """Outside the searched damping range (ζ <= 1e4, where ε_IIa ≈ 2.5e-9) there is no answer."""
    with pytest.raises(ValueError, match="cannot produce"):
        dashpot.contact_from_restitution("IIa", 1e-3, 1e-12, mass=0.5, v0=1.0, g=9.81)


@pytest.mark.parametrize("model", dashpot.MODELS)
def test_extreme_restitution_round_trip(model):
    """Nearly elastic and nearly dead contacts, a slow impact with a long contact."""
    for tau, eps, v0 in [(10.0, 0.999, 0.01), (1e-3, 0.3, 1.0)]:
        k, gamma = dashpot.contact_from_restitution(model, tau, eps, mass=0.5, v0=v0, g=9.81)
        tau2, eps2 = dashpot.restitution_from_contact(model, k, gamma, mass=0.5, v0=v0, g=9.81)
        assert tau2 == pytest.approx(tau, rel=1e-9) and eps2 == pytest.approx(eps, rel=1e-9)
