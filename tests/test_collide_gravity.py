"""The one-pass compiled collide of the gravity models (exact_kernels.ib_collide, iib_collide).

Above ṽ = 20 the solver takes its first Halley step from the gravity-free end time in closed
form, decides most rebounds and releases from closed-form sufficient conditions instead of
evaluating the end condition at the bracket's end, and takes ξ'(τ) from a Taylor series about
its last iterate. Checked here against references that share no code with it: the contact time
and ε against the end condition written with mpmath at 50 digits, and the capture flags against
the critical speed (dashpot.critical_velocity, a root of the tangency condition).
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest

import dashpot

RTOL = 1e-13  # models.EXACT_RTOL, the stated accuracy


def _mp_state(zeta, vtilde, t):
    """ξ(t) and ξ'(t) at 50 digits: ξ = η − 1, η = e^{−ζt}(cosh st + (ζ − ṽ) sinh(st)/s)."""
    z, v, t = mp.mpf(zeta), mp.mpf(vtilde), mp.mpf(t)
    s = mp.sqrt(mp.mpc(z * z - 1))
    decay = mp.exp(-z * t)
    c = mp.re(decay * mp.cosh(s * t))
    sine = mp.re(decay * (mp.sinh(s * t) / s if s != 0 else t))
    return c - 1 + (z - v) * sine, -v * c + (z * v - 1) * sine


def _mp_end(model, zeta, vtilde, t):
    """ξ (Ib) or the force F/(mg) = −ξ − 2ζξ' (IIb) at t."""
    xi, rate = _mp_state(zeta, vtilde, t)
    return xi if model == "Ib" else -xi - 2 * mp.mpf(zeta) * rate


def _fast_points(k, n):
    """ζ log-uniform in [1e-3, 0.95], ṽ log-uniform in [20, 1e12] (the closed-form start)."""
    rng = np.random.default_rng(20261126 + k)
    return 10 ** rng.uniform(-3, np.log10(0.95), n), 10 ** rng.uniform(np.log10(20.0), 12, n)


@pytest.mark.parametrize("model", ["Ib", "IIb"])
def test_fast_path_contact_time_and_restitution_at_50_digits(model):
    zeta, vtilde = _fast_points(0 if model == "Ib" else 1, 30)
    result = dashpot.collide(model, zeta, vtilde)
    rebound = ~result.captured
    assert rebound.sum() >= 20, "most of these fast impacts rebound"
    with mp.workdps(50):
        for z, v, tau, eps in zip(zeta[rebound], vtilde[rebound], result.contact_time[rebound],
                                  result.eps[rebound]):
            root = mp.findroot(lambda t: _mp_end(model, z, v, t), mp.mpf(tau))
            # The first root: the end condition keeps its sign before it.
            for fraction in np.linspace(0.02, 0.98, 25):
                inner = _mp_end(model, z, v, root * fraction)
                assert (inner < 0) if model == "Ib" else (inner > 0), (z, v, fraction)
            assert abs(float(tau / root) - 1) <= RTOL, (z, v, tau, float(root))
            reference = _mp_state(z, v, root)[1] / mp.mpf(v)
            assert abs(float(eps / reference) - 1) <= RTOL, (z, v, eps, float(reference))


@pytest.mark.parametrize("model", ["Ib", "IIb"])
def test_capture_flags_follow_the_critical_speed_on_the_fast_path(model):
    """Just above and below ṽc, where the closed-form sufficient conditions must not claim a
    rebound (release) that the end condition would refuse, and far above it. IIb's ṽc exceeds
    the fast path's 20 only from ζ ≈ 0.95 on."""
    zeta = np.array([0.05, 0.3, 0.6, 0.75, 0.8, 0.85, 0.9] if model == "Ib"
                    else [0.3, 0.96, 0.99, 0.999, 1 - 1e-9])
    vc = dashpot.critical_velocity(model, zeta)
    factors = np.array([0.5, 1 - 1e-6, 1 + 1e-6, 1.01, 1.5, 3.0, 30.0, 1e4])
    z, v = (a.ravel() for a in np.meshgrid(zeta, factors, indexing="ij"))
    v = v * np.repeat(vc, factors.size)
    usable = np.isfinite(v) & (v > 20.0) & (v < 1e300)
    assert usable.sum() >= 20 if model == "Ib" else usable.sum() >= 12
    result = dashpot.collide(model, z[usable], v[usable])
    expected_captured = v[usable] < np.repeat(vc, factors.size)[usable]
    np.testing.assert_array_equal(result.captured, expected_captured)


@pytest.mark.parametrize("model", ["Ib", "IIb", "hybrid"])
def test_collide_agrees_with_the_bracket_interface(model):
    """collide's contact time is the root that brackets._ib_solve/_iib_release return (which
    always evaluate the end condition at the bracket's end to decide capture)."""
    from dashpot.physics.brackets import _ib_solve, _iib_release

    rng = np.random.default_rng(20261128)
    zeta, vtilde = 10 ** rng.uniform(-3, 1, 2000), 10 ** rng.uniform(-1, 8, 2000)
    result = dashpot.collide(model, zeta, vtilde)
    tau = (_ib_solve if model == "Ib" else _iib_release)(zeta, vtilde)[3]
    if model == "hybrid":
        # Released (finite τ) but too slow to climb back: captured by the hybrid alone.
        assert np.all(result.captured[np.isinf(tau)])
        both = ~result.captured
        climb = result.contact_time[both] - tau[both]
        assert np.all(climb > 0)
    else:
        np.testing.assert_array_equal(result.contact_time, tau)
